//! The versioned on-disk scene format (version 2; version 1 is still read).
//!
//! ```text
//! offset 0      FileHeader (192 B; 128 B in version 1), zero-padded to BLOCK
//! BLOCK         rep payloads, each starting on a BLOCK boundary, zero-padded
//! data end      skeleton: [NodeRecord; node_count] [RepRecord; rep_count]
//! skeleton end  object section (version 2, may be empty): names and extras
//!               of the source objects, for picking (see [`objects`])
//! ```
//!
//! The header carries the magic, the version, the section ranges, the world
//! position of the scene's origin (version 2: coordinates are stored relative
//! to it in `f32`, so survey-coordinate models keep millimetres) and three
//! CRC-32s (header, skeleton, object section). Each [`RepRecord`] names its payload's byte range and
//! CRC-32, so one rep can be read and checked alone, and reading the skeleton
//! never touches rep data. The skeleton sits after the data so that the builder
//! streams reps to disk as it makes them; the header is written last.
//!
//! All integers are little-endian; every record is `repr(C)` with its size
//! asserted at compile time.

pub mod objects;
mod reader;
mod rep;
mod writer;

pub use reader::{SceneFile, SceneMeta, check_rep_crc, check_vdt_record};
pub use rep::{PackedVertex, REP_MAGIC, RepHeader, RepMesh, quantize_unit_normal};
pub use writer::SceneWriter;

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

use crate::skeleton::ValidationError;

#[cfg(not(target_endian = "little"))]
compile_error!("the scene format is little-endian and this engine reads it by casting");

/// File magic: the first eight bytes of every scene file.
pub const MAGIC: [u8; 8] = *b"OOCHLOD\0";
/// The format version this build writes (and the newest it reads).
pub const VERSION: u32 = 2;
/// The oldest version this build reads (no origin, no object section).
pub const OLDEST_VERSION: u32 = 1;
/// Alignment of every rep payload and of the data section.
pub const BLOCK: u64 = 4096;
/// "No node / no object" marker in `u32` fields.
pub const NONE: u32 = u32::MAX;

/// The fixed header at offset 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FileHeader {
    pub magic: [u8; 8],
    pub version: u32,
    /// `size_of::<FileHeader>()`, for forward compatibility checks.
    pub header_size: u32,
    pub node_count: u32,
    pub rep_count: u32,
    /// Objects (glTF mesh instances) in the source scene.
    pub object_count: u32,
    pub flags: u32,
    /// Triangles in the source scene after instancing.
    pub input_triangles: u64,
    pub data_offset: u64,
    pub data_len: u64,
    pub skeleton_offset: u64,
    pub skeleton_len: u64,
    pub file_len: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// CRC-32 of the skeleton section.
    pub skeleton_crc: u32,
    /// CRC-32 of this header with this field set to zero.
    pub header_crc: u32,
    /// World position of the scene's origin: stored coordinates are
    /// relative to it (version 2; zero for version 1).
    pub origin: [f64; 3],
    /// The object section (after the skeleton; length 0 when absent).
    pub objects_offset: u64,
    pub objects_len: u64,
    /// CRC-32 of the object section.
    pub objects_crc: u32,
    pub reserved: [u32; 9],
}
const _: () = assert!(size_of::<FileHeader>() == 192);

/// The version-1 header: the version-2 one up to `header_crc`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FileHeaderV1 {
    pub magic: [u8; 8],
    pub version: u32,
    pub header_size: u32,
    pub node_count: u32,
    pub rep_count: u32,
    pub object_count: u32,
    pub flags: u32,
    pub input_triangles: u64,
    pub data_offset: u64,
    pub data_len: u64,
    pub skeleton_offset: u64,
    pub skeleton_len: u64,
    pub file_len: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub skeleton_crc: u32,
    pub header_crc: u32,
    pub reserved: [u32; 4],
}
const _: () = assert!(size_of::<FileHeaderV1>() == 128);

impl FileHeaderV1 {
    /// The same facts in the version-2 layout (origin zero, no object
    /// section). `header_crc` keeps the version-1 value.
    pub fn upgrade(&self) -> FileHeader {
        FileHeader {
            magic: self.magic,
            version: self.version,
            header_size: size_of::<FileHeader>() as u32,
            node_count: self.node_count,
            rep_count: self.rep_count,
            object_count: self.object_count,
            flags: self.flags,
            input_triangles: self.input_triangles,
            data_offset: self.data_offset,
            data_len: self.data_len,
            skeleton_offset: self.skeleton_offset,
            skeleton_len: self.skeleton_len,
            file_len: self.file_len,
            bounds_min: self.bounds_min,
            bounds_max: self.bounds_max,
            skeleton_crc: self.skeleton_crc,
            header_crc: self.header_crc,
            origin: [0.0; 3],
            objects_offset: self.file_len,
            objects_len: 0,
            objects_crc: 0,
            reserved: [0; 9],
        }
    }
}

