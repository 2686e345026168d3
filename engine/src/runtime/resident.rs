//! P_I's resident set as a value: the InMemoryList (StartTail LRU), each
//! resident rep's payload, the resident and speculative byte counts with
//! the bytes reserved for reads in flight, the pins of the frame being
//! drawn and the root rep that is never evicted. [`ResidentSet::make_room`]
//! is the eviction rule (Varadhan & Manocha §4.3 with this engine's
//! speculative cap) over the StartTail order ([`crate::evict`]);
//! [`ResidentSet::validate`] checks every invariant.
//! Plain Rust: no thread, no channel, no byte source, no clock.

use std::sync::Arc;

use crate::evict::start_tail::InMemoryList;
use crate::evict::{Eviction, Verdict, choose};
use crate::skeleton::RepId;

/// Who asks for room: Stage II may evict any unpinned rep; a prefetch only
/// reps not accessed since Stage II began, and only speculative ones once
/// speculation holds its share of the budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    Demand,
    Prefetch,
}

/// The resident reps and their bytes.
#[derive(Debug)]
pub struct ResidentSet {
    list: InMemoryList,
    data: Vec<Option<Arc<[u8]>>>,
    /// Footprint of each rep while resident (payload, and a tree store's reserve).
    cost: Vec<u64>,
    /// Bytes of resident reps plus `reserved`.
    resident: u64,
    /// Bytes reserved for reads in flight (counted in `resident`).
    reserved: u64,
    /// Prefetched and not drawn since, and their bytes.
    speculative: Vec<bool>,
    speculative_bytes: u64,
    /// A rep is pinned (P_R draws it this frame) when its stamp is `frame`.
    pinned: Vec<u32>,
    frame: u32,
    /// Never evicted (the root's coarsest rep in the out-of-core modes).
    keep: Option<RepId>,
    /// Evicted since the last [`ResidentSet::take_evicted`], and in all.
    evicted: Vec<RepId>,
    evictions: u64,
    /// Bytes of speculative reps evicted before they were ever drawn.
    wasted: u64,
    /// The rep each rep's payload is held under (a shared payload under
    /// its owner: [`crate::skeleton::Skeleton::payload_rep`]); empty when
    /// every rep owns its payload.
    owner: Vec<RepId>,
}

impl ResidentSet {
    /// An empty set over reps whose footprints are `cost`.
    pub fn new(cost: Vec<u64>) -> Self {
        let n = cost.len();
        Self {
            list: InMemoryList::new(n),
            data: vec![None; n],
            cost,
            resident: 0,
            reserved: 0,
            speculative: vec![false; n],
            speculative_bytes: 0,
            pinned: vec![0; n],
            // Stamps of 0 never match: nothing is pinned yet.
            frame: 1,
            keep: None,
            evicted: Vec::new(),
            evictions: 0,
            wasted: 0,
            owner: Vec::new(),
        }
    }

    /// An empty set whose rep `r` holds the payload of `owner[r]`: a
    /// payload several reps place is resident, counted, pinned and
    /// evicted once, under its owner's id (the id that evictions report).
    pub fn shared(cost: Vec<u64>, owner: Vec<RepId>) -> Self {
        debug_assert_eq!(cost.len(), owner.len());
        let mut s = Self::new(cost);
        if owner.iter().enumerate().any(|(i, &o)| o as usize != i) {
            s.owner = owner;
        }
        s
    }

    /// The id rep `r`'s payload is held under.
    fn key(&self, r: RepId) -> RepId {
        match self.owner.get(r as usize) {
            Some(&o) => o,
            None => r,
        }
    }

    /// Footprint of rep `r` while resident.
    pub fn cost(&self, r: RepId) -> u64 {
        self.cost[self.key(r) as usize]
    }

    /// Bytes resident or reserved: what the budget bounds.
    pub fn bytes(&self) -> u64 {
        self.resident
    }

    /// Bytes of speculative reps.
    pub fn speculative_bytes(&self) -> u64 {
        self.speculative_bytes
    }

    /// Rep `r`'s payload when resident.
    pub fn payload(&self, r: RepId) -> Option<&Arc<[u8]>> {
        self.data[self.key(r) as usize].as_ref()
    }

    /// Whether rep `r` is resident.
    pub fn contains(&self, r: RepId) -> bool {
        self.data[self.key(r) as usize].is_some()
    }

    /// The frame stamp of the current Stage II (the pins' generation).
    pub fn frame(&self) -> u32 {
        self.frame
    }

    /// Evictions so far, and bytes prefetched and evicted undrawn.
    pub fn evictions(&self) -> u64 {
        self.evictions
    }

    pub fn wasted_bytes(&self) -> u64 {
        self.wasted
    }

    /// Starts Stage II for a front: a new frame stamp, the front pinned and
    /// no longer speculative, StartTail at the list's tail.
    pub fn start_stage2(&mut self, front: &[RepId]) {
        self.frame += 1;
        for &r in front {
            self.pin(r);
        }
        self.list.start_stage2();
    }

    /// Pins rep `r` for this frame (it is drawn): not speculative any more.
    pub fn pin(&mut self, r: RepId) {
        let r = self.key(r);
        self.pinned[r as usize] = self.frame;
        self.set_speculative(r, false);
    }

    /// Whether rep `r` must not be evicted now.
    pub fn is_pinned(&self, r: RepId) -> bool {
        let r = self.key(r);
        self.pinned[r as usize] == self.frame || self.keep == Some(r)
    }

