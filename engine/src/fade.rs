//! Smooth LOD switches (issue 21, item 4): a rep that replaces another on
//! the screen fades in over a short time while the one it replaces fades
//! out, through complementary screen-door dithers ([`Fade`]), so that the
//! two together cover every pixel once and the switch is a dissolve, not a
//! pop.
//!
//! [`Fades`] is the policy, plain Rust and told the time. Each frame, from
//! the front after culling and the reps shown last frame, it finds:
//! - *refinements*: a front rep not shown last frame whose nearest shown
//!   ancestor (PAR chain) is no longer in the front: the ancestor fades out,
//!   the rep fades in;
//! - *coarsenings*: a rep shown last frame, no longer in the front, whose
//!   nearest front ancestor was not shown: the rep fades out, the ancestor
//!   fades in (one fade-in, several fading out).
//!
//! A rep joining a switch already under way takes its start, so partners
//! always share one `t` and their dithers stay complementary. The reps
//! fading out are asked of P_I with the fetch command; P_I draws those
//! still resident first and pins them for the frame, so the footprint
//! counts both reps of a switch. A rep fading in whose partners did not
//! come (evicted meanwhile) is drawn opaque at once: a fade never leaves a
//! hole. Newly visible reps (no shown relative) and view-dependence trees
//! (refined continuously) do not fade.

use std::collections::{BTreeMap, BTreeSet};

use crate::render::Fade;
use crate::skeleton::RepId;

/// A set of reps with O(1) insert, lookup and clear, over rep ids.
#[derive(Debug, Default)]
struct RepSet {
    stamp: Vec<u32>,
    generation: u32,
    list: Vec<RepId>,
}

impl RepSet {
    fn new(reps: usize) -> Self {
        Self {
            stamp: vec![0; reps],
            generation: 1,
            list: Vec::new(),
        }
    }

    fn clear(&mut self) {
        self.list.clear();
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.generation = 1;
        }
    }

    fn insert(&mut self, r: RepId) {
        if let Some(s) = self.stamp.get_mut(r as usize)
            && *s != self.generation
        {
            *s = self.generation;
            self.list.push(r);
        }
    }

    fn contains(&self, r: RepId) -> bool {
        self.stamp.get(r as usize) == Some(&self.generation)
    }
}

/// A rep fading in, and the reps it replaces.
#[derive(Debug)]
struct Incoming {
    start: f64,
    partners: Vec<RepId>,
}

/// The fades under way.
#[derive(Debug)]
pub struct Fades {
    seconds: f64,
    now: f64,
    incoming: BTreeMap<RepId, Incoming>,
    /// Reps fading out, by start time.
    outgoing: BTreeMap<RepId, f64>,
    /// Reps shown (opaque or fading in) last frame and this frame.
    shown_prev: RepSet,
    shown_now: RepSet,
    front: RepSet,
    /// Reps drawn fading out this frame.
    out_drawn: RepSet,
}

impl Fades {
    /// Fades of `seconds` (0: off) over a scene of `reps` reps.
    pub fn new(seconds: f32, reps: usize) -> Self {
        let on = seconds > 0.0;
        let n = if on { reps } else { 0 };
        Self {
            seconds: f64::from(seconds.max(0.0)),
            now: 0.0,
            incoming: BTreeMap::new(),
            outgoing: BTreeMap::new(),
            shown_prev: RepSet::new(n),
            shown_now: RepSet::new(n),
            front: RepSet::new(n),
            out_drawn: RepSet::new(n),
        }
    }

    /// Whether fades are on.
    pub fn on(&self) -> bool {
        self.seconds > 0.0
    }

    /// Fades under way: (reps fading in, reps fading out).
    pub fn active(&self) -> (usize, usize) {
        (self.incoming.len(), self.outgoing.len())
    }

    fn progress(&self, start: f64) -> f32 {
        (((self.now - start) / self.seconds).clamp(0.0, 1.0)) as f32
    }

