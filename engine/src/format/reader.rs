//! The validating scene reader: header and skeleton at open, reps on demand.

use std::mem::size_of;
use std::path::Path;
use std::sync::Arc;

use super::objects::ObjectTable;
use super::walk::{Chunk, ChunkRecord, WalkIndex};
use super::{
    BLOCK, FileHeader, FileHeaderV1, FileHeaderV2, FormatError, MAGIC, NodeRecord, RepMesh,
    RepPlacement, RepRecord, VERSION,
};
use crate::io::{ByteSource, FileSource, MemSource};
use crate::skeleton::{RepId, Skeleton};
use crate::vdt::file::VdtFile;

/// Scene-level facts stored in the header besides the skeleton.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneMeta {
    /// Objects (glTF mesh instances) in the source.
    pub object_count: u32,
    /// Source triangles after instancing.
    pub input_triangles: u64,
    /// World position of the scene's origin (stored coordinates are relative to it).
    pub origin: [f64; 3],
    /// What the scene was built from ([`crate::FileHeader::source_key`]).
    pub source_key: [u8; 16],
    /// Of the input triangles, those the finest reps hold (0: not recorded).
    pub drawn_triangles: u64,
    /// Of the input triangles, those of objects left out by default.
    pub hidden_triangles: u64,
}

/// An opened scene: the validated header and skeleton in core, the source kept
/// for reading reps.
#[derive(Debug)]
pub struct SceneFile<S: ByteSource = FileSource> {
    source: S,
    header: FileHeader,
    skeleton: Skeleton,
}

impl SceneFile<FileSource> {
    /// Opens and validates the scene file at `path` (reads no rep data).
    pub fn open(path: &Path) -> Result<Self, FormatError> {
        Self::from_source(FileSource::open(path)?)
    }
}

impl<S: ByteSource> SceneFile<S> {
    /// Reads and validates the header and the skeleton from `source`.
    pub fn from_source(source: S) -> Result<Self, FormatError> {
        let header = read_header(&source)?;
        // The records need this much memory once checked: refuse a count
        // the machine cannot hold before reading anything.
        let limit = crate::limits::memory_total();
        if header.skeleton_len > limit {
            return Err(FormatError::TooLargeForMachine(format!(
                "the skeleton of {} nodes and {} reps needs {}, more than this machine's memory ({})",
                header.node_count,
                header.rep_count,
                crate::limits::human(header.skeleton_len),
                crate::limits::human(limit)
            )));
        }
        // The checksum first, read in chunks: a header that lies about
        // its counts costs no memory.
        let computed = chunked_crc(&source, header.skeleton_offset, header.skeleton_len)?;
        if computed != header.skeleton_crc {
            return Err(FormatError::Checksum {
                what: "skeleton".into(),
                stored: header.skeleton_crc,
                computed,
            });
        }
        let node_bytes = u64::from(header.node_count) * size_of::<NodeRecord>() as u64;
        let nodes: Vec<NodeRecord> = read_records(&source, header.skeleton_offset, node_bytes)?;
        let rep_bytes = u64::from(header.rep_count) * size_of::<RepRecord>() as u64;
        let reps: Vec<RepRecord> =
            read_records(&source, header.skeleton_offset + node_bytes, rep_bytes)?;
        let placements: Vec<RepPlacement> = read_records(
            &source,
            header.skeleton_offset + node_bytes + rep_bytes,
            header.skeleton_len - node_bytes - rep_bytes,
        )?;
        let skeleton = Skeleton {
            nodes,
            reps,
            placements,
        };
        skeleton.validate(header.data_offset, header.data_offset + header.data_len)?;
        Ok(Self {
            source,
            header,
            skeleton,
        })
    }

    /// The file header.
    pub fn header(&self) -> &FileHeader {
        &self.header
    }

    /// The in-core skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// Scene-level facts.
    pub fn meta(&self) -> SceneMeta {
        SceneMeta {
            object_count: self.header.object_count,
            input_triangles: self.header.input_triangles,
            origin: self.header.origin,
            source_key: self.header.source_key,
            drawn_triangles: crate::records::join_u64(self.header.drawn_triangles),
            hidden_triangles: crate::records::join_u64(self.header.hidden_triangles),
        }
    }

