//! A clairvoyant P_I on the disk model (`--bounds`): what prefetching could
//! save on a path if it knew the path, under the same footprint and disk.
//! It separates the limit of prediction from those of the footprint and
//! the disk's bandwidth: how far ahead a P_I would have to know the path
//! to leave a given share of the demand reads. It is greedy (a reference,
//! not an optimum), and generous where the engine pays (below).
//!
//! Frame by frame: the view front's missing reps are read on demand
//! (Stage II), making room by evicting the resident rep used again last
//! (Belady); then, for as long as the frame is drawn at the render rate
//! (at least the frame period), the disk reads ahead the reps of the next
//! `horizon` frames in the order they are first drawn, evicting only reps
//! used again later than the one read. It reads by aligned pages as the
//! engine does, more generously: a frame's pages go in file order, one
//! seek per run of consecutive pages, and of each page read it keeps every
//! rep drawn within `keep` frames (room allowing, by the same rule) while
//! the pages themselves take no room.

use std::collections::BTreeSet;

use engine::disk::DiskModel;
use engine::evict::Eviction;
use engine::evict::belady::Belady;
use engine::skeleton::{RepId, Skeleton};

/// What the clairvoyant P_I read (bytes of whole pages).
#[derive(Debug, Default, PartialEq)]
pub struct Oracle {
    /// Read on demand (frames after the first).
    pub stage2_bytes: u64,
    /// Runs read on demand (seeks).
    pub stage2_seeks: u64,
    /// Frames with a demand read.
    pub stage2_frames: usize,
    /// Read ahead.
    pub prefetch_bytes: u64,
}

/// The setting: footprint, disk, and the time each frame gives.
pub struct Setting {
    pub budget: u64,
    pub disk: DiskModel,
    /// Pages read whole.
    pub page_bytes: u64,
    /// The shortest frame (the period), s.
    pub period_s: f64,
    /// Triangles drawn per second (0: frames last the period).
    pub render_rate: f64,
    /// Frames whose reps it reads ahead (0: it reads on demand only).
    pub horizon: usize,
    /// Of a page read, it keeps the reps drawn within this many frames.
    pub keep: usize,
}

/// One frame's page reads: runs of consecutive pages, and what they cost
/// on the disk model.
#[derive(Default)]
struct Batch {
    pages: BTreeSet<u64>,
    runs: u64,
}

impl Batch {
    /// The pages of `pages` not read yet, and the runs there would be with
    /// them read too.
    fn grown(&self, pages: std::ops::RangeInclusive<u64>) -> (BTreeSet<u64>, u64) {
        let mut more = BTreeSet::new();
        let mut runs = self.runs;
        for p in pages {
            if !self.pages.contains(&p) && more.insert(p) {
                let has = |q: u64| self.pages.contains(&q) || more.contains(&q);
                // A page joins the run before it, the run after it, or both.
                runs = (runs + 1) - u64::from(p > 0 && has(p - 1)) - u64::from(has(p + 1));
            }
        }
        (more, runs)
    }

    /// The seconds this batch would take with `pages` read too.
    fn cost_with(&self, s: &Setting, pages: std::ops::RangeInclusive<u64>) -> f64 {
        let (more, runs) = self.grown(pages);
        let n = (self.pages.len() + more.len()) as u64;
        runs as f64 * s.disk.latency.as_secs_f64()
            + (n * s.page_bytes) as f64 / s.disk.bytes_per_sec
    }

    fn add(&mut self, pages: std::ops::RangeInclusive<u64>) {
        let (more, runs) = self.grown(pages);
        self.pages.extend(more);
        self.runs = runs;
    }

    fn bytes(&self, page: u64) -> u64 {
        self.pages.len() as u64 * page
    }
}

/// The resident reps of a path's fronts, in Belady's order (the rep used
/// again last goes first: [`Belady`]); a pinned rep (drawn this frame) is
/// resident and not a victim. Also the demand fetching with Belady's
/// eviction of `--bounds`.
pub(crate) struct Resident<'a> {
    skel: &'a Skeleton,
    budget: u64,
    used: u64,
    order: Belady,
    uses: Vec<Vec<u32>>,
    cursor: Vec<usize>,
}

/// Belady's hint for a next use (`u32::MAX`: none, the rep is used again
/// last of all).
fn hint(k: u32) -> u32 {
    if k == u32::MAX { NEVER } else { k }
}

/// The next use of a rep never drawn again (after every frame; below
/// [`Belady::NOW`]).
const NEVER: u32 = Belady::NOW - 1;

