//! What the scene targets share: a scene file's header, skeleton and
//! object-section CRCs recomputed, so that mutations reach the checks
//! behind the checksums.

use engine::format::FileHeader;

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