    /// Keeps rep `r` resident for good.
    pub fn keep(&mut self, r: RepId) {
        self.keep = Some(self.key(r));
    }

    /// An access: rep `r` moves right after StartTail.
    pub fn access(&mut self, r: RepId) {
        let r = self.key(r);
        Eviction::access(&mut self.list, r, ());
    }

    /// Bytes reserved for reads in flight.
    pub fn reserved(&self) -> u64 {
        self.reserved
    }

    /// Reserves `bytes` for a read about to start (room made first).
    pub fn reserve(&mut self, bytes: u64) {
        self.reserved += bytes;
        self.resident += bytes;
    }

    /// Gives a reservation back (a read failed or was given up).
    pub fn release(&mut self, bytes: u64) {
        debug_assert!(bytes <= self.reserved);
        self.reserved -= bytes;
        self.resident -= bytes;
    }

    /// A read of rep `r` completed: its reservation becomes the resident
    /// rep, accessed now, speculative when prefetched.
    pub fn insert(&mut self, r: RepId, payload: Arc<[u8]>, speculative: bool) {
        let r = self.key(r);
        debug_assert!(self.data[r as usize].is_none());
        self.reserved -= self.cost[r as usize];
        self.data[r as usize] = Some(payload);
        Eviction::insert(&mut self.list, r, ());
        if speculative {
            self.set_speculative(r, true);
        }
    }

    /// Marks rep `r` speculative (prefetched, not drawn since) or not.
    pub fn set_speculative(&mut self, r: RepId, on: bool) {
        let r = self.key(r);
        let flag = &mut self.speculative[r as usize];
        if *flag != on {
            *flag = on;
            if on {
                self.speculative_bytes += self.cost[r as usize];
            } else {
                self.speculative_bytes -= self.cost[r as usize];
            }
        }
    }

    /// Removes resident rep `r` (evicted, or unusable); P_R is told by
    /// [`ResidentSet::take_evicted`].
    pub fn remove(&mut self, r: RepId, payload_len: u64) {
        let r = self.key(r);
        if self.speculative[r as usize] {
            self.wasted += payload_len;
        }
        self.set_speculative(r, false);
        self.data[r as usize] = None;
        Eviction::remove(&mut self.list, r);
        self.resident -= self.cost[r as usize];
        self.evicted.push(r);
    }

    /// The reps removed since the last call.
    pub fn take_evicted(&mut self) -> Vec<RepId> {
        std::mem::take(&mut self.evicted)
    }

    /// Whether reps were removed since the last [`ResidentSet::take_evicted`].
    pub fn has_evicted(&self) -> bool {
        !self.evicted.is_empty()
    }

    /// The eviction rule: evicts unpinned reps from the head of the list
    /// until `need` more bytes fit in `budget`. A prefetch stops at
    /// StartTail (it may not evict what this frame accessed) and, once
    /// speculative reps would exceed `speculative_cap` bytes, evicts only
    /// speculative reps. `payload_len(r)` is a rep's payload length (for
    /// the wasted-bytes count). Evicts nothing and returns `false` when the
    /// room cannot be made.
    pub fn make_room(
        &mut self,
        need: u64,
        budget: u64,
        purpose: Purpose,
        speculative_cap: u64,
        payload_len: impl Fn(RepId) -> u64,
    ) -> bool {
        if self.resident.saturating_add(need) <= budget {
            return true;
        }
        if need > budget {
            return false;
        }
        let only_speculative =
            purpose == Purpose::Prefetch && self.speculative_bytes + need > speculative_cap;
        let over = self.resident - (budget - need);
        let verdict = |v: crate::evict::Victim<RepId>| {
            if purpose == Purpose::Prefetch && v.recent {
                Verdict::Stop
            } else if self.is_pinned(v.key)
                || (only_speculative && !self.speculative[v.key as usize])
            {
                Verdict::Skip
            } else {
                Verdict::Take
            }
        };
        let Some(victims) = choose(
            self.list.victims(),
            over,
            |r| self.cost[r as usize],
            verdict,
        ) else {
            return false;
        };
        for r in victims {
            self.remove(r, payload_len(r));
            self.evictions += 1;
        }
        true
    }

    /// Checks every invariant: the byte counts equal the sums they stand
    /// for, the list holds exactly the resident reps, the kept rep is resident.
    pub fn validate(&self) -> Result<(), String> {
        let mut sum = self.reserved;
        let mut spec = 0;
        for (r, d) in self.data.iter().enumerate() {
            let r32 = r as RepId;
            if d.is_some() {
                if self.key(r32) != r32 {
                    return Err(format!("rep {r} holds a payload it does not own"));
                }
                sum += self.cost[r];
                if !self.list.contains(r32) {
                    return Err(format!("rep {r} resident but not in the list"));
                }
            } else {
                if self.list.contains(r32) {
                    return Err(format!("rep {r} in the list but not resident"));
                }
                if self.speculative[r] {
                    return Err(format!("rep {r} speculative but not resident"));
                }
            }
            if self.speculative[r] {
                spec += self.cost[r];
            }
        }
        if sum != self.resident {
            return Err(format!(
                "resident bytes {} but the reps and reservations hold {sum}",
                self.resident
            ));
        }
        if spec != self.speculative_bytes {
            return Err(format!(
                "speculative bytes {} but the speculative reps hold {spec}",
                self.speculative_bytes
            ));
        }
        if self.list.len() != self.data.iter().filter(|d| d.is_some()).count() {
            return Err("list length differs from the resident count".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