    /// The raw object section (empty when the file has none), checked
    /// against its CRC. Never read on the rendering path.
    pub fn read_objects_bytes(&self) -> Result<Vec<u8>, FormatError> {
        let h = &self.header;
        let mut buf = crate::limits::alloc_bytes(h.objects_len, "the object section")
            .map_err(|e| FormatError::TooLargeForMachine(e.to_string()))?;
        self.source.read_at(h.objects_offset, &mut buf)?;
        let computed = crc32fast::hash(&buf);
        if computed != h.objects_crc {
            return Err(FormatError::Checksum {
                what: "object section".into(),
                stored: h.objects_crc,
                computed,
            });
        }
        Ok(buf)
    }

    /// The object section decoded: names and extras of the source
    /// objects, and which object each triangle of a merged leaf's finest
    /// rep belongs to. Loaded on demand (for picking), checked.
    pub fn read_objects(&self) -> Result<ObjectTable, FormatError> {
        ObjectTable::decode(&self.read_objects_bytes()?, &self.skeleton)
    }

    /// The walk section's header and index, checked against the header's
    /// CRC; `None` when the file has none (built before version 5).
    pub fn read_walk_index(&self) -> Result<Option<WalkIndex>, FormatError> {
        walk_index(&self.source, &self.header)
    }

    /// One chunk of the walk section, read, checked against its CRC and
    /// decoded.
    pub fn read_walk_chunk(&self, rec: &ChunkRecord) -> Result<Chunk, FormatError> {
        read_walk_chunk_at(&self.source, self.header.walk_offset, rec)
    }

    /// The whole walk section (empty when absent), every chunk checked:
    /// what a rewrite of the file copies.
    pub fn read_walk_bytes(&self) -> Result<Vec<u8>, FormatError> {
        let Some(index) = self.read_walk_index()? else {
            return Ok(Vec::new());
        };
        let mut buf = crate::limits::alloc_bytes(self.header.walk_len, "the walk section")
            .map_err(|e| FormatError::TooLargeForMachine(e.to_string()))?;
        self.source.read_at(self.header.walk_offset, &mut buf)?;
        for rec in &index.chunks {
            let at = rec.offset as usize;
            check_walk_chunk(rec, &buf[at..at + rec.len as usize])?;
        }
        Ok(buf)
    }

    /// The byte source reps are read from.
    pub fn source(&self) -> &S {
        &self.source
    }

    /// Reads rep `rep`'s payload and checks its CRC.
    pub fn read_rep_bytes(&self, rep: RepId) -> Result<Vec<u8>, FormatError> {
        let rec = self.record(rep)?;
        let mut buf = vec![0u8; rec.len as usize];
        self.source.read_at(rec.offset, &mut buf)?;
        check_rep_crc(rep, rec, &buf)?;
        Ok(buf)
    }

    /// Reads and decodes rep `rep` (a static mesh: not a view-dependence tree).
    pub fn read_rep(&self, rep: RepId) -> Result<RepMesh, FormatError> {
        if self.record(rep)?.is_paged() {
            return Err(FormatError::BadRep {
                rep,
                reason: "a view-dependence tree or MT, not a mesh".into(),
            });
        }
        // A shared payload is read as its source rep's and placed as this one.
        let src = self.skeleton.payload_rep(rep);
        let bytes = self.read_rep_bytes(src)?;
        let mut mesh = RepMesh::decode(&bytes, src, self.record(src)?)?;
        mesh.placement = self.skeleton.placement(rep).copied();
        Ok(mesh)
    }

    /// Reads the whole embedded view-dependence tree of rep `rep` and opens
    /// it (its in-core part checked against the record).
    pub fn read_vdt(&self, rep: RepId) -> Result<VdtFile, FormatError> {
        let rec = *self.record(rep)?;
        let bad = |reason: String| FormatError::BadRep { rep, reason };
        if !rec.is_vdt() {
            return Err(bad("not a view-dependence tree".into()));
        }
        let mut buf = crate::limits::alloc_bytes(rec.extent(), "a view-dependence tree")
            .map_err(|e| bad(e.to_string()))?;
        self.source.read_at(rec.offset, &mut buf)?;
        check_rep_crc(rep, &rec, &buf[..rec.len as usize])?;
        let file = VdtFile::open(Arc::new(MemSource::new(buf))).map_err(|e| bad(e.to_string()))?;
        check_vdt_record(rep, &rec, &file)?;
        Ok(file)
    }

