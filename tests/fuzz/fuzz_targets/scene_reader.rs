//! The scene-file reader: header, skeleton, `validate()`, every rep decoded.
//! Inputs of even length get their header and skeleton CRCs recomputed
//! first, so that mutations reach the checks behind the checksums.
#![no_main]

use engine::format::FileHeader;
use engine::{MemSource, SceneFile};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    if bytes.len().is_multiple_of(2) {
        fix_checksums(&mut bytes);
    }
    if let Ok(scene) = SceneFile::from_source(MemSource::new(bytes)) {
        let _ = scene.verify_all_reps();
    }
});

fn fix_checksums(bytes: &mut [u8]) {
    const H: usize = std::mem::size_of::<FileHeader>();
    if bytes.len() < H {
        return;
    }
    let mut h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..H]);
    let (off, len) = (h.skeleton_offset as usize, h.skeleton_len as usize);
    if let Some(skel) = off.checked_add(len).and_then(|end| bytes.get(off..end)) {
        h.skeleton_crc = crc32fast::hash(skel);
    }
    h.header_crc = 0;
    h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
}