impl<'a> Resident<'a> {
    /// Nothing resident under `budget`; the uses of each rep by `fronts`.
    pub(crate) fn new(skel: &'a Skeleton, fronts: &[Vec<RepId>], budget: u64) -> Self {
        let n = skel.reps.len();
        let mut uses: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (t, f) in fronts.iter().enumerate() {
            for &r in f {
                uses[r as usize].push(t as u32);
            }
        }
        Self {
            skel,
            budget,
            used: 0,
            order: Belady::new(n),
            uses,
            cursor: vec![0; n],
        }
    }

    pub(crate) fn len(&self, r: RepId) -> u64 {
        self.skel.reps[r as usize].resident_len()
    }

    pub(crate) fn contains(&self, r: RepId) -> bool {
        self.order.contains(r)
    }

    /// The first frame after `t` that draws `r` (`u32::MAX`: none).
    fn next_use(&mut self, r: RepId, t: usize) -> u32 {
        let u = &self.uses[r as usize];
        let c = &mut self.cursor[r as usize];
        while *c < u.len() && u[*c] as usize <= t {
            *c += 1;
        }
        u.get(*c).map_or(u32::MAX, |&x| x)
    }

    /// Pins `r` (drawn now) if resident.
    pub(crate) fn pin(&mut self, r: RepId) {
        if self.order.next_use(r).is_some() {
            self.order.access(r, Belady::NOW);
        }
    }

    /// Unpins `r`, keyed by its next use after `t`.
    pub(crate) fn unpin(&mut self, r: RepId, t: usize) {
        let k = self.next_use(r, t);
        self.order.access(r, hint(k));
    }

    /// Makes `r` resident with next use `k`, evicting reps used again
    /// after `k`; false when there is no such room. `u32::MAX` pins it: it
    /// is drawn now, so any unpinned rep may go, and it is admitted even
    /// when the front alone exceeds the budget.
    pub(crate) fn admit(&mut self, r: RepId, k: u32) -> bool {
        let need = self.len(r);
        let pin = k == u32::MAX;
        while self.used + need > self.budget {
            let victim = self.order.victims().next().map(|v| v.key);
            match victim {
                Some(v) if pin || self.order.next_use(v).is_some_and(|kk| kk > k) => {
                    self.order.remove(v);
                    self.used -= self.len(v);
                }
                None if pin => break,
                _ => return false,
            }
        }
        self.used += need;
        self.order.insert(r, if pin { Belady::NOW } else { k });
        true
    }
}

/// The clairvoyant P_I's reads on `fronts` (the view fronts, frame by
/// frame) in setting `s`.
pub fn clairvoyant(skel: &Skeleton, fronts: &[Vec<RepId>], s: &Setting) -> Oracle {
    // The reps each frame draws that the one before did not: a rep not
    // resident first drawn at frame u > t+1 is among frame u's entries.
    let entries = entries(fronts);
    let by_offset = skel.reps_in_file_order();
    let page = s.page_bytes.max(1);
    let span = |r: RepId| {
        let rec = skel.reps[r as usize];
        rec.offset / page..=(rec.offset + u64::from(rec.len).max(1) - 1) / page
    };
    // The reps stored from page `p` on.
    let in_page = |p: u64| {
        let i = by_offset.partition_point(|&r| skel.reps[r as usize].offset < p * page);
        let j = by_offset.partition_point(|&r| skel.reps[r as usize].offset < (p + 1) * page);
        &by_offset[i..j]
    };
    let mut res = Resident::new(skel, fronts, s.budget);
    let mut out = Oracle::default();
    // The other reps of the pages just read that are drawn within the
    // horizon stay, if there is room for them.
    let keep = |res: &mut Resident, pages: std::ops::RangeInclusive<u64>, t: usize| {
        for p in pages {
            for &g in in_page(p) {
                if res.contains(g) || *span(g).end() > p {
                    continue;
                }
                let k = res.next_use(g, t);
                if (k as usize) <= t + s.keep {
                    res.admit(g, k);
                }
            }
        }
    };
    for (t, f) in fronts.iter().enumerate() {
        for &r in f {
            res.pin(r);
        }
        // Stage II: the pages of the missing reps.
        let mut demand = Batch::default();
        for &r in f {
            if !res.contains(r) {
                res.admit(r, u32::MAX);
                demand.add(span(r));
            }
        }
        let read: Vec<u64> = demand.pages.iter().copied().collect();
        for p in read {
            keep(&mut res, p..=p, t);
        }
        if t > 0 && !demand.pages.is_empty() {
            out.stage2_bytes += demand.bytes(page);
            out.stage2_seeks += demand.runs;
            out.stage2_frames += 1;
        }
        for &r in f {
            res.unpin(r, t);
        }
        // Reading ahead while the frame is drawn.
        let tris: u64 = f
            .iter()
            .map(|&r| u64::from(skel.reps[r as usize].tri_count))
            .sum();
        let draw_s = if s.render_rate > 0.0 {
            tris as f64 / s.render_rate
        } else {
            0.0
        };
        let time = draw_s.max(s.period_s);
        let mut batch = Batch::default();
        let first = fronts
            .get(t + 1)
            .filter(|_| s.horizon > 0)
            .into_iter()
            .flatten()
            .map(|&r| (t + 1, r));
        let ahead = (t + 2..=t + s.horizon)
            .filter(|&u| u < fronts.len())
            .flat_map(|u| entries[u].iter().map(move |&r| (u, r)));
        let candidates: Vec<(usize, RepId)> = first.chain(ahead).collect();
        for (u, r) in candidates {
            if res.contains(r) || span(r).all(|p| batch.pages.contains(&p)) {
                continue;
            }
            if batch.cost_with(s, span(r)) > time || !res.admit(r, u as u32) {
                break;
            }
            batch.add(span(r));
            keep(&mut res, span(r), t);
        }
        out.prefetch_bytes += batch.bytes(page);
    }
    out
}