    /// Reads the whole embedded Multi-Triangulation of rep `rep` and opens
    /// it (its in-core part checked against the record).
    pub fn read_mt(&self, rep: RepId) -> Result<crate::mt::file::MtFile, FormatError> {
        let rec = *self.record(rep)?;
        let bad = |reason: String| FormatError::BadRep { rep, reason };
        if !rec.is_mt() {
            return Err(bad("not a Multi-Triangulation".into()));
        }
        let mut buf = crate::limits::alloc_bytes(rec.extent(), "a Multi-Triangulation")
            .map_err(|e| bad(e.to_string()))?;
        self.source.read_at(rec.offset, &mut buf)?;
        check_rep_crc(rep, &rec, &buf[..rec.len as usize])?;
        let file = crate::mt::file::MtFile::open(Arc::new(MemSource::new(buf)))
            .map_err(|e| bad(e.to_string()))?;
        let h = &file.header;
        if h.data_offset != u64::from(rec.len)
            || h.data_len != u64::from(rec.aux)
            || h.input_triangles != u64::from(rec.tri_count)
        {
            return Err(bad(
                "embedded Multi-Triangulation disagrees with its record".into(),
            ));
        }
        Ok(file)
    }

    /// Reads MT rep `rep` and checks every node record.
    pub fn verify_mt(&self, rep: RepId) -> Result<(), FormatError> {
        let file = self.read_mt(rep)?;
        for (n, r) in file
            .read_nodes(0, file.header.node_count)
            .map_err(|e| FormatError::BadRep {
                rep,
                reason: e.to_string(),
            })?
            .into_iter()
            .enumerate()
        {
            r.map_err(|e| FormatError::BadRep {
                rep,
                reason: format!("MT node {n}: {e}"),
            })?;
        }
        Ok(())
    }

    /// Reads and decodes every rep (every meta-node of a view-dependence
    /// tree, every node of an MT): a full integrity check of the data
    /// section.
    pub fn verify_all_reps(&self) -> Result<(), FormatError> {
        for rep in 0..self.skeleton.reps.len() as RepId {
            if self.skeleton.reps[rep as usize].is_mt() {
                self.verify_mt(rep)?;
            } else if self.skeleton.reps[rep as usize].is_vdt() {
                self.verify_tree(rep)?;
            } else {
                self.read_rep(rep)?;
            }
        }
        Ok(())
    }

    /// Reads view-dependence tree rep `rep` and every one of its meta-nodes.
    pub fn verify_tree(&self, rep: RepId) -> Result<(), FormatError> {
        let file = self.read_vdt(rep)?;
        for m in 0..file.header.meta_count {
            file.read_meta(m).map_err(|e| FormatError::BadRep {
                rep,
                reason: format!("meta-node {m}: {e}"),
            })?;
        }
        Ok(())
    }

    fn record(&self, rep: RepId) -> Result<&RepRecord, FormatError> {
        self.skeleton
            .reps
            .get(rep as usize)
            .ok_or_else(|| FormatError::BadRep {
                rep,
                reason: format!("no such rep ({} in the scene)", self.skeleton.reps.len()),
            })
    }
}

/// Checks an opened embedded tree against its rep record: the in-core part
/// and the root meta-nodes are exactly `len` bytes, the whole file `len + aux`, and the counts agree.
pub fn check_vdt_record(rep: RepId, rec: &RepRecord, file: &VdtFile) -> Result<(), FormatError> {
    let h = &file.header;
    if file.core_bytes() + file.root_bytes() != u64::from(rec.len)
        || file.source.len() != rec.extent()
        || h.leaf_count != rec.vertex_count
        || h.triangle_count != rec.tri_count
    {
        return Err(FormatError::BadRep {
            rep,
            reason: "embedded view-dependence tree disagrees with its record".into(),
        });
    }
    Ok(())
}

/// Checks a payload read by other means (e.g. block by block) against its record.
pub fn check_rep_crc(rep: RepId, rec: &RepRecord, bytes: &[u8]) -> Result<(), FormatError> {
    let computed = crc32fast::hash(bytes);
    if computed != rec.checksum {
        return Err(FormatError::Checksum {
            what: format!("rep {rep}"),
            stored: rec.checksum,
            computed,
        });
    }
    Ok(())
}

/// Bytes read at once while checking or decoding the skeleton.
const CHUNK: u64 = 1 << 20;

