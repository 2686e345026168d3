//! A scene's walk section, read chunk by chunk as the walker needs them,
//! with the chunks held bounded by bytes.

use lru::LruCache;

use super::{Grid, SolidMap};
use crate::format::FormatError;
use crate::format::walk::{CHUNK_CELLS, Chunk, ChunkRecord, Column, WalkIndex};
use crate::io::ByteSource;

/// The walk section of a scene: its index in core, chunks on demand.
pub struct WalkMap<S: ByteSource> {
    source: S,
    /// Where the section starts in the source.
    offset: u64,
    index: WalkIndex,
    chunks: LruCache<(i32, i32), Chunk>,
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
            chunks: LruCache::unbounded(),
            held: 0,
            cap,
            reads: 0,
        }
    }

    /// The scene's walk section, if it has one (a scene built before format
    /// version 5 has not).
    pub fn open(
        scene: &crate::SceneFile<S>,
        source: S,
        cap: usize,
    ) -> Result<Option<Self>, FormatError> {
        let offset = scene.header().walk_offset;
        Ok(scene
            .read_walk_index()?
            .map(|index| Self::new(source, offset, index, cap)))
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
        let mut buf = vec![0u8; rec.len as usize];
        self.source.read_at(self.offset + rec.offset, &mut buf)?;
        self.reads += 1;
        let computed = crc32fast::hash(&buf);
        if computed != rec.crc {
            return Err(FormatError::Checksum {
                what: format!("walk chunk ({}, {})", rec.x, rec.z),
                stored: rec.crc,
                computed,
            });
        }
        Chunk::decode(&buf)
            .map_err(|e| FormatError::BadHeader(format!("walk chunk ({}, {}): {e}", rec.x, rec.z)))
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
        let n = CHUNK_CELLS as i64;
        let (Ok(cx), Ok(cz)) = (
            i32::try_from(x.div_euclid(n)),
            i32::try_from(z.div_euclid(n)),
        ) else {
            return Ok(Column::default());
        };
        let Some(&rec) = self.index.find(cx, cz) else {
            return Ok(Column::default());
        };
        if !self.chunks.contains(&(cx, cz)) {
            let chunk = self.read(rec)?;
            self.held += chunk.heap_bytes();
            self.chunks.put((cx, cz), chunk);
            while self.held > self.cap && self.chunks.len() > 1 {
                if let Some((_, old)) = self.chunks.pop_lru() {
                    self.held -= old.heap_bytes();
                }
            }
        }
        let chunk = self.chunks.get(&(cx, cz)).expect("inserted above");
        let (i, j) = (x.rem_euclid(n) as usize, z.rem_euclid(n) as usize);
        Ok(chunk.column(i, j))
    }
}
