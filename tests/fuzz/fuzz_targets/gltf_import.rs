//! The glTF/GLB importer on bytes (external buffers resolve against a
//! folder that does not exist).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = hlod_builder::import::load_slice(
        data,
        Path::new("/nonexistent-fuzz-dir"),
        Path::new("fuzz.glb"),
    );
});
