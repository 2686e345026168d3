//! A scene's walk section, read chunk by chunk as the walker needs them,
//! with the chunks held bounded by bytes.

use crate::evict::lru::LruMap;

use super::{Grid, SolidMap};
use crate::format::FormatError;
use crate::format::walk::{CHUNK_CELLS, Chunk, ChunkRecord, Column, WalkIndex, locate};
use crate::io::ByteSource;

/// The walk section of a scene: its index in core, chunks on demand.
pub struct WalkMap<S: ByteSource> {
    source: S,
    /// Where the section starts in the source.
    offset: u64,
    index: WalkIndex,
    chunks: LruMap<(i32, i32), Chunk>,
    held: usize,
    cap: usize,
    /// Chunks read so far.
    pub reads: u64,
}

impl<S: ByteSource> std::fmt::Debug for WalkMap<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WalkMap")
            .field("chunks", &self.index.chunks.len())
            .field("held", &self.held)
            .finish_non_exhaustive()
    }
}

/// Bytes of chunks a [`WalkMap`] holds at most by default: a 3 × 3
/// neighbourhood of busy chunks several times over.
pub const DEFAULT_CAP: usize = 2 << 20;

impl<S: ByteSource> WalkMap<S> {
    /// A map over the section at `offset` of `source` whose index is
    /// `index`, holding at most `cap` bytes of chunks (and always the last
    /// one read).
    pub fn new(source: S, offset: u64, index: WalkIndex, cap: usize) -> Self {
        Self {
            source,
            offset,
            index,
            chunks: LruMap::default(),
            held: 0,
            cap,
            reads: 0,
        }
    }

    /// The walk section of the scene file in `source` (its header read and
    /// checked, not its skeleton), if it has one: a scene built before
    /// format version 5 has not.
    pub fn open(source: S, cap: usize) -> Result<Option<Self>, FormatError> {
        Ok(crate::format::walk_index_of(&source)?
            .map(|(offset, index)| Self::new(source, offset, index, cap)))
    }

    /// Bytes held: the index and the chunks in the cache.
    pub fn resident_bytes(&self) -> usize {
        self.index.heap_bytes() + self.held
    }

    /// The index's bytes alone (what stays in core).
    pub fn index_bytes(&self) -> usize {
        self.index.heap_bytes()
    }

    fn read(&mut self, rec: ChunkRecord) -> Result<Chunk, FormatError> {
        self.reads += 1;
        crate::format::read_walk_chunk_at(&self.source, self.offset, &rec)
    }
}

impl<S: ByteSource> SolidMap for WalkMap<S> {
    fn grid(&self) -> Grid {
        let h = &self.index.header;
        Grid {
            cell: h.cell,
            quantum: h.quantum,
            y_base: h.y_base,
        }
    }

    fn column(&mut self, x: i64, z: i64) -> Result<Column<'_>, FormatError> {
        let Some(((cx, cz), c)) = locate(x, z) else {
            return Ok(Column::default());
        };
        let Some(&rec) = self.index.find(cx, cz) else {
            return Ok(Column::default());
        };
        if !self.chunks.contains((cx, cz)) {
            let chunk = self.read(rec)?;
            self.held += chunk.heap_bytes();
            self.chunks.put((cx, cz), chunk);
            while self.held > self.cap && self.chunks.len() > 1 {
                if let Some((_, old)) = self.chunks.pop_victim() {
                    self.held -= old.heap_bytes();
                }
            }
        }
        let chunk = self.chunks.get((cx, cz)).expect("inserted above");
        Ok(chunk.column(c % CHUNK_CELLS, c / CHUNK_CELLS))
    }
}
