//! Sub-allocation of rep geometry from a few large GPU buffers (plain Rust).
//!
//! The arena is a list of chunks (one GPU buffer each); every chunk keeps its
//! free ranges in an ordered map, allocates first-fit in 16-byte units (the
//! vertex stride, so a rep's first vertex is a whole `base_vertex`) and merges
//! a freed range with its free neighbours.

use std::collections::BTreeMap;

/// Allocation granule: the packed vertex size.
pub const GRANULE: u64 = 16;

/// One allocated range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Alloc {
    pub chunk: u32,
    pub offset: u64,
    pub size: u64,
}

#[derive(Clone, Debug)]
struct Chunk {
    size: u64,
    /// offset → length of each free range; ranges never touch.
    free: BTreeMap<u64, u64>,
}

/// First-fit allocator over chunks.
#[derive(Clone, Debug)]
pub struct Arena {
    chunks: Vec<Chunk>,
    live: u64,
}

impl Arena {
    /// Chunks of at most `chunk_size` bytes adding up to at least `capacity`
    /// (both rounded up to the granule).
    pub fn new(capacity: u64, chunk_size: u64) -> Self {
        let chunk_size = chunk_size.max(GRANULE).next_multiple_of(GRANULE);
        let mut left = capacity.max(GRANULE).next_multiple_of(GRANULE);
        let mut chunks = Vec::new();
        while left > 0 {
            let size = left.min(chunk_size);
            chunks.push(Chunk {
                size,
                free: BTreeMap::from([(0, size)]),
            });
            left -= size;
        }
        Self { chunks, live: 0 }
    }

    /// Sizes of the chunks, in order.
    pub fn chunk_sizes(&self) -> impl Iterator<Item = u64> + '_ {
        self.chunks.iter().map(|c| c.size)
    }

    /// Bytes handed out.
    pub fn live_bytes(&self) -> u64 {
        self.live
    }

    /// The largest single allocation that can ever succeed.
    pub fn max_alloc(&self) -> u64 {
        self.chunks.iter().map(|c| c.size).max().unwrap_or(0)
    }

    /// A range of at least `size` bytes, or `None` if no free range is large
    /// enough.
    pub fn alloc(&mut self, size: u64) -> Option<Alloc> {
        let size = size.max(1).next_multiple_of(GRANULE);
        for (ci, c) in self.chunks.iter_mut().enumerate() {
            let Some((&off, &len)) = c.free.iter().find(|&(_, &len)| len >= size) else {
                continue;
            };
            c.free.remove(&off);
            if len > size {
                c.free.insert(off + size, len - size);
            }
            self.live += size;
            return Some(Alloc {
                chunk: ci as u32,
                offset: off,
                size,
            });
        }
        None
    }

    /// Returns a range from [`alloc`](Self::alloc).
    pub fn free(&mut self, a: Alloc) {
        let c = &mut self.chunks[a.chunk as usize];
        let (mut off, mut len) = (a.offset, a.size);
        debug_assert!(off + len <= c.size);
        if let Some((&p, &plen)) = c.free.range(..off).next_back()
            && p + plen == off
        {
            c.free.remove(&p);
            off = p;
            len += plen;
        }
        if let Some(&nlen) = c.free.get(&(off + len)) {
            c.free.remove(&(off + len));
            len += nlen;
        }
        c.free.insert(off, len);
        self.live -= a.size;
    }

    /// Frees everything.
    pub fn reset(&mut self) {
        for c in &mut self.chunks {
            c.free = BTreeMap::from([(0, c.size)]);
        }
        self.live = 0;
    }

    /// Checks the free lists: in bounds, sorted, disjoint, not touching, and
    /// adding up with the live bytes to the capacity.
    pub fn validate(&self) -> Result<(), String> {
        let mut free_total = 0;
        for (ci, c) in self.chunks.iter().enumerate() {
            let mut end = None;
            for (&off, &len) in &c.free {
                if len == 0 || off % GRANULE != 0 || len % GRANULE != 0 || off + len > c.size {
                    return Err(format!("chunk {ci}: bad free range {off}+{len}"));
                }
                if end.is_some_and(|e| e >= off) {
                    return Err(format!("chunk {ci}: free ranges touch or overlap at {off}"));
                }
                end = Some(off + len);
                free_total += len;
            }
        }
        let cap: u64 = self.chunks.iter().map(|c| c.size).sum();
        if free_total + self.live != cap {
            return Err(format!(
                "free {free_total} + live {} != capacity {cap}",
                self.live
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn chunks_cover_the_capacity() {
        let a = Arena::new(100, 40);
        assert_eq!(a.chunk_sizes().collect::<Vec<_>>(), vec![48, 48, 16]);
        assert_eq!(a.max_alloc(), 48);
        let mut a = Arena::new(64, 64);
        let x = a.alloc(10).unwrap();
        let y = a.alloc(16).unwrap();
        assert_eq!((x.offset, x.size, y.offset), (0, 16, 16));
        a.free(x);
        assert_eq!(a.alloc(32).unwrap().offset, 32);
        a.free(y);
        assert_eq!(a.alloc(32).unwrap().offset, 0);
        assert!(a.alloc(1).is_none());
        a.validate().unwrap();
    }

    proptest! {
        #[test]
        fn arena_matches_a_byte_map(
            ops in proptest::collection::vec((any::<bool>(), 1u64..200, any::<prop::sample::Index>()), 1..300),
            chunk in 64u64..400,
        ) {
            let mut a = Arena::new(1000, chunk);
            let sizes: Vec<u64> = a.chunk_sizes().collect();
            let mut owner: Vec<Vec<bool>> = sizes.iter().map(|&s| vec![false; s as usize]).collect();
            let mut live: Vec<Alloc> = Vec::new();
            for (is_alloc, size, pick) in ops {
                if is_alloc || live.is_empty() {
                    let need = size.next_multiple_of(GRANULE);
                    // A fit exists iff some chunk has `need` consecutive free bytes at a granule.
                    let fits = owner.iter().any(|o| {
                        (0..o.len()).step_by(GRANULE as usize).any(|s| {
                            s + need as usize <= o.len() && o[s..s + need as usize].iter().all(|b| !b)
                        })
                    });
                    match a.alloc(size) {
                        Some(x) => {
                            prop_assert!(fits);
                            prop_assert_eq!(x.size, need);
                            let o = &mut owner[x.chunk as usize];
                            prop_assert!((x.offset + x.size) as usize <= o.len());
                            for b in &mut o[x.offset as usize..(x.offset + x.size) as usize] {
                                prop_assert!(!*b, "overlap");
                                *b = true;
                            }
                            live.push(x);
                        }
                        None => prop_assert!(!fits, "first fit missed a free range"),
                    }
                } else {
                    let x = live.swap_remove(pick.index(live.len()));
                    for b in &mut owner[x.chunk as usize][x.offset as usize..(x.offset + x.size) as usize] {
                        *b = false;
                    }
                    a.free(x);
                }
                prop_assert!(a.validate().is_ok(), "{:?}", a.validate());
                prop_assert_eq!(a.live_bytes(), live.iter().map(|x| x.size).sum::<u64>());
            }
            for x in live.drain(..) {
                a.free(x);
            }
            for c in &a.chunks {
                prop_assert_eq!(c.free.len(), 1, "not merged back");
            }
        }
    }
}
