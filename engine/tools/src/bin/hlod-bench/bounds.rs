//! `--bounds`: what any fetching policy could do on a path, from the fronts
//! alone (no run): how much the path must read at least, whether an oracle
//! prefetcher's working set fits the footprint, and how long the disk model
//! needs to read it. It separates the limits of the budget and of the disk
//! from those of prediction.

use std::collections::HashSet;
use std::fmt::Write as _;

use engine::camera::Pose;
use engine::disk::DiskModel;
use engine::front::FrontIndex;
use engine::runtime::RuntimeParams;
use engine::skeleton::{RepId, Skeleton};

const MIB: f64 = 1048576.0;
/// Frames the clairvoyant P_I knows ahead (4 s at 30 fps), and the
/// shorter horizons measured.
const ORACLE_HORIZON: usize = 120;
const ORACLE_HORIZONS: [usize; 5] = [3, 10, 30, 60, ORACLE_HORIZON];
/// A rep under this size costs its seek rather than its transfer.
const SMALL: u64 = 8 << 10;

/// How the clairvoyant P_I reads and how long a frame is drawn.
pub struct Io {
    /// Pages it reads by (`--page`; 128 KiB when off).
    pub page_bytes: u64,
    /// Triangles drawn per second (`--render-rate`).
    pub render_rate: f64,
}

/// The bounds table (markdown) for `poses` under `params`, for each budget.
pub fn bounds(
    skel: &Skeleton,
    poses: &[Pose],
    params: &RuntimeParams,
    budgets: &[u64],
    disk: Option<DiskModel>,
    fps: f32,
    io: Io,
) -> String {
    let index = FrontIndex::new(skel);
    let len = |r: RepId| skel.reps[r as usize].resident_len();
    let fronts: Vec<Vec<RepId>> = poses
        .iter()
        .map(|p| {
            let view = params.view(p);
            let mut out = Vec::new();
            index.compute(&view, &view.frustum(0.0), params.tolerance_px, &mut out);
            out
        })
        .collect();
    let bytes = |f: &[RepId]| f.iter().map(|&r| len(r)).sum::<u64>();
    let mut sizes: Vec<u64> = fronts.iter().map(|f| bytes(f)).collect();
    sizes.sort_unstable();
    let mut seen: HashSet<RepId> = fronts.first().into_iter().flatten().copied().collect();
    let mut new_reps: Vec<RepId> = Vec::new();
    for f in fronts.iter().skip(1) {
        new_reps.extend(f.iter().filter(|&&r| seen.insert(r)));
    }
    let small: Vec<RepId> = new_reps
        .iter()
        .copied()
        .filter(|&r| len(r) < SMALL)
        .collect();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "front: median {:.2} MiB, max {:.2} MiB; {} reps drawn after the first frame for the first time ({:.2} MiB: the least that fetching on demand alone reads), {} of them under {} KiB ({:.2} MiB)",
        sizes[sizes.len() / 2] as f64 / MIB,
        sizes[sizes.len() - 1] as f64 / MIB,
        new_reps.len(),
        bytes(&new_reps) as f64 / MIB,
        small.len(),
        SMALL >> 10,
        bytes(&small) as f64 / MIB
    );
    // The oracle's working set: the fronts of the next second together.
    let w = (fps.max(1.0) as usize).max(1);
    let mut max_u = 0u64;
    let mut sum_u = 0u64;
    let mut n_u = 0u64;
    for t in (0..fronts.len()).step_by(w) {
        let u: HashSet<RepId> = fronts[t..(t + w).min(fronts.len())]
            .iter()
            .flatten()
            .copied()
            .collect();
        let b = u.iter().map(|&r| len(r)).sum::<u64>();
        max_u = max_u.max(b);
        sum_u += b;
        n_u += 1;
    }
    let _ = writeln!(
        s,
        "fronts of the next {w} frames together: mean {:.2} MiB, max {:.2} MiB",
        sum_u as f64 / n_u.max(1) as f64 / MIB,
        max_u as f64 / MIB
    );
    if let Some(d) = disk {
        // Every rep the path draws, read once in file order: runs joined
        // through gaps shorter than the break-even gap.
        let mut all: Vec<RepId> = fronts.iter().flatten().copied().collect();
        all.sort_unstable_by_key(|&r| skel.reps[r as usize].offset);
        all.dedup();
        let seek = d.latency.as_secs_f64();
        let gap = (seek * d.bytes_per_sec) as u64;
        let (runs, read) = file_order_runs(skel, &all, gap);
        let one_seek_each = all.len() as f64 * seek + bytes(&all) as f64 / d.bytes_per_sec;
        let _ = writeln!(
            s,
            "disk: the {} reps the path draws take {:.1} s read one seek each, {:.1} s in {runs} runs in file order ({:.2} MiB read through gaps under {} KiB); the path lasts {:.1} s",
            all.len(),
            one_seek_each,
            runs as f64 * seek + read as f64 / d.bytes_per_sec,
            read as f64 / MIB,
            gap >> 10,
            fronts.len() as f64 / f64::from(fps.max(1e-3))
        );
        s.push_str(&new_per_frame(skel, &fronts, gap, seek, d.bytes_per_sec));
    }
    s.push_str(&all_around(
        skel, &index, poses, params, &fronts, budgets, disk,
    ));
    let _ = writeln!(
        s,
        "\n| budget MiB | demand fetch, optimal eviction (MiB) | reads |\n|---:|---:|---:|"
    );
    for &b in budgets {
        let (mib, reads) = belady(skel, &fronts, b);
        let _ = writeln!(s, "| {:.2} | {:.2} | {reads} |", b as f64 / MIB, mib);
    }
    if let Some(d) = disk {
        s.push_str(&clairvoyant_table(skel, &fronts, budgets, d, fps, &io));
    }
    s
}

