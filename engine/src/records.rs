//! The on-disk records and constants of the scene format (see
//! [`crate::format`]): plain data, with their sizes asserted. The skeleton
//! and the format's reader and writer both build on these; this module
//! depends on neither.

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

#[cfg(not(target_endian = "little"))]
compile_error!("the scene format is little-endian and this engine reads it by casting");

/// File magic: the first eight bytes of every scene file.
pub const MAGIC: [u8; 8] = *b"OOCHLOD\0";
/// The format version this build writes (and the newest it reads).
/// Version 6 adds the placements of shared reps (after the rep records);
/// version 5 the walk section; version 4 the Multi-Triangulation rep kind; version 3 packs the
/// reps on [`REP_ALIGN`] boundaries; versions 1 and 2 padded every rep to a
/// [`BLOCK`].
pub const VERSION: u32 = 6;
/// The oldest version this build reads (no origin, no object section).
pub const OLDEST_VERSION: u32 = 1;
/// Alignment of the data section, the skeleton section and of every
/// view-dependence tree rep (whose pages are sized to it).
pub const BLOCK: u64 = 4096;
/// Alignment of a mesh rep's payload (version 3): reps of a few KB packed
/// back to back, so that reading a run of them is one sequential read with
/// no padding between (at this scale a 4 KiB pad per rep was a third of
/// the file).
pub const REP_ALIGN: u64 = 16;
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
    /// What the scene was built from: a hash of the input's bytes (the
    /// model and its buffers) and of the build parameters, as the builder
    /// keys its cache and its shards (zero when not recorded: files of
    /// earlier builds, scenes built in memory). Inside the header's CRC.
    pub source_key: [u8; 16],
    /// Of `input_triangles`, those the finest reps hold (degenerate ones
    /// and hidden objects' left out), as the low and high halves of a
    /// `u64` (the header has no 8-aligned room left); zero when not
    /// recorded (files of earlier builds). Inside the header's CRC.
    pub drawn_triangles: [u32; 2],
    /// Of `input_triangles`, those of objects left out by default (IFC
    /// opening voids and spaces), as `drawn_triangles`.
    pub hidden_triangles: [u32; 2],
    /// CRC-32 of the walk section's header and index (version 5).
    pub walk_crc: u32,
    /// The walk section (after the object section; length 0 when absent):
    /// solid space for walking ([`crate::format::walk`]).
    pub walk_offset: u64,
    pub walk_len: u64,
    /// [`RepPlacement`] records after the rep records in the skeleton
    /// section (version 6; zero before).
    pub placement_count: u64,
    pub reserved: [u64; 5],
}
const _: () = assert!(size_of::<FileHeader>() == 256);

/// The header of versions 2 to 4: the version-5 one up to `hidden_triangles`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FileHeaderV2 {
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
    /// What the scene was built from: a hash of the input's bytes (the
    /// model and its buffers) and of the build parameters, as the builder
    /// keys its cache and its shards (zero when not recorded: files of
    /// earlier builds, scenes built in memory). Inside the header's CRC.
    pub source_key: [u8; 16],
    /// Of `input_triangles`, those the finest reps hold (degenerate ones
    /// and hidden objects' left out), as the low and high halves of a
    /// `u64` (the header has no 8-aligned room left); zero when not
    /// recorded (files of earlier builds). Inside the header's CRC.
    pub drawn_triangles: [u32; 2],
    /// Of `input_triangles`, those of objects left out by default (IFC
    /// opening voids and spaces), as `drawn_triangles`.
    pub hidden_triangles: [u32; 2],
    pub reserved: [u32; 1],
}
const _: () = assert!(size_of::<FileHeaderV2>() == 192);

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

/// A `u64` stored as two `u32` halves (low first).
pub fn split_u64(v: u64) -> [u32; 2] {
    [v as u32, (v >> 32) as u32]
}

/// The `u64` of [`split_u64`]'s halves.
pub fn join_u64(h: [u32; 2]) -> u64 {
    u64::from(h[0]) | (u64::from(h[1]) << 32)
}

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
            source_key: [0; 16],
            drawn_triangles: [0; 2],
            hidden_triangles: [0; 2],
            walk_crc: 0,
            walk_offset: self.file_len,
            walk_len: 0,
            placement_count: 0,
            reserved: [0; 5],
        }
    }
}

impl FileHeaderV2 {
    /// The same facts in the version-5 layout (no walk section).
    /// `header_crc` keeps the old value.
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
            origin: self.origin,
            objects_offset: self.objects_offset,
            objects_len: self.objects_len,
            objects_crc: self.objects_crc,
            source_key: self.source_key,
            drawn_triangles: self.drawn_triangles,
            hidden_triangles: self.hidden_triangles,
            walk_crc: 0,
            walk_offset: self.file_len,
            walk_len: 0,
            placement_count: 0,
            reserved: [0; 5],
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
    /// A Multi-Triangulation (Holst & Schumann; format version 4): the
    /// finest rep of a large object's leaf, cut per frame. Its payload range
    /// holds an embedded MT file; `len` covers the in-core part (header,
    /// node directory, partition table, checksummed by `checksum`) and
    /// `aux` the node records after it (each with its own CRC in the
    /// directory); `error` is the error of its coarsest cut.
    Mt = 3,
}