/// Calls `f` with the `len` bytes at `offset`, read `chunk` bytes at a time
/// into one buffer.
fn for_each_chunk(
    source: &impl ByteSource,
    offset: u64,
    len: u64,
    chunk: u64,
    mut f: impl FnMut(&[u8]),
) -> Result<(), FormatError> {
    let mut buf = vec![0u8; chunk.min(len) as usize];
    let mut at = 0;
    while at < len {
        let n = (len - at).min(chunk) as usize;
        source.read_at(offset + at, &mut buf[..n])?;
        f(&buf[..n]);
        at += n as u64;
    }
    Ok(())
}

/// CRC-32 of `len` bytes at `offset`, read a chunk at a time.
fn chunked_crc(source: &impl ByteSource, offset: u64, len: u64) -> Result<u32, FormatError> {
    let mut h = crc32fast::Hasher::new();
    for_each_chunk(source, offset, len, CHUNK, |b| h.update(b))?;
    Ok(h.finalize())
}

/// The `len / size_of::<T>()` records at `offset`, decoded a chunk at a
/// time into a fallibly reserved vector.
fn read_records<T: bytemuck::Pod>(
    source: &impl ByteSource,
    offset: u64,
    len: u64,
) -> Result<Vec<T>, FormatError> {
    let size = size_of::<T>() as u64;
    let count = usize::try_from(len / size)
        .map_err(|_| FormatError::TooLargeForMachine("too many records".into()))?;
    let mut out = Vec::new();
    out.try_reserve_exact(count).map_err(|_| {
        FormatError::TooLargeForMachine(format!(
            "cannot allocate {} for the skeleton",
            crate::limits::human(len)
        ))
    })?;
    // Whole records per chunk.
    for_each_chunk(source, offset, len, CHUNK / size * size, |b| {
        out.extend(
            b.chunks_exact(size as usize)
                .map(bytemuck::pod_read_unaligned::<T>),
        );
    })?;
    Ok(out)
}

fn read_header(source: &impl ByteSource) -> Result<FileHeader, FormatError> {
    let have = source.len();
    let truncated = |need: u64| FormatError::Truncated {
        what: "header",
        need,
        have,
    };
    if have < 16 {
        return Err(truncated(16));
    }
    let mut head = [0u8; 16];
    source.read_at(0, &mut head)?;
    let magic: [u8; 8] = head[..8].try_into().expect("8 bytes");
    if magic != MAGIC {
        return Err(FormatError::BadMagic(magic));
    }
    let version = u32::from_le_bytes(head[8..12].try_into().expect("4 bytes"));
    let header = match version {
        1 => {
            let hsize = size_of::<FileHeaderV1>();
            if have < hsize as u64 {
                return Err(truncated(hsize as u64));
            }
            let mut buf = vec![0u8; hsize];
            source.read_at(0, &mut buf)?;
            let v1: FileHeaderV1 = bytemuck::pod_read_unaligned(&buf);
            let mut zeroed = v1;
            zeroed.header_crc = 0;
            check_header_crc(v1.header_crc, bytemuck::bytes_of(&zeroed))?;
            if v1.header_size as usize != hsize {
                return Err(FormatError::BadHeader("header size".into()));
            }
            v1.upgrade()
        }
        2..=4 => read_sized::<FileHeaderV2>(source, have)?.upgrade(),
        // Version 5's header is version 6's with no placements.
        5 | VERSION => read_sized::<FileHeader>(source, have)?,
        found => return Err(FormatError::UnsupportedVersion { found }),
    };
    let bad = |s: &str| Err(FormatError::BadHeader(s.to_string()));
    if header.file_len > have {
        return Err(FormatError::Truncated {
            what: "file",
            need: header.file_len,
            have,
        });
    }
    if header.placement_count > u64::from(header.rep_count) {
        return bad("more placements than reps");
    }
    let records = u64::from(header.node_count) * size_of::<NodeRecord>() as u64
        + u64::from(header.rep_count) * size_of::<RepRecord>() as u64
        + header.placement_count * size_of::<RepPlacement>() as u64;
    if header.data_offset != BLOCK
        || header.data_offset.checked_add(header.data_len) != Some(header.skeleton_offset)
        || !header.skeleton_offset.is_multiple_of(BLOCK)
        || header.skeleton_len != records
        || header.skeleton_offset.checked_add(header.skeleton_len) != Some(header.objects_offset)
        || header.objects_offset.checked_add(header.objects_len) != Some(header.walk_offset)
        || header.walk_offset.checked_add(header.walk_len) != Some(header.file_len)
    {
        return bad("section ranges are inconsistent");
    }
    if !header.origin.iter().all(|c| c.is_finite()) {
        return bad("origin is not finite");
    }
    if header.file_len != have {
        return bad("file is longer than the header says");
    }
    Ok(header)
}