/// The clairvoyant P_I's demand reads against reading on demand alone
/// with the same I/O, per budget ([`crate::oracle`]).
fn clairvoyant_table(
    skel: &Skeleton,
    fronts: &[Vec<RepId>],
    budgets: &[u64],
    disk: DiskModel,
    fps: f32,
    io: &Io,
) -> String {
    let page = if io.page_bytes > 0 {
        io.page_bytes
    } else {
        128 << 10
    };
    let mut s = format!(
        "\nA clairvoyant P_I that reads ahead H frames: while each frame is drawn (at {:.0} triangles/s, at least the period) it reads the reps the next H frames draw, first drawn first, by {} KiB pages, one seek per run of consecutive pages; of every page read it keeps the reps drawn within {ORACLE_HORIZON} frames; Belady's eviction. Stage II MiB of pages (frames with a demand read); on demand alone: H = 0.\n\n| budget MiB | on demand alone |{}\n|---:|---:|{}\n",
        io.render_rate,
        page >> 10,
        ORACLE_HORIZONS.map(|h| format!(" H = {h} |")).concat(),
        "---:|".repeat(ORACLE_HORIZONS.len())
    );
    for &b in budgets {
        let setting = |horizon| crate::oracle::Setting {
            budget: b,
            disk,
            page_bytes: page,
            period_s: 1.0 / f64::from(fps.max(1e-3)),
            render_rate: io.render_rate,
            horizon,
            keep: ORACLE_HORIZON,
        };
        let cell = |o: crate::oracle::Oracle| {
            format!(
                " {:.2} ({}) |",
                o.stage2_bytes as f64 / MIB,
                o.stage2_frames
            )
        };
        let none = crate::oracle::clairvoyant(skel, fronts, &setting(0));
        let _ = write!(s, "| {:.2} |{}", b as f64 / MIB, cell(none));
        for h in ORACLE_HORIZONS {
            s.push_str(&cell(crate::oracle::clairvoyant(skel, fronts, &setting(h))));
        }
        s.push('\n');
    }
    s
}

/// Demand fetching with Belady's eviction (the resident rep used again
/// last goes first; a greedy bound with reps of different sizes): the
/// Stage II bytes after the first frame and the number of reps read.
fn belady(skel: &Skeleton, fronts: &[Vec<RepId>], budget: u64) -> (f64, u64) {
    let mut res = crate::oracle::Resident::new(skel, fronts, budget);
    let (mut fetched, mut reads) = (0u64, 0u64);
    for (t, f) in fronts.iter().enumerate() {
        for &r in f {
            res.pin(r);
        }
        for &r in f {
            if !res.contains(r) {
                res.admit(r, u32::MAX);
                if t > 0 {
                    fetched += res.len(r);
                    reads += 1;
                }
            }
        }
        for &r in f {
            res.unpin(r, t);
        }
    }
    (fetched as f64 / MIB, reads)
}

