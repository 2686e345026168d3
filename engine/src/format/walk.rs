//! The walk section: the scene's solid space as vertical spans per column of
//! a horizontal grid, for walking (collision, gravity, stairs) whatever reps
//! happen to be resident.
//!
//! ```text
//! WalkHeader (64 B)
//! [ChunkRecord; chunk_count]    sorted by (z, x), the index (in core)
//! chunk payloads (deflate)      read one at a time, on demand
//! ```
//!
//! A chunk covers [`CHUNK_CELLS`]² cells of `cell` metres (x and z, scene
//! coordinates) in two layers: solid (walls, slabs, stairs, furniture) and
//! doors' leaves, which a walker may pass with the doors open. Its payload,
//! inflated, is one span count per cell and layer (the solid layer's cells
//! row after row, x fastest, then the doors'), then every cell's spans in
//! the same order: `(lo, hi)` in steps of `quantum` above `y_base`, sorted,
//! disjoint, rounded outwards so that a span holds every surface that
//! touches its cell. Empty chunks are not
//! stored. The file header's CRC covers the header and the index; each
//! chunk record carries its payload's CRC.

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

use super::FormatError;

/// Section magic.
pub const WALK_MAGIC: [u8; 8] = *b"WALKMAP\0";
/// Cells along each side of a chunk.
pub const CHUNK_CELLS: usize = 32;
/// Cells of a chunk.
pub const CHUNK_AREA: usize = CHUNK_CELLS * CHUNK_CELLS;
/// Layers of a chunk: solid, then doors' leaves.
pub const LAYERS: usize = 2;
/// Spans a column keeps at most (the builder fills the smallest gaps).
pub const MAX_SPANS: usize = 255;

/// The chunk `(x, z)` holding cell `(x, z)` and the cell's index in it
/// (row after row, x fastest); `None` beyond the `i32` chunk range.
pub fn locate(x: i64, z: i64) -> Option<((i32, i32), usize)> {
    let n = CHUNK_CELLS as i64;
    let cx = i32::try_from(x.div_euclid(n)).ok()?;
    let cz = i32::try_from(z.div_euclid(n)).ok()?;
    Some(((cx, cz), (z.rem_euclid(n) * n + x.rem_euclid(n)) as usize))
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct WalkHeader {
    pub magic: [u8; 8],
    pub chunk_count: u32,
    pub chunk_cells: u32,
    /// Cell side, metres (scene units).
    pub cell: f32,
    /// Height step of the spans.
    pub quantum: f32,
    /// Height of span value 0.
    pub y_base: f32,
    pub reserved0: u32,
    pub reserved: [u32; 8],
}
const _: () = assert!(size_of::<WalkHeader>() == 64);

/// Where chunk `(x, z)` (in chunk units) lies in the section.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ChunkRecord {
    pub x: i32,
    pub z: i32,
    /// From the section's start.
    pub offset: u64,
    pub len: u32,
    pub crc: u32,
}
const _: () = assert!(size_of::<ChunkRecord>() == 24);

/// A vertical interval of solid space: `[lo, hi]` quantum steps above the base.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Pod, Zeroable)]
pub struct Span {
    pub lo: u16,
    pub hi: u16,
}
const _: () = assert!(size_of::<Span>() == 4);

/// One chunk's columns, inflated.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Chunk {
    /// `starts[c]..starts[c + 1]` are cell `c`'s spans (cells of the door
    /// layer after the solid layer's).
    starts: Vec<u32>,
    spans: Vec<Span>,
}

/// One cell's spans: solid, and doors' leaves.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Column<'a> {
    pub solid: &'a [Span],
    pub doors: &'a [Span],
}