/// One scene-graph node. Nodes are stored breadth-first: node 0 is the root and
/// the children of a node are contiguous.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct NodeRecord {
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    /// Parent node, [`NONE`] for the root.
    pub parent: u32,
    pub first_child: u32,
    pub child_count: u32,
    /// First of this node's reps in the rep table; `N[0]` coarsest.
    pub first_rep: u32,
    pub rep_count: u32,
    /// Distance from the root.
    pub depth: u32,
    /// Source object of a leaf made of one object (or one chunk of it), else [`NONE`].
    pub object: u32,
    /// Dominant base colour, RGBA8 (red in the low byte).
    pub color: u32,
    /// [`NodeRecord::FLAG_CHUNK`], [`NodeRecord::FLAG_MERGED`].
    pub flags: u32,
    /// Source objects (or chunks) below and at this node.
    pub object_count: u32,
}
const _: () = assert!(size_of::<NodeRecord>() == 64);

impl NodeRecord {
    /// The leaf is one spatial chunk of a large object.
    pub const FLAG_CHUNK: u32 = 1;
    /// The leaf merges several small objects into one.
    pub const FLAG_MERGED: u32 = 2;

    /// Whether the node has no children.
    pub fn is_leaf(&self) -> bool {
        self.child_count == 0
    }
}

/// What an object-rep approximates.
#[repr(u16)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RepKind {
    /// A static LOD of a leaf's geometry.
    Lod = 0,
    /// A hierarchical LOD of an interior node and all its descendants.
    Hlod = 1,
    /// A view-dependence tree (El-Sana & Chiang): the finest rep of a large
    /// object's leaf, refined per frame. Its payload range holds an embedded
    /// `.vdt` file; `len` covers only the in-core part (header, MNT,
    /// permanent triangles, checksummed by `checksum`) and `aux` the paged
    /// part after it; `error` is the tree's coarsest switch value.
    Vdt = 2,
}

impl RepKind {
    /// Decodes the on-disk tag.
    pub fn from_u16(v: u16) -> Option<Self> {
        match v {
            0 => Some(Self::Lod),
            1 => Some(Self::Hlod),
            2 => Some(Self::Vdt),
            _ => None,
        }
    }
}

/// One object-rep: its error, box, counts and payload range.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RepRecord {
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    pub node: u32,
    /// Position `i` in the node's list `N[0..Num(N)]`, coarsest first.
    pub index: u16,
    /// [`RepKind`] tag.
    pub kind: u16,
    /// Object-space error in scene units (simplification plus quantisation).
    pub error: f32,
    /// CRC-32 of the payload bytes.
    pub checksum: u32,
    /// Payload offset, a multiple of [`BLOCK`].
    pub offset: u64,
    /// Payload length (without the padding to the next block).
    pub len: u32,
    pub tri_count: u32,
    pub vertex_count: u32,
    /// [`RepKind::Vdt`]: bytes of the embedded tree after `len` (its
    /// meta-nodes and flat layout, paged at run time); 0 for other kinds.
    pub aux: u32,
}
const _: () = assert!(size_of::<RepRecord>() == 64);

impl RepRecord {
    /// The decoded kind, if the tag is known.
    pub fn rep_kind(&self) -> Option<RepKind> {
        RepKind::from_u16(self.kind)
    }

    /// Whether this rep is a view-dependence tree.
    pub fn is_vdt(&self) -> bool {
        self.kind == RepKind::Vdt as u16
    }

    /// Bytes the rep occupies in the data section (`len`, plus `aux` for a
    /// view-dependence tree).
    pub fn extent(&self) -> u64 {
        u64::from(self.len) + u64::from(self.aux)
    }
}

impl From<std::io::Error> for FormatError {
    fn from(e: std::io::Error) -> Self {
        Self::Io(e)
    }
}

/// Errors from reading or writing a scene file.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The message includes the I/O error's, so it is not also a source
    /// (an `anyhow` chain would print it twice).
    #[error("I/O error: {0}")]
    Io(std::io::Error),
    #[error("not a scene file (bad magic {0:02x?})")]
    BadMagic([u8; 8]),
    #[error(
        "unsupported format version {found} (this build reads {OLDEST_VERSION} to {VERSION}): rebuild the scene with this hlod-build"
    )]
    UnsupportedVersion { found: u32 },
    #[error("file truncated: {what} needs bytes up to {need}, file has {have}")]
    Truncated {
        what: &'static str,
        need: u64,
        have: u64,
    },
    #[error("checksum mismatch in {what}: stored {stored:08x}, computed {computed:08x}")]
    Checksum {
        what: String,
        stored: u32,
        computed: u32,
    },
    #[error("corrupt header: {0}")]
    BadHeader(String),
    #[error("rep {rep}: {reason}")]
    BadRep { rep: u32, reason: String },
    #[error("invalid hierarchy: {0}")]
    Invalid(#[from] ValidationError),
    #[error("scene too large for the format: {0}")]
    TooLarge(String),
    /// What the file claims needs more memory than this machine has.
    #[error("{0}")]
    TooLargeForMachine(String),
}

#[cfg(test)]
mod tests;