impl RepKind {
    /// Decodes the on-disk tag.
    pub fn from_u16(v: u16) -> Option<Self> {
        match v {
            0 => Some(Self::Lod),
            1 => Some(Self::Hlod),
            2 => Some(Self::Vdt),
            3 => Some(Self::Mt),
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
    /// Payload offset: a multiple of [`REP_ALIGN`] (of [`BLOCK`] for a
    /// view-dependence tree, and for every rep before version 3).
    pub offset: u64,
    /// Bytes stored (without padding). A mesh rep's payload may be
    /// compressed (version 3): it is then shorter than the
    /// [`RepRecord::resident_len`] it expands to.
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

    /// Bytes the rep takes while resident: a mesh rep's expanded payload
    /// ([`rep_payload_len`] of its counts, whether stored compressed or
    /// not), a view-dependence tree's or MT's in-core part (`len`).
    pub fn resident_len(&self) -> u64 {
        if self.is_paged() {
            u64::from(self.len)
        } else {
            rep_payload_len(self.vertex_count as usize, self.tri_count as usize * 3) as u64
        }
    }

    /// Bytes of the rep in core when all of it is loaded: its resident
    /// payload, and a tree's paged part (what in-core mode holds).
    pub fn expanded_extent(&self) -> u64 {
        self.resident_len() + u64::from(self.aux)
    }

    /// Bytes a load of this rep needs besides its resident payload: its
    /// compressed copy while it is decoded (none for a paged rep or one
    /// stored raw).
    pub fn load_scratch(&self) -> u64 {
        if self.is_paged() || self.resident_len() == u64::from(self.len) {
            0
        } else {
            u64::from(self.len)
        }
    }

    /// Whether this rep is a view-dependence tree.
    pub fn is_vdt(&self) -> bool {
        self.kind == RepKind::Vdt as u16
    }

    /// Whether this rep is a Multi-Triangulation.
    pub fn is_mt(&self) -> bool {
        self.kind == RepKind::Mt as u16
    }

    /// Whether this rep is refined per frame and paged from its payload
    /// range (a view-dependence tree or a Multi-Triangulation): P_I loads
    /// its in-core part, P_R pages the rest through its own store.
    pub fn is_paged(&self) -> bool {
        self.is_vdt() || self.is_mt()
    }

    /// Bytes the rep occupies in the data section (`len`, plus `aux` for a
    /// view-dependence tree or an MT).
    pub fn extent(&self) -> u64 {
        u64::from(self.len) + u64::from(self.aux)
    }
}

/// A mesh rep whose payload is shared (format version 6): an instanced
/// mesh's level, stored once in the mesh's own coordinates and placed by
/// every instance's rep with its transform. The rep's record keeps its own
/// box (in scene coordinates), node, index and error; its payload range,
/// checksum and counts are those of `source`, the first rep that places
/// the payload (its own record, `source == rep`, names it in the payload's
/// header).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RepPlacement {
    pub rep: u32,
    pub source: u32,
    /// Rows of the affine map from the payload's coordinates to the
    /// scene's: `p' = M · (p, 1)`.
    pub transform: [[f32; 4]; 3],
}
const _: () = assert!(size_of::<RepPlacement>() == 56);

impl RepPlacement {
    /// `transform` applied to a point.
    pub fn point(&self, p: [f32; 3]) -> [f32; 3] {
        let m = &self.transform;
        std::array::from_fn(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3])
    }

    /// A normal carried by the transform (its linear part's cofactor
    /// matrix: the inverse transpose up to scale), unit length.
    pub fn normal(&self, n: [f32; 3]) -> [f32; 3] {
        let m = &self.transform;
        let col = |j: usize| [m[0][j], m[1][j], m[2][j]];
        let cross = |a: [f32; 3], b: [f32; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let (c0, c1, c2) = (col(0), col(1), col(2));
        let cof = [cross(c1, c2), cross(c2, c0), cross(c0, c1)];
        let v: [f32; 3] =
            std::array::from_fn(|i| cof[0][i] * n[0] + cof[1][i] * n[1] + cof[2][i] * n[2]);
        // The cofactors are det · M⁻ᵀ: a mirroring transform flips them.
        let det = c0[0] * cof[0][0] + c0[1] * cof[0][1] + c0[2] * cof[0][2];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() * det.signum();
        if l != 0.0 && l.is_finite() {
            v.map(|c| c / l)
        } else {
            [0.0; 3]
        }
    }
}

/// Bytes of a rep payload with these counts (header, vertices, indices
/// padded to 4 B; u16 indices up to 65,536 vertices): what
/// [`crate::format::RepMesh::encode`] writes.
pub fn rep_payload_len(vertex_count: usize, index_count: usize) -> usize {
    let index_size = if vertex_count <= 1 << 16 { 2 } else { 4 };
    REP_HEADER_BYTES
        + vertex_count * PACKED_VERTEX_BYTES
        + (index_count * index_size).next_multiple_of(4)
}

/// Size of a rep payload's header ([`crate::format::RepHeader`]).
pub const REP_HEADER_BYTES: usize = 48;
/// Size of one packed vertex ([`crate::format::PackedVertex`]).
pub const PACKED_VERTEX_BYTES: usize = 16;