impl Chunk {
    /// The spans of cell `(i, j)` of the chunk (`i` along x).
    pub fn column(&self, i: usize, j: usize) -> Column<'_> {
        let c = j * CHUNK_CELLS + i;
        let at = |c: usize| &self.spans[self.starts[c] as usize..self.starts[c + 1] as usize];
        Column {
            solid: at(c),
            doors: at(c + CHUNK_AREA),
        }
    }

    /// Bytes held.
    pub fn heap_bytes(&self) -> usize {
        self.starts.len() * 4 + self.spans.len() * 4
    }

    /// Encodes `columns` (`LAYERS * CHUNK_AREA` cells: the solid layer's,
    /// then the doors', each sorted and disjoint) as a payload.
    pub fn encode(columns: &[Vec<Span>]) -> Vec<u8> {
        assert_eq!(
            columns.len(),
            LAYERS * CHUNK_AREA,
            "a chunk has two layers of cells"
        );
        let mut raw = Vec::with_capacity(LAYERS * CHUNK_AREA * 5);
        raw.extend(columns.iter().map(|c| c.len().min(MAX_SPANS) as u8));
        for c in columns {
            for s in &c[..c.len().min(MAX_SPANS)] {
                raw.extend_from_slice(bytemuck::bytes_of(s));
            }
        }
        miniz_oxide::deflate::compress_to_vec(&raw, 6)
    }

    /// Decodes and checks a payload.
    pub fn decode(payload: &[u8]) -> Result<Self, String> {
        let cells = LAYERS * CHUNK_AREA;
        let limit = cells * (1 + MAX_SPANS * size_of::<Span>());
        let raw = miniz_oxide::inflate::decompress_to_vec_with_limit(payload, limit)
            .map_err(|e| format!("cannot inflate: {e}"))?;
        let counts = raw.get(..cells).ok_or("shorter than its counts")?;
        let mut starts = Vec::with_capacity(cells + 1);
        let mut n = 0u32;
        starts.push(0);
        for &c in counts {
            n += u32::from(c);
            starts.push(n);
        }
        let body = &raw[cells..];
        if body.len() != n as usize * size_of::<Span>() {
            return Err("span bytes disagree with the counts".into());
        }
        let spans: Vec<Span> = body
            .chunks_exact(4)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        for w in starts.windows(2) {
            let col = &spans[w[0] as usize..w[1] as usize];
            let ordered =
                col.iter().all(|s| s.lo <= s.hi) && col.windows(2).all(|p| p[0].hi < p[1].lo);
            if !ordered {
                return Err("a column's spans are not sorted and disjoint".into());
            }
        }
        Ok(Self { starts, spans })
    }
}

/// The decoded header and index of a walk section.
#[derive(Clone, Debug, PartialEq)]
pub struct WalkIndex {
    pub header: WalkHeader,
    pub chunks: Vec<ChunkRecord>,
    /// The section's length.
    pub len: u64,
}

impl WalkIndex {
    /// Bytes of the header and index (what the file header's CRC covers).
    pub fn index_len(chunk_count: u32) -> u64 {
        size_of::<WalkHeader>() as u64 + u64::from(chunk_count) * size_of::<ChunkRecord>() as u64
    }

    /// Encodes a section from `chunks` (`(x, z)` and payload, any order).
    pub fn encode(
        cell: f32,
        quantum: f32,
        y_base: f32,
        chunks: &[((i32, i32), Vec<u8>)],
    ) -> Vec<u8> {
        let mut sorted: Vec<&((i32, i32), Vec<u8>)> = chunks.iter().collect();
        sorted.sort_by_key(|((x, z), _)| (*z, *x));
        let header = WalkHeader {
            magic: WALK_MAGIC,
            chunk_count: sorted.len() as u32,
            chunk_cells: CHUNK_CELLS as u32,
            cell,
            quantum,
            y_base,
            ..WalkHeader::default()
        };
        let mut at = Self::index_len(header.chunk_count);
        let mut recs = Vec::with_capacity(sorted.len());
        for ((x, z), p) in &sorted {
            recs.push(ChunkRecord {
                x: *x,
                z: *z,
                offset: at,
                len: p.len() as u32,
                crc: crc32fast::hash(p),
            });
            at += p.len() as u64;
        }
        let mut out = bytemuck::bytes_of(&header).to_vec();
        out.extend_from_slice(bytemuck::cast_slice(&recs));
        for (_, p) in sorted {
            out.extend_from_slice(p);
        }
        out
    }

