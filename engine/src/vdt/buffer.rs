//! The main-memory buffer manager of El-Sana & Chiang §3.3.3, over a byte
//! budget.
//!
//! Place holders, a hash table from meta-node to holder, and a FIFO **free
//! list** of holders whose usage and reference counts are both 0 (an
//! [`Lru`] of [`crate::evict`], in the order the holders were freed). A
//! flushed meta-node keeps its hash entry until its holder is taken for
//! another one (**second chance**): freed holders join the list's end, space is taken
//! from its front, and a request for a flushed meta-node just takes its
//! holder off the list.
//!
//! The paper's holders all have the size of the largest meta-node, which
//! "do not differ too much" there. Collapse trees are chain-like, so our
//! meta-nodes range from one node to a full block (median a tenth of the
//! largest): fixed holders would waste most of the footprint. A holder here
//! is as big as its meta-node, the capacity is in bytes, and making room
//! takes as many free-list entries from the front as needed — the same
//! order, counts and rules otherwise.
//!
//! - *usage count*: active tree nodes inside the meta-node (only the
//!   navigating side changes it: here, the owner of this struct);
//! - *reference count*: active parent plus active child meta-nodes;
//!   raising it on a meta-node not in real memory asks for a prefetch,
//!   lowering it on one not in real memory does nothing.
//! - A plain prefetch gives up when the free list cannot make room. An
//!   **urgent** one (a wanted switch whose meta-node is missing) may also
//!   take the holders of the first meta-nodes that are only prefetched
//!   (usage 0): always for a switch up, for a switch down only while at
//!   least three holders in real memory are not in use.
//!
//! The manager only does bookkeeping; the caller reads the data into the
//! holder it is told to fill and reports back with [`BufferManager::loaded`].

use std::collections::HashMap;

use crate::evict::Eviction;
use crate::evict::lru::Lru;

use super::NONE;

/// Why a meta-node is wanted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Urgency {
    /// A prefetch: give up if no holder is free.
    Prefetch,
    /// A switch up (collapse) needs it: always urgent.
    Up,
    /// A switch down (split) needs it: urgent while three holders are unused.
    Down,
}

/// The state of a place holder's content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Content {
    Empty,
    /// A read was issued and has not come back.
    Loading,
    Ready,
}

/// What a request found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Request {
    /// In real memory already (ready or loading).
    Present(u32),
    /// Was flushed but still in its holder: back in real memory, no read.
    SecondChance(u32),
    /// Read it into this new holder; `evicted` lists the `(meta-node,
    /// holder)` pairs whose space it took (they lose their hash entries).
    Load {
        holder: u32,
        evicted: Vec<(u32, u32)>,
    },
    /// No room could be had.
    GiveUp,
}

