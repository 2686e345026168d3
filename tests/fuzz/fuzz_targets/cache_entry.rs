//! The build cache's check of an entry (`hlod_builder::cache::check_entry_source`):
//! a scene whose header records the key it was built for, every rep
//! passing its checksum. The key asked for is the one the input's header
//! records (so that mutations get past the key check); inputs of even
//! length get their checksums recomputed first, as in `scene_reader`.
#![no_main]

use engine::format::FileHeader;
use engine::MemSource;
use libfuzzer_sys::fuzz_target;

#[path = "fix.rs"]
mod fix;

fuzz_target!(|data: &[u8]| {
    let bytes = fix::prepared(data);
    let key = bytes
        .get(..std::mem::size_of::<FileHeader>())
        .map(|h| bytemuck::pod_read_unaligned::<FileHeader>(h).source_key)
        .unwrap_or([0; 16]);
    let _ = hlod_builder::cache::check_entry_source(MemSource::new(bytes), &key);
});