    /// Decodes and checks the header and index (`bytes`: at least the
    /// index) of a section of `len` bytes.
    pub fn decode(bytes: &[u8], len: u64) -> Result<Self, FormatError> {
        let bad = |s: &str| FormatError::BadHeader(format!("walk section: {s}"));
        let hsize = size_of::<WalkHeader>();
        let header: WalkHeader = bytemuck::pod_read_unaligned(
            bytes
                .get(..hsize)
                .ok_or_else(|| bad("shorter than its header"))?,
        );
        if header.magic != WALK_MAGIC {
            return Err(bad("bad magic"));
        }
        if header.chunk_cells as usize != CHUNK_CELLS {
            return Err(bad("chunk size is not 32 cells"));
        }
        // Sane ranges: a cell of a centimetre to 100 m, a height step of a
        // tenth of a millimetre to 100 m (a walker queries (0.2 m / cell)²
        // cells per step).
        let cell_ok = (0.01..=100.0).contains(&header.cell);
        let quantum_ok = (1e-4..=100.0).contains(&header.quantum);
        if !cell_ok || !quantum_ok || !header.y_base.is_finite() {
            return Err(bad(
                "cell (0.01 to 100 m), quantum (0.1 mm to 100 m) or base out of range",
            ));
        }
        let index_len = Self::index_len(header.chunk_count);
        if index_len > len || (bytes.len() as u64) < index_len {
            return Err(bad("shorter than its index"));
        }
        let chunks: Vec<ChunkRecord> = bytes[hsize..index_len as usize]
            .chunks_exact(size_of::<ChunkRecord>())
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let sorted = chunks
            .windows(2)
            .all(|w| (w[0].z, w[0].x) < (w[1].z, w[1].x));
        let inside = chunks.iter().all(|c| {
            c.offset >= index_len
                && c.offset
                    .checked_add(u64::from(c.len))
                    .is_some_and(|e| e <= len)
        });
        if !sorted || !inside {
            return Err(bad("chunk records are unsorted or out of range"));
        }
        Ok(Self {
            header,
            chunks,
            len,
        })
    }

    /// The record of chunk `(x, z)`, if it holds anything.
    pub fn find(&self, x: i32, z: i32) -> Option<&ChunkRecord> {
        self.chunks
            .binary_search_by(|c| (c.z, c.x).cmp(&(z, x)))
            .ok()
            .map(|k| &self.chunks[k])
    }

    /// Bytes the index holds in core.
    pub fn heap_bytes(&self) -> usize {
        self.chunks.len() * size_of::<ChunkRecord>() + size_of::<WalkHeader>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns() -> Vec<Vec<Span>> {
        let mut c = vec![Vec::new(); LAYERS * CHUNK_AREA];
        c[0] = vec![Span { lo: 0, hi: 10 }, Span { lo: 150, hi: 160 }];
        c[33] = vec![Span { lo: 5, hi: 5 }];
        c[CHUNK_AREA + 33] = vec![Span { lo: 6, hi: 100 }];
        c
    }

    #[test]
    fn chunks_and_index_round_trip() {
        let p = Chunk::encode(&columns());
        let c = Chunk::decode(&p).unwrap();
        assert_eq!(c.column(0, 0).solid, &columns()[0][..]);
        assert!(c.column(0, 0).doors.is_empty());
        assert_eq!(c.column(1, 1).solid, &columns()[33][..]);
        assert_eq!(c.column(1, 1).doors, &[Span { lo: 6, hi: 100 }]);
        assert_eq!(c.column(5, 7), Column::default());
        let s = WalkIndex::encode(0.1, 0.02, -1.0, &[((3, -2), p.clone()), ((-1, -2), p)]);
        let idx = WalkIndex::decode(&s, s.len() as u64).unwrap();
        assert_eq!(idx.chunks.len(), 2);
        assert_eq!(idx.chunks[0].x, -1, "sorted by (z, x)");
        let r = idx.find(3, -2).unwrap();
        let payload = &s[r.offset as usize..(r.offset + u64::from(r.len)) as usize];
        assert_eq!(crc32fast::hash(payload), r.crc);
        assert!(idx.find(0, 0).is_none());
    }

    #[test]
    fn damaged_sections_and_chunks_are_refused() {
        let p = Chunk::encode(&columns());
        let s = WalkIndex::encode(0.1, 0.02, 0.0, &[((0, 0), p.clone())]);
        assert!(WalkIndex::decode(&s[..10], 10).is_err());
        assert!(
            WalkIndex::decode(&s, s.len() as u64 - 1).is_err(),
            "payload past the end"
        );
        let mut bad = s.clone();
        bad[16..20].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(WalkIndex::decode(&bad, bad.len() as u64).is_err());
        assert!(Chunk::decode(&p[..p.len() / 2]).is_err());
        let mut unsorted = columns();
        unsorted[0].swap(0, 1);
        assert!(Chunk::decode(&Chunk::encode(&unsorted)).is_err());
    }
}