/// The all-around front A(t) (the front at ε with no frustum culling): the
/// view front is its part in the frustum, so a P_I that kept A(t-1)
/// resident would miss only what the motion of frame t switched.
fn all_around(
    skel: &Skeleton,
    index: &FrontIndex,
    poses: &[Pose],
    params: &RuntimeParams,
    fronts: &[Vec<RepId>],
    budgets: &[u64],
    disk: Option<DiskModel>,
) -> String {
    let len = |r: RepId| skel.reps[r as usize].resident_len();
    let around: Vec<Vec<RepId>> = poses.iter().map(|p| around_of(index, params, p)).collect();
    let mut sizes: Vec<u64> = around
        .iter()
        .map(|a| a.iter().map(|&r| len(r)).sum())
        .collect();
    let (mut miss_n, mut miss_b, mut churn_n, mut churn_b, mut churn_s) =
        (0u64, 0u64, 0u64, 0u64, 0f64);
    for t in 1..around.len() {
        let prev = &around[t - 1];
        for &r in &fronts[t] {
            if prev.binary_search(&r).is_err() {
                miss_n += 1;
                miss_b += len(r);
            }
        }
        let mut new: Vec<RepId> = around[t]
            .iter()
            .copied()
            .filter(|r| prev.binary_search(r).is_err())
            .collect();
        churn_n += new.len() as u64;
        churn_b += new.iter().map(|&r| len(r)).sum::<u64>();
        if let Some(d) = disk {
            new.sort_unstable_by_key(|&r| skel.reps[r as usize].offset);
            let seek = d.latency.as_secs_f64();
            let (runs, read) = file_order_runs(skel, &new, (seek * d.bytes_per_sec) as u64);
            churn_s += runs as f64 * seek + read as f64 / d.bytes_per_sec;
        }
    }
    // How predictable those switches are: the all-around front of the
    // position extrapolated `k` frames ahead from frame t-k (the motion of
    // its last frame) holds r, or r was already in A(t-k).
    let mut foresee = Vec::new();
    for k in [5usize, 10] {
        let (mut n, mut b, mut tot) = (0u64, 0u64, 0u64);
        for t in (k + 1)..around.len() {
            let s0 = t - k;
            let v = poses[s0].position - poses[s0 - 1].position;
            let ahead = Pose {
                position: poses[s0].position + v * k as f32,
                ..poses[s0]
            };
            let pred = around_of(index, params, &ahead);
            for &r in &fronts[t] {
                if around[t - 1].binary_search(&r).is_err() {
                    tot += 1;
                    if pred.binary_search(&r).is_ok() || around[s0].binary_search(&r).is_ok() {
                        n += 1;
                        b += len(r);
                    }
                }
            }
        }
        foresee.push(format!(
            "{k} frames ahead {n} of {tot} ({:.2} MiB)",
            b as f64 / MIB
        ));
    }
    let over: Vec<String> = budgets
        .iter()
        .map(|&b| {
            format!(
                "{} over {:.2} MiB",
                sizes.iter().filter(|&&x| x > b).count(),
                b as f64 / MIB
            )
        })
        .collect();
    sizes.sort_unstable();
    format!(
        "all-around front: median {:.2} MiB, max {:.2} MiB (frames {}); with A(t-1) resident the view fronts miss {miss_n} reps ({:.2} MiB); A changes by {churn_n} reps ({:.2} MiB) over the path, {churn_s:.1} s to read in file order frame by frame; extrapolating the camera's position, the all-around fronts foresee those misses {}\n",
        sizes[sizes.len() / 2] as f64 / MIB,
        sizes[sizes.len() - 1] as f64 / MIB,
        over.join(", "),
        miss_b as f64 / MIB,
        churn_b as f64 / MIB,
        foresee.join(", "),
    )
}

/// The all-around front of `pose` (no frustum culling), sorted by rep id.
fn around_of(index: &FrontIndex, params: &RuntimeParams, pose: &Pose) -> Vec<RepId> {
    let view = params.view(pose);
    let mut out = Vec::new();
    let f = engine::camera::Frustum::all_around(pose.position, pose.forward());
    index.compute(&view, &f, params.tolerance_px, &mut out);
    out.sort_unstable();
    out
}

/// `reps` (in file order) read as runs joined through gaps up to `gap`
/// bytes: the number of runs and the bytes read, gaps included.
/// The reps each frame draws that the previous one did not, read in file
/// order with the same coalescing: how many runs (seeks) they take, over the
/// path and in the busiest 1% of frames (the sudden turns).
fn new_per_frame(skel: &Skeleton, fronts: &[Vec<RepId>], gap: u64, seek: f64, rate: f64) -> String {
    let mut frames: Vec<(usize, u64, u64)> = Vec::new();
    for mut new in crate::oracle::entries(fronts).into_iter().skip(1) {
        new.sort_unstable_by_key(|&r| skel.reps[r as usize].offset);
        let (runs, read) = file_order_runs(skel, &new, gap);
        frames.push((new.len(), runs, read));
    }
    frames.sort_unstable_by_key(|f| std::cmp::Reverse(f.0));
    let sum = |f: &[(usize, u64, u64)]| {
        f.iter().fold((0usize, 0u64, 0u64), |a, x| {
            (a.0 + x.0, a.1 + x.1, a.2 + x.2)
        })
    };
    let (n, runs, _) = sum(&frames);
    let top = &frames[..frames.len().div_ceil(100).min(frames.len())];
    let (tn, truns, tread) = sum(top);
    format!(
        "newly drawn reps, frame by frame: {n} in {runs} runs ({:.1} a run); in the busiest 1% of frames {:.0} a frame in {:.0} runs, {:.0} ms a frame at the disk model\n",
        n as f64 / runs.max(1) as f64,
        tn as f64 / top.len().max(1) as f64,
        truns as f64 / top.len().max(1) as f64,
        (truns as f64 * seek + tread as f64 / rate) * 1e3 / top.len().max(1) as f64
    )
}

fn file_order_runs(skel: &Skeleton, reps: &[RepId], gap: u64) -> (u64, u64) {
    let (mut runs, mut read, mut end) = (0u64, 0u64, None::<u64>);
    for &r in reps {
        let rec = skel.reps[r as usize];
        match end {
            Some(e) if rec.offset <= e + gap => read += rec.offset.saturating_sub(e),
            _ => runs += 1,
        }
        read += u64::from(rec.len);
        end = Some(rec.offset + u64::from(rec.len));
    }
    (runs, read)
}
