//! The `.vdt` reader: header, meta-node table, permanent triangles, and
//! the first meta-nodes. Inputs of even length get their header, MNT and
//! permanent-triangle CRCs recomputed first.
#![no_main]

use std::sync::Arc;

use engine::MemSource;
use engine::vdt::file::{VdtFile, VdtHeader};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    if bytes.len().is_multiple_of(2) {
        fix_checksums(&mut bytes);
    }
    if let Ok(f) = VdtFile::open(Arc::new(MemSource::new(bytes))) {
        for m in 0..f.header.meta_count.min(64) {
            let _ = f.read_meta(m);
        }
    }
});

fn fix_checksums(bytes: &mut [u8]) {
    const H: usize = std::mem::size_of::<VdtHeader>();
    if bytes.len() < H {
        return;
    }
    let mut h: VdtHeader = bytemuck::pod_read_unaligned(&bytes[..H]);
    let mnt_len = u64::from(h.meta_count) * 32;
    let perm_len = u64::from(h.permanent_count) * 16;
    let range = |at: u64, len: u64| {
        let end = at.checked_add(len)?;
        bytes.get(usize::try_from(at).ok()?..usize::try_from(end).ok()?)
    };
    if let Some(m) = range(H as u64, mnt_len) {
        h.mnt_crc = crc32fast::hash(m);
    }
    if let Some(p) = range(H as u64 + mnt_len, perm_len) {
        h.permanent_crc = crc32fast::hash(p);
    }
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
    h.header_crc = crc32fast::hash(&bytes[..H - 4]);
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
}