impl Request {
    /// The holder, unless the request gave up.
    pub fn holder(&self) -> Option<u32> {
        match self {
            Self::Present(h) | Self::SecondChance(h) | Self::Load { holder: h, .. } => Some(*h),
            Self::GiveUp => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Holder {
    pub meta: u32,
    pub bytes: u32,
    pub usage: u32,
    pub refs: u32,
    pub content: Content,
}

const EMPTY: Holder = Holder {
    meta: NONE,
    bytes: 0,
    usage: 0,
    refs: 0,
    content: Content::Empty,
};

/// Place holders, hash table and free list.
#[derive(Debug)]
pub struct BufferManager {
    holders: Vec<Holder>,
    /// Holder slots without content, reused last-in first-out.
    spare: Vec<u32>,
    table: HashMap<u32, u32>,
    /// Front = least recently freed.
    free: Lru<u32>,
    capacity: u64,
    /// Bytes of every holder with content (flushed ones too).
    used: u64,
}

impl BufferManager {
    /// An empty buffer of `capacity` bytes.
    pub fn new(capacity: u64) -> Self {
        Self {
            holders: Vec::new(),
            spare: Vec::new(),
            table: HashMap::new(),
            free: Lru::default(),
            capacity,
            used: 0,
        }
    }

    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// Bytes held (never above the capacity).
    pub fn used(&self) -> u64 {
        self.used
    }

    pub fn holder(&self, h: u32) -> &Holder {
        &self.holders[h as usize]
    }

    /// The holder of `meta` if it is in physical memory.
    pub fn find(&self, meta: u32) -> Option<u32> {
        self.table.get(&meta).copied()
    }

    /// Whether `meta` is in real memory (found and not on the free list).
    pub fn in_real(&self, meta: u32) -> bool {
        self.find(meta).is_some_and(|h| !self.free.contains(h))
    }

    /// The holder of `meta` if it is in real memory and its data is there.
    pub fn ready(&self, meta: u32) -> Option<u32> {
        self.find(meta).filter(|&h| {
            !self.free.contains(h) && self.holders[h as usize].content == Content::Ready
        })
    }

    /// Holders in real memory whose meta-node is not in use.
    pub fn unused_in_real(&self) -> usize {
        self.holders
            .iter()
            .enumerate()
            .filter(|(h, x)| x.meta != NONE && x.usage == 0 && !self.free.contains(*h as u32))
            .count()
    }

    /// Free-list holders, front first.
    pub fn free_list(&self) -> Vec<u32> {
        self.free.victims().map(|v| v.key).collect()
    }

    /// Brings `meta` (`bytes` long) into real memory if it can (see
    /// [`Urgency`]).
    pub fn request(&mut self, meta: u32, bytes: u32, urgency: Urgency) -> Request {
        if let Some(h) = self.find(meta) {
            return if self.free.contains(h) {
                self.free.remove(h);
                Request::SecondChance(h)
            } else {
                Request::Present(h)
            };
        }
        let need = u64::from(bytes);
        if need > self.capacity {
            return Request::GiveUp;
        }
        // Plan the evictions first; give up without touching anything.
        let mut room = self.capacity - self.used;
        let mut victims = Vec::new();
        // Front of the free list first: the least recently freed.
        for h in self.free.victims().map(|v| v.key) {
            if room >= need {
                break;
            }
            room += u64::from(self.holders[h as usize].bytes);
            victims.push(h);
        }
        if room < need {
            let allowed = match urgency {
                Urgency::Prefetch => false,
                Urgency::Up => true,
                Urgency::Down => self.unused_in_real() >= 3,
            };
            if !allowed {
                return Request::GiveUp;
            }
            // The first meta-nodes that are only prefetched, not in use.
            for (h, x) in self.holders.iter().enumerate() {
                if room >= need {
                    break;
                }
                let h = h as u32;
                if x.meta != NONE
                    && x.usage == 0
                    && x.content == Content::Ready
                    && !self.free.contains(h)
                {
                    room += u64::from(x.bytes);
                    victims.push(h);
                }
            }
            if room < need {
                return Request::GiveUp;
            }
        }
        let evicted = victims
            .into_iter()
            .map(|h| {
                let m = self.holders[h as usize].meta;
                self.release(h);
                (m, h)
            })
            .collect();
        let h = self.spare.pop().unwrap_or_else(|| {
            self.holders.push(EMPTY);
            self.holders.len() as u32 - 1
        });
        self.table.insert(meta, h);
        self.used += need;
        self.holders[h as usize] = Holder {
            meta,
            bytes,
            usage: 0,
            refs: 0,
            content: Content::Loading,
        };
        Request::Load { holder: h, evicted }
    }

    /// Empties holder `h` (its meta-node loses its hash entry).
    fn release(&mut self, h: u32) {
        let x = self.holders[h as usize];
        self.table.remove(&x.meta);
        self.free.remove(h);
        self.used -= u64::from(x.bytes);
        self.holders[h as usize] = EMPTY;
        self.spare.push(h);
    }

    /// The read into `h` for `meta` finished (`ok` false: it failed, and
    /// the holder is emptied). Returns false when the holder was meanwhile
    /// given to another meta-node (the data is dropped).
    pub fn loaded(&mut self, h: u32, meta: u32, ok: bool) -> bool {
        let x = &mut self.holders[h as usize];
        if x.meta != meta || x.content != Content::Loading {
            return false;
        }
        if ok {
            x.content = Content::Ready;
            self.maybe_flush(h);
        } else {
            self.release(h);
        }
        true
    }

    /// Raises `meta`'s reference count, prefetching it if it is not in real
    /// memory. Returns the request made.
    pub fn ref_inc(&mut self, meta: u32, bytes: u32) -> Request {
        let r = self.request(meta, bytes, Urgency::Prefetch);
        if let Some(h) = r.holder() {
            self.holders[h as usize].refs += 1;
        }
        r
    }

    /// Lowers `meta`'s reference count (no effect unless in real memory).
    pub fn ref_dec(&mut self, meta: u32) {
        if let Some(h) = self.find(meta).filter(|&h| !self.free.contains(h)) {
            let x = &mut self.holders[h as usize];
            x.refs = x.refs.saturating_sub(1);
            self.maybe_flush(h);
        }
    }

    /// One more active node in holder `h`.
    pub fn use_inc(&mut self, h: u32) {
        self.holders[h as usize].usage += 1;
    }

    /// One active node fewer in holder `h`.
    pub fn use_dec(&mut self, h: u32) {
        let x = &mut self.holders[h as usize];
        x.usage = x.usage.saturating_sub(1);
        self.maybe_flush(h);
    }

    /// A holder with both counts 0 goes to the end of the free list; its
    /// hash entry stays (second chance). One still loading waits for its
    /// data.
    pub fn maybe_flush(&mut self, h: u32) {
        let x = &self.holders[h as usize];
        if x.usage == 0 && x.refs == 0 && x.content == Content::Ready && !self.free.contains(h) {
            self.free.insert(h, ());
        }
    }

    /// Consistency of table, holders and free list.
    pub fn validate(&self) -> Result<(), String> {
        let used: u64 = self.holders.iter().map(|x| u64::from(x.bytes)).sum();
        if used != self.used || used > self.capacity {
            return Err(format!(
                "{used} bytes held, {} counted, capacity {}",
                self.used, self.capacity
            ));
        }
        for (&m, &h) in &self.table {
            if self.holders.get(h as usize).map(|x| x.meta) != Some(m) {
                return Err(format!(
                    "table maps {m} to holder {h} holding something else"
                ));
            }
        }
        for (h, x) in self.holders.iter().enumerate() {
            let h = h as u32;
            if x.meta != NONE && self.table.get(&x.meta) != Some(&h) {
                return Err(format!("holder {h} not in the table"));
            }
            let free = self.free.contains(h);
            if free && (x.usage > 0 || x.refs > 0) {
                return Err(format!("holder {h} free while counted"));
            }
            if x.meta == NONE && (free || !self.spare.contains(&h)) {
                return Err(format!("empty holder {h} on the free list or lost"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
#[path = "buffer_tests.rs"]
mod tests;
