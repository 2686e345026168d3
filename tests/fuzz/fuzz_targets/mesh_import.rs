//! The PLY, OBJ and STL readers (`hlod_builder::import::parse_mesh_bytes`):
//! the first byte picks the format, the rest is the file (an OBJ's
//! material libraries resolve against a folder that does not exist).
#![no_main]

use std::path::Path;

use hlod_builder::import::{Format, parse_mesh_bytes};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let format = [Format::Ply, Format::Obj, Format::Stl][usize::from(pick % 3)];
    let _ = parse_mesh_bytes(file, format, Path::new("/nonexistent-fuzz-dir"));
});
