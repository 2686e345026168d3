//! Streaming scene writer: reps go to disk as they are made, the skeleton and
//! the header last.

use std::io::{Seek, SeekFrom, Write};
use std::mem::size_of;

use super::{BLOCK, FileHeader, FormatError, MAGIC, NodeRecord, REP_ALIGN, RepRecord, VERSION};
use crate::format::reader::SceneMeta;
use crate::skeleton::Skeleton;

/// Where a payload landed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RepLocation {
    pub offset: u64,
    pub len: u32,
    pub checksum: u32,
}

/// Writes one scene file. Call [`SceneWriter::write_rep`] for every payload,
/// then [`SceneWriter::finish`] with the skeleton that references them.
#[derive(Debug)]
pub struct SceneWriter<W: Write + Seek> {
    out: W,
    pos: u64,
}

impl<W: Write + Seek> SceneWriter<W> {
    /// Starts a file: reserves the header block.
    pub fn new(mut out: W) -> Result<Self, FormatError> {
        out.seek(SeekFrom::Start(0))?;
        out.write_all(&[0u8; BLOCK as usize])?;
        Ok(Self { out, pos: BLOCK })
    }

    /// Appends a mesh payload on the next [`REP_ALIGN`] boundary, right
    /// after the previous one.
    pub fn write_rep(&mut self, payload: &[u8]) -> Result<RepLocation, FormatError> {
        self.write_aligned(payload, REP_ALIGN)
    }

    /// Appends a view-dependence tree's payload on the next [`BLOCK`]
    /// boundary: its pages are sized to blocks.
    pub fn write_tree_rep(&mut self, payload: &[u8]) -> Result<RepLocation, FormatError> {
        self.write_aligned(payload, BLOCK)
    }

    fn write_aligned(&mut self, payload: &[u8], align: u64) -> Result<RepLocation, FormatError> {
        let len = u32::try_from(payload.len())
            .map_err(|_| FormatError::TooLarge(format!("rep of {} bytes", payload.len())))?;
        self.pad_to(align)?;
        let offset = self.pos;
        self.out.write_all(payload)?;
        self.pos += payload.len() as u64;
        Ok(RepLocation {
            offset,
            len,
            checksum: crc32fast::hash(payload),
        })
    }

    fn pad_to(&mut self, align: u64) -> Result<(), FormatError> {
        let pad = (self.pos.next_multiple_of(align) - self.pos) as usize;
        self.out.write_all(&[0u8; BLOCK as usize][..pad])?;
        self.pos += pad as u64;
        Ok(())
    }

    /// Ends the data section without a skeleton (a builder's partial output,
    /// which adds its own records): the sink, flushed, and the data's end.
    pub fn into_inner(mut self) -> Result<(W, u64), FormatError> {
        self.out.flush()?;
        Ok((self.out, self.pos))
    }

    /// Validates `skeleton` against the written data, writes it and the header,
    /// and returns the sink (flushed). No object section.
    pub fn finish(self, skeleton: &Skeleton, meta: &SceneMeta) -> Result<W, FormatError> {
        self.finish_with_objects(skeleton, meta, &[])
    }

    /// [`SceneWriter::finish`] with an object section
    /// ([`ObjectTable::encode`](super::objects::ObjectTable::encode)) after the skeleton.
    pub fn finish_with_objects(
        self,
        skeleton: &Skeleton,
        meta: &SceneMeta,
        objects: &[u8],
    ) -> Result<W, FormatError> {
        self.finish_with_sections(skeleton, meta, objects, &[])
    }

    /// [`SceneWriter::finish_with_objects`] with a walk section
    /// ([`WalkIndex::encode`](super::walk::WalkIndex::encode); empty for
    /// none) after the object section.
    pub fn finish_with_sections(
        mut self,
        skeleton: &Skeleton,
        meta: &SceneMeta,
        objects: &[u8],
        walk: &[u8],
    ) -> Result<W, FormatError> {
        if !meta.origin.iter().all(|c| c.is_finite()) {
            return Err(FormatError::BadHeader("origin is not finite".into()));
        }
        self.pad_to(BLOCK)?;
        skeleton.validate(BLOCK, self.pos)?;
        let too_large = |what: &str| FormatError::TooLarge(what.to_string());
        let node_count = u32::try_from(skeleton.nodes.len()).map_err(|_| too_large("nodes"))?;
        let rep_count = u32::try_from(skeleton.reps.len()).map_err(|_| too_large("reps"))?;
        let node_bytes: &[u8] = bytemuck::cast_slice(&skeleton.nodes);
        let rep_bytes: &[u8] = bytemuck::cast_slice(&skeleton.reps);
        let placement_bytes: &[u8] = bytemuck::cast_slice(&skeleton.placements);
        let mut crc = crc32fast::Hasher::new();
        crc.update(node_bytes);
        crc.update(rep_bytes);
        crc.update(placement_bytes);
        self.out.write_all(node_bytes)?;
        self.out.write_all(rep_bytes)?;
        self.out.write_all(placement_bytes)?;
        let skeleton_len = (node_bytes.len() + rep_bytes.len() + placement_bytes.len()) as u64;
        self.out.write_all(objects)?;
        self.out.write_all(walk)?;
        let objects_offset = self.pos + skeleton_len;
        let walk_offset = objects_offset + objects.len() as u64;
        let walk_crc = if walk.is_empty() {
            0
        } else {
            let index = super::walk::WalkIndex::decode(walk, walk.len() as u64)?;
            let index_len = super::walk::WalkIndex::index_len(index.header.chunk_count);
            crc32fast::hash(&walk[..index_len as usize])
        };
        let root = &skeleton.nodes[0];
        let mut header = FileHeader {
            magic: MAGIC,
            version: VERSION,
            header_size: size_of::<FileHeader>() as u32,
            node_count,
            rep_count,
            object_count: meta.object_count,
            flags: 0,
            input_triangles: meta.input_triangles,
            data_offset: BLOCK,
            data_len: self.pos - BLOCK,
            skeleton_offset: self.pos,
            skeleton_len,
            file_len: walk_offset + walk.len() as u64,
            bounds_min: root.bbox_min,
            bounds_max: root.bbox_max,
            skeleton_crc: crc.finalize(),
            header_crc: 0,
            origin: meta.origin,
            objects_offset,
            objects_len: objects.len() as u64,
            objects_crc: crc32fast::hash(objects),
            source_key: meta.source_key,
            drawn_triangles: crate::records::split_u64(meta.drawn_triangles),
            hidden_triangles: crate::records::split_u64(meta.hidden_triangles),
            walk_crc,
            walk_offset,
            walk_len: walk.len() as u64,
            placement_count: skeleton.placements.len() as u64,
            reserved: [0; 5],
        };
        header.header_crc = crc32fast::hash(bytemuck::bytes_of(&header));
        self.out.seek(SeekFrom::Start(0))?;
        self.out.write_all(bytemuck::bytes_of(&header))?;
        self.out.seek(SeekFrom::End(0))?;
        self.out.flush()?;
        Ok(self.out)
    }
}

const _: () =
    assert!(size_of::<NodeRecord>().is_multiple_of(8) && size_of::<RepRecord>().is_multiple_of(8));