/// For each frame, the reps its front holds that the one before did not.
pub(crate) fn entries(fronts: &[Vec<RepId>]) -> Vec<Vec<RepId>> {
    let sorted: Vec<Vec<RepId>> = fronts
        .iter()
        .map(|f| {
            let mut v = f.clone();
            v.sort_unstable();
            v
        })
        .collect();
    fronts
        .iter()
        .enumerate()
        .map(|(t, f)| {
            f.iter()
                .copied()
                .filter(|&r| t == 0 || sorted[t - 1].binary_search(&r).is_err())
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn setting(budget: u64, horizon: usize) -> Setting {
        Setting {
            budget,
            disk: DiskModel {
                latency: Duration::from_millis(10),
                bytes_per_sec: 30e6,
            },
            page_bytes: 4096,
            period_s: 0.1,
            render_rate: 0.0,
            horizon,
            keep: horizon,
        }
    }

    /// Five reps, each in its own 4 KiB page, none beside another.
    fn skeleton() -> Skeleton {
        let reps = (0..5u64)
            .map(|i| engine::records::RepRecord {
                offset: i * 8192,
                len: 1000,
                tri_count: 10,
                vertex_count: 10,
                ..Default::default()
            })
            .collect();
        Skeleton {
            nodes: Vec::new(),
            reps,
            ..Skeleton::default()
        }
    }

    #[test]
    fn reading_ahead_leaves_no_demand_read_when_the_disk_keeps_up() {
        let skel = skeleton();
        // The path draws three reps one after another, then the first again.
        let fronts: Vec<Vec<RepId>> = vec![vec![1], vec![2], vec![3], vec![1]];
        let all: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
        let none = clairvoyant(&skel, &fronts, &setting(all, 0));
        assert_eq!(
            (none.stage2_frames, none.stage2_bytes, none.prefetch_bytes),
            (2, 2 * 4096, 0)
        );
        let ahead = clairvoyant(&skel, &fronts, &setting(all, 4));
        assert_eq!((ahead.stage2_bytes, ahead.prefetch_bytes), (0, 2 * 4096));
        // Room for one rep: rep 1 is evicted for rep 2 (drawn sooner) and
        // read again, ahead, for the last frame.
        let one = skel.reps[1].resident_len();
        let tight = clairvoyant(&skel, &fronts, &setting(one, 4));
        assert_eq!((tight.stage2_bytes, tight.prefetch_bytes), (0, 3 * 4096));
    }

    #[test]
    fn a_slow_disk_leaves_demand_reads() {
        let skel = skeleton();
        let fronts: Vec<Vec<RepId>> = vec![vec![1], vec![2], vec![3]];
        let all: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
        let mut s = setting(all, 4);
        // A seek takes longer than a frame: nothing is read ahead.
        s.disk.latency = Duration::from_millis(200);
        let o = clairvoyant(&skel, &fronts, &s);
        assert_eq!((o.stage2_frames, o.prefetch_bytes), (2, 0), "{o:?}");
    }
}
