//! The scene-file reader: header, skeleton, `validate()`, every rep
//! decoded, the object section, and a pick through the scene. Inputs of
//! even length get their header, skeleton and object-section CRCs
//! recomputed first (version 2), so that mutations reach the checks behind
//! the checksums.
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
        if let Ok(objects) = scene.read_objects() {
            let root = &scene.skeleton().nodes[0];
            let (lo, hi) = (glam::Vec3::from(root.bbox_min), glam::Vec3::from(root.bbox_max));
            let eye = hi + (hi - lo);
            let _ = engine::pick::pick(&scene, &objects, eye, (lo + hi) * 0.5 - eye);
            for k in 0..objects.len() as u32 {
                let _ = objects.info(k);
            }
        }
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
    let (off, len) = (h.objects_offset as usize, h.objects_len as usize);
    if let Some(obj) = off.checked_add(len).and_then(|end| bytes.get(off..end)) {
        h.objects_crc = crc32fast::hash(obj);
    }
    h.header_crc = 0;
    h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
}