    /// Starts a frame at `now` (seconds) with its `front` (after culling):
    /// ends the fades that are over, starts the switches' fades, and
    /// returns the reps to draw fading out (not in the front), in id order.
    /// `par` is the rep hierarchy's PAR, `fadeable` says which reps may
    /// fade (static ones).
    pub fn plan(
        &mut self,
        now: f64,
        front: &[RepId],
        par: impl Fn(RepId) -> Option<RepId>,
        fadeable: impl Fn(RepId) -> bool,
    ) -> Vec<RepId> {
        if !self.on() {
            return Vec::new();
        }
        self.now = now;
        self.front.clear();
        for &r in front {
            self.front.insert(r);
        }
        let (s, fr) = (self.seconds, &self.front);
        self.incoming
            .retain(|r, f| now - f.start < s && fr.contains(*r));
        // A rep fades out only while a rep that replaces it fades in.
        let replaced: BTreeSet<RepId> = self
            .incoming
            .values()
            .flat_map(|f| f.partners.iter().copied())
            .collect();
        self.outgoing
            .retain(|r, _| replaced.contains(r) && !fr.contains(*r));
        // Refinements: a new front rep whose nearest shown (or fading)
        // ancestor left.
        for &r in front {
            if !fadeable(r) || self.shown_prev.contains(r) || self.incoming.contains_key(&r) {
                continue;
            }
            let mut a = par(r);
            while let Some(x) = a {
                // Shown last frame, or fading out still (a sibling's switch).
                if self.shown_prev.contains(x) || self.outgoing.contains_key(&x) {
                    break;
                }
                a = par(x);
            }
            if let Some(x) = a
                && fadeable(x)
                && !self.front.contains(x)
            {
                let start = *self.outgoing.entry(x).or_insert(now);
                self.incoming.insert(
                    r,
                    Incoming {
                        start,
                        partners: vec![x],
                    },
                );
            }
        }
        // Coarsenings: a shown rep that left for a new front ancestor.
        for &o in &self.shown_prev.list {
            if self.front.contains(o) || !fadeable(o) || self.outgoing.contains_key(&o) {
                continue;
            }
            let mut a = par(o);
            while let Some(x) = a {
                if self.front.contains(x) {
                    break;
                }
                a = par(x);
            }
            if let Some(x) = a
                && fadeable(x)
                && !self.shown_prev.contains(x)
            {
                let inc = self.incoming.entry(x).or_insert(Incoming {
                    start: now,
                    partners: Vec::new(),
                });
                inc.partners.push(o);
                self.outgoing.insert(o, inc.start);
            }
        }
        self.outgoing.keys().copied().collect()
    }

    /// How to draw `r` that P_I handed over as fading out (`None`: its
    /// fade is over).
    pub fn fade_out(&mut self, r: RepId) -> Option<Fade> {
        let start = *self.outgoing.get(&r)?;
        self.out_drawn.insert(r);
        Some(Fade::Out(self.progress(start)))
    }

    /// How to draw front rep `r` (shown this frame): fading in while it
    /// replaces reps drawn fading out this frame, opaque otherwise (its
    /// fade, if any, ends).
    pub fn fade_in(&mut self, r: RepId) -> Fade {
        if !self.on() {
            return Fade::Opaque;
        }
        self.shown_now.insert(r);
        let Some(inc) = self.incoming.get(&r) else {
            return Fade::Opaque;
        };
        if inc.partners.iter().any(|&p| self.out_drawn.contains(p)) {
            Fade::In(self.progress(inc.start))
        } else {
            // Its partners were evicted: no fade (and no ghost of them).
            if let Some(inc) = self.incoming.remove(&r) {
                for p in inc.partners {
                    self.outgoing.remove(&p);
                }
            }
            Fade::Opaque
        }
    }

    /// A substitute drawn opaque this frame (shown).
    pub fn shown(&mut self, r: RepId) {
        if self.on() {
            self.shown_now.insert(r);
        }
    }

    /// Ends the frame: what was shown becomes last frame's.
    pub fn end_frame(&mut self) {
        if !self.on() {
            return;
        }
        std::mem::swap(&mut self.shown_prev, &mut self.shown_now);
        self.shown_now.clear();
        self.out_drawn.clear();
    }
}

#[cfg(test)]
#[path = "fade/tests.rs"]
mod tests;
