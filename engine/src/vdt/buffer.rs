//! The main-memory buffer manager of El-Sana & Chiang §3.3.3.
//!
//! `K` place holders, each big enough for the largest meta-node; a hash
//! table from meta-node to holder; a FIFO **free list** of holders whose
//! usage and reference counts are both 0. A flushed meta-node keeps its
//! hash entry until its holder is taken for another one (**second chance**):
//! freed holders join the list's end, new space comes from its front, and a
//! request for a flushed meta-node just takes its holder off the list.
//!
//! - *usage count*: active tree nodes inside the meta-node (only the
//!   navigating side changes it: here, the owner of this struct);
//! - *reference count*: active parent plus active child meta-nodes;
//!   raising it on a meta-node not in real memory asks for a prefetch,
//!   lowering it on one not in real memory does nothing.
//! - A plain prefetch gives up when the free list is empty. An **urgent**
//!   one (a wanted switch whose meta-node is missing) may take the holder of
//!   the first meta-node that is only prefetched (usage 0): always for a
//!   switch up, for a switch down only while at least three holders in real
//!   memory are not in use.
//!
//! The manager only does bookkeeping; the caller reads the data into the
//! holder it is told to fill and reports back with [`BufferManager::loaded`].

use std::collections::HashMap;

use lru::LruCache;

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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// In real memory already (ready or loading).
    Present(u32),
    /// Was flushed but still in its holder: back in real memory, no read.
    SecondChance(u32),
    /// Read it into this holder; `evicted` is the meta-node whose hash entry
    /// it loses (or `NONE`).
    Load { holder: u32, evicted: u32 },
    /// No holder could be had.
    GiveUp,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Holder {
    pub meta: u32,
    pub usage: u32,
    pub refs: u32,
    pub content: Content,
}

/// Place holders, hash table and free list.
#[derive(Debug)]
pub struct BufferManager {
    holders: Vec<Holder>,
    table: HashMap<u32, u32>,
    /// Front = least recently freed.
    free: LruCache<u32, ()>,
}

impl BufferManager {
    /// `k` empty holders, all on the free list.
    pub fn new(k: usize) -> Self {
        let mut free = LruCache::unbounded();
        for h in 0..k as u32 {
            free.push(h, ());
        }
        Self {
            holders: vec![
                Holder {
                    meta: NONE,
                    usage: 0,
                    refs: 0,
                    content: Content::Empty,
                };
                k
            ],
            table: HashMap::new(),
            free,
        }
    }

    pub fn capacity(&self) -> usize {
        self.holders.len()
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
        self.find(meta).is_some_and(|h| !self.free.contains(&h))
    }

    /// The holder of `meta` if it is in real memory and its data is there.
    pub fn ready(&self, meta: u32) -> Option<u32> {
        self.find(meta).filter(|&h| {
            !self.free.contains(&h) && self.holders[h as usize].content == Content::Ready
        })
    }

    /// Holders in real memory whose meta-node is not in use.
    pub fn unused_in_real(&self) -> usize {
        self.holders
            .iter()
            .enumerate()
            .filter(|(h, x)| x.meta != NONE && x.usage == 0 && !self.free.contains(&(*h as u32)))
            .count()
    }

    /// Free-list holders, front first.
    pub fn free_list(&self) -> Vec<u32> {
        self.free.iter().rev().map(|(&h, _)| h).collect()
    }

    /// Brings `meta` into real memory if it can (see [`Urgency`]).
    pub fn request(&mut self, meta: u32, urgency: Urgency) -> Request {
        if let Some(h) = self.find(meta) {
            return if self.free.pop(&h).is_some() {
                Request::SecondChance(h)
            } else {
                Request::Present(h)
            };
        }
        let h = if let Some((h, ())) = self.free.pop_lru() {
            h
        } else {
            let allowed = match urgency {
                Urgency::Prefetch => false,
                Urgency::Up => true,
                Urgency::Down => self.unused_in_real() >= 3,
            };
            // The first meta-node that is only prefetched, not in use.
            let victim = self
                .holders
                .iter()
                .position(|x| x.meta != NONE && x.usage == 0 && x.content == Content::Ready);
            match victim {
                Some(v) if allowed => v as u32,
                _ => return Request::GiveUp,
            }
        };
        let old = self.holders[h as usize].meta;
        if old != NONE {
            self.table.remove(&old);
        }
        self.table.insert(meta, h);
        self.holders[h as usize] = Holder {
            meta,
            usage: 0,
            refs: 0,
            content: Content::Loading,
        };
        Request::Load { holder: h, evicted: old }
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
            self.table.remove(&meta);
            *x = Holder {
                meta: NONE,
                usage: 0,
                refs: 0,
                content: Content::Empty,
            };
            self.free.pop(&h);
            // A failed holder is reused first.
            self.free.push(h, ());
            self.free.demote(&h);
        }
        true
    }

    /// Raises `meta`'s reference count, prefetching it if it is not in real
    /// memory. Returns the request made (or `Present`).
    pub fn ref_inc(&mut self, meta: u32) -> Request {
        let r = self.request(meta, Urgency::Prefetch);
        if let Request::Present(h) | Request::SecondChance(h) | Request::Load { holder: h, .. } = r {
            self.holders[h as usize].refs += 1;
        }
        r
    }

    /// Lowers `meta`'s reference count (no effect unless in real memory).
    pub fn ref_dec(&mut self, meta: u32) {
        if let Some(h) = self.find(meta).filter(|h| !self.free.contains(h)) {
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
    /// data (so at most `K` reads are ever outstanding).
    pub fn maybe_flush(&mut self, h: u32) {
        let x = &self.holders[h as usize];
        if x.usage == 0
            && x.refs == 0
            && x.content == Content::Ready
            && !self.free.contains(&h)
        {
            self.free.push(h, ());
        }
    }

    /// Consistency of table, holders and free list.
    pub fn validate(&self) -> Result<(), String> {
        for (&m, &h) in &self.table {
            if self.holders.get(h as usize).map(|x| x.meta) != Some(m) {
                return Err(format!("table maps {m} to holder {h} holding something else"));
            }
        }
        for (h, x) in self.holders.iter().enumerate() {
            let h = h as u32;
            if x.meta != NONE && self.table.get(&x.meta) != Some(&h) {
                return Err(format!("holder {h} not in the table"));
            }
            let free = self.free.contains(&h);
            if free && (x.usage > 0 || x.refs > 0) {
                return Err(format!("holder {h} free while counted"));
            }
            if !free && x.meta != NONE && x.usage == 0 && x.refs == 0 && x.content == Content::Ready
            {
                return Err(format!("holder {h} unreferenced but not free"));
            }
            if x.meta == NONE && !free {
                return Err(format!("empty holder {h} not free"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
#[path = "buffer_tests.rs"]
mod tests;