/// Where the walk section of the file in `source` starts, and its index:
/// the header is read and checked, not the skeleton (what walk mode needs
/// of a scene already open). `None` when the file has no walk section.
pub fn walk_index_of(source: &impl ByteSource) -> Result<Option<(u64, WalkIndex)>, FormatError> {
    let h = read_header(source)?;
    Ok(walk_index(source, &h)?.map(|i| (h.walk_offset, i)))
}

/// The walk section's header and index of the file whose header is `h`,
/// checked against its CRC.
fn walk_index(source: &impl ByteSource, h: &FileHeader) -> Result<Option<WalkIndex>, FormatError> {
    if h.walk_len == 0 {
        return Ok(None);
    }
    let mut head = vec![0u8; size_of::<super::walk::WalkHeader>().min(h.walk_len as usize)];
    source.read_at(h.walk_offset, &mut head)?;
    let count = if head.len() >= 12 {
        u32::from_le_bytes(head[8..12].try_into().expect("4 bytes"))
    } else {
        0
    };
    let index_len = WalkIndex::index_len(count).min(h.walk_len);
    let mut buf = crate::limits::alloc_bytes(index_len, "the walk index")
        .map_err(|e| FormatError::TooLargeForMachine(e.to_string()))?;
    source.read_at(h.walk_offset, &mut buf)?;
    let computed = crc32fast::hash(&buf);
    if computed != h.walk_crc {
        return Err(FormatError::Checksum {
            what: "walk section index".into(),
            stored: h.walk_crc,
            computed,
        });
    }
    WalkIndex::decode(&buf, h.walk_len).map(Some)
}

/// Chunk `rec` of the walk section at `offset` in `source`, read, checked
/// against its CRC and decoded.
pub fn read_walk_chunk_at(
    source: &impl ByteSource,
    offset: u64,
    rec: &ChunkRecord,
) -> Result<Chunk, FormatError> {
    let mut buf = vec![0u8; rec.len as usize];
    source.read_at(offset + rec.offset, &mut buf)?;
    check_walk_chunk(rec, &buf)
}

/// Chunk `rec`'s payload `buf` checked against its CRC and decoded.
fn check_walk_chunk(rec: &ChunkRecord, buf: &[u8]) -> Result<Chunk, FormatError> {
    let computed = crc32fast::hash(buf);
    if computed != rec.crc {
        return Err(FormatError::Checksum {
            what: format!("walk chunk ({}, {})", rec.x, rec.z),
            stored: rec.crc,
            computed,
        });
    }
    Chunk::decode(buf)
        .map_err(|e| FormatError::BadHeader(format!("walk chunk ({}, {}): {e}", rec.x, rec.z)))
}

/// A header of type `H` (its CRC and `header_size` checked).
fn read_sized<H: HeaderLike>(source: &impl ByteSource, have: u64) -> Result<H, FormatError> {
    let hsize = size_of::<H>();
    if have < hsize as u64 {
        return Err(FormatError::Truncated {
            what: "header",
            need: hsize as u64,
            have,
        });
    }
    let mut buf = vec![0u8; hsize];
    source.read_at(0, &mut buf)?;
    let h: H = bytemuck::pod_read_unaligned(&buf);
    check_header_crc(h.crc(), bytemuck::bytes_of(&h.without_crc()))?;
    if h.size() as usize != hsize {
        return Err(FormatError::BadHeader("header size".into()));
    }
    Ok(h)
}

/// The fields [`read_sized`] checks.
trait HeaderLike: bytemuck::Pod {
    fn crc(&self) -> u32;
    fn size(&self) -> u32;
    fn without_crc(&self) -> Self;
}

macro_rules! header_like {
    ($t:ty) => {
        impl HeaderLike for $t {
            fn crc(&self) -> u32 {
                self.header_crc
            }
            fn size(&self) -> u32 {
                self.header_size
            }
            fn without_crc(&self) -> Self {
                Self {
                    header_crc: 0,
                    ..*self
                }
            }
        }
    };
}
header_like!(FileHeader);
header_like!(FileHeaderV2);

fn check_header_crc(stored: u32, zeroed: &[u8]) -> Result<(), FormatError> {
    let computed = crc32fast::hash(zeroed);
    if computed != stored {
        return Err(FormatError::Checksum {
            what: "header".into(),
            stored,
            computed,
        });
    }
    Ok(())
}
