//! The footprint as one value: the user's budget and the shares it is
//! split into, derived here and nowhere else ([`Footprint::new`] first
//! checks the parameters, the shares' ranges with the others:
//! [`RuntimeParams::check`]).
//!
//! Out of core, the budget bounds everything the walk holds for geometry:
//! - P_R's occluder store ([`crate::occlusion`]) takes `occluders` off the
//!   top (at most half the budget);
//! - requests started ahead on a network source ([`crate::ByteSource::hint`])
//!   take `in_flight` ([`Footprint::with_read_ahead`]);
//! - P_I's side, the rest ([`Footprint::reps`]), holds the resident reps
//!   with their trees' and MTs' store reserves, the bytes reserved for
//!   reads in flight and their scratch, the reps P_R draws fading out, and
//!   the pages read on a seek-bound disk or a network;
//! - pages may take `page_share` of P_I's side away from prefetching (a
//!   demand read takes it back: [`Footprint::rep_room`]);
//! - prefetched reps not drawn since may take `speculative_share` of it
//!   ([`Footprint::speculative_cap`]).
//!
//! In core, everything is loaded at start and nothing is bounded: that is a
//! variant of its own ([`Footprint::InCore`]), not a very large budget.

use super::params::{Mode, RuntimeError, RuntimeParams};
use super::resident::Purpose;

/// What a walk may hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Footprint {
    /// Every rep is loaded at start and stays: nothing bounds P_I. The
    /// occluder store keeps its own cap.
    InCore { occluders: u64 },
    /// Resident bytes never exceed `total`.
    Bounded(Shares),
}

/// The budget of an out-of-core walk and its shares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shares {
    /// The user's footprint in bytes.
    pub total: u64,
    /// P_R's occluder store, taken off the top.
    pub occluders: u64,
    /// What requests started ahead may hold (in flight, or answered and
    /// not yet read), taken off the top.
    pub in_flight: u64,
    /// The part of P_I's side that pages may take from prefetching.
    pub page_share: f32,
    /// The part of P_I's side that speculative reps may hold.
    pub speculative_share: f32,
}

/// What P_I holds against its side of the footprint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Held {
    /// Resident reps (with their stores' reserves) and reservations for
    /// reads in flight: [`super::resident::ResidentSet::bytes`].
    pub reps: u64,
    /// Pages held ([`super::loader`]'s page cache).
    pub pages: u64,
}

impl Held {
    pub fn sum(&self) -> u64 {
        self.reps + self.pages
    }
}

impl Footprint {
    /// The footprint `params` ask for, checked.
    pub fn new(params: &RuntimeParams) -> Result<Self, RuntimeError> {
        // The shares' ranges are parameters, checked with the others.
        params.check()?;
        let speculative_share = params.prefetch.speculative_share;
        if params.mode == Mode::Incore {
            return Ok(Self::InCore {
                occluders: params.occlusion_bytes,
            });
        }
        Ok(Self::Bounded(Shares {
            total: params.budget_bytes,
            occluders: params.occlusion_bytes,
            in_flight: 0,
            page_share: params.page_share,
            speculative_share,
        }))
    }

    /// The same with a share for reading ahead on a source that would hold
    /// up to `max` bytes of requests started ahead: at most an eighth of
    /// P_I's side, and none in core (everything is read at start). The
    /// share given is [`Self::in_flight`].
    pub fn with_read_ahead(self, max: u64) -> Self {
        match self {
            Self::InCore { .. } => self,
            Self::Bounded(s) => {
                let side = s.total - s.occluders - s.in_flight;
                Self::Bounded(Shares {
                    in_flight: s.in_flight + max.min(side / 8),
                    ..s
                })
            }
        }
    }

    /// Bytes requests started ahead may hold (0 when none).
    pub fn in_flight(&self) -> u64 {
        match self {
            Self::InCore { .. } => 0,
            Self::Bounded(s) => s.in_flight,
        }
    }

    /// The user's footprint; `None` in core.
    pub fn total(&self) -> Option<u64> {
        match self {
            Self::InCore { .. } => None,
            Self::Bounded(s) => Some(s.total),
        }
    }

    /// Bytes of P_R's occluder store (0: no occlusion culling).
    pub fn occluders(&self) -> u64 {
        match self {
            Self::InCore { occluders } => *occluders,
            Self::Bounded(s) => s.occluders,
        }
    }

    /// P_I's side: what its reps, reservations, fades and pages may hold
    /// together; `None` in core.
    pub fn reps(&self) -> Option<u64> {
        match self {
            Self::InCore { .. } => None,
            Self::Bounded(s) => Some(s.total - s.occluders - s.in_flight),
        }
    }

    /// Whether `held` fits P_I's side.
    pub fn holds(&self, held: Held) -> bool {
        self.reps().is_none_or(|b| held.sum() <= b)
    }

    /// The pages' room this frame: their share of P_I's side when reads go
    /// by pages of `page_bytes` and the share holds the two pages a rep may
    /// straddle (with room for one, its second page would evict its first);
    /// else 0. Never in core.
    pub fn pages_cap(&self, page_bytes: u64, paging: bool) -> u64 {
        let Self::Bounded(s) = self else { return 0 };
        let side = s.total - s.occluders - s.in_flight;
        let share = (side as f64 * f64::from(s.page_share)) as u64;
        if paging && page_bytes > 0 && share >= 2 * page_bytes {
            share
        } else {
            0
        }
    }

    /// Whether a page of `n` more bytes fits: within the pages' cap, and
    /// beside what P_I holds.
    pub fn page_fits(&self, held: Held, pages_cap: u64, n: u64) -> bool {
        held.pages + n <= pages_cap
            && self
                .reps()
                .is_none_or(|b| held.sum().saturating_add(n) <= b)
    }

    /// The reps' room for a read of `purpose`: P_I's side less the pages
    /// held, and a prefetch also leaves the pages' whole cap (a demand read
    /// may take it back by evicting pages). `None` in core: unbounded.
    pub fn rep_room(&self, pages_held: u64, pages_cap: u64, purpose: Purpose) -> Option<u64> {
        let held = match purpose {
            Purpose::Demand => pages_held,
            Purpose::Prefetch => pages_held.max(pages_cap),
        };
        self.reps().map(|b| b.saturating_sub(held))
    }

    /// The bytes prefetched reps not drawn since may hold (`u64::MAX` in
    /// core, where nothing is prefetched).
    pub fn speculative_cap(&self) -> u64 {
        match self {
            Self::InCore { .. } => u64::MAX,
            Self::Bounded(s) => {
                let side = s.total - s.occluders - s.in_flight;
                (side as f64 * f64::from(s.speculative_share)) as u64
            }
        }
    }

    /// An error unless the root's coarsest rep (`need` bytes while it
    /// loads) fits P_I's side: it is the last-resort substitute.
    pub fn check_root(&self, need: u64) -> Result<(), RuntimeError> {
        match self.reps() {
            Some(b) if need > b => Err(RuntimeError::BudgetTooSmall { budget: b, need }),
            _ => Ok(()),
        }
    }

    /// `None` when P_I's side can hold every rep drawn as itself
    /// (`full_detail` bytes: the largest rep while it loads, beside the
    /// root's coarsest); else `full_detail`. Always `None` in core.
    pub fn unfit(&self, full_detail: u64) -> Option<u64> {
        self.reps()
            .filter(|&b| b < full_detail)
            .map(|_| full_detail)
    }
}

#[cfg(test)]
mod tests;
