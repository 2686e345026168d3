//! What the scene targets share: a scene file's header, skeleton,
//! object-section and walk-index CRCs recomputed, so that mutations reach
//! the checks behind the checksums.

use engine::format::{FileHeader, FileHeaderV2};

/// `data` as a scene file to read: inputs of even length get their
/// checksums recomputed ([`fix_checksums`]), odd ones stay as they are.
pub fn prepared(data: &[u8]) -> Vec<u8> {
    let mut bytes = data.to_vec();
    if bytes.len().is_multiple_of(2) {
        fix_checksums(&mut bytes);
    }
    bytes
}

pub fn fix_checksums(bytes: &mut [u8]) {
    const H: usize = std::mem::size_of::<FileHeader>();
    const H2: usize = std::mem::size_of::<FileHeaderV2>();
    let version = bytes.get(8..12).map(|v| u32::from_le_bytes(v.try_into().expect("4 bytes")));
    if version.is_some_and(|v| (2..5).contains(&v)) && bytes.len() >= H2 {
        // Versions 2 to 4: the 192-byte header.
        let mut h: FileHeaderV2 = bytemuck::pod_read_unaligned(&bytes[..H2]);
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
        bytes[..H2].copy_from_slice(bytemuck::bytes_of(&h));
        return;
    }
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
    // The walk section's header and index.
    let off = h.walk_offset as usize;
    let count = off
        .checked_add(12)
        .and_then(|end| bytes.get(off + 8..end))
        .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")));
    if let Some(count) = count {
        let len = engine::format::walk::WalkIndex::index_len(count).min(h.walk_len) as usize;
        if let Some(index) = off.checked_add(len).and_then(|end| bytes.get(off..end)) {
            h.walk_crc = crc32fast::hash(index);
        }
    }
    h.header_crc = 0;
    h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
}
