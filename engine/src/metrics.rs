//! Per-frame metrics, their CSV form and the per-run summary.

use std::fmt::Write as _;

/// How a field is written in a CSV cell.
trait Cell {
    fn cell(&self, out: &mut String);
}

impl Cell for u32 {
    fn cell(&self, out: &mut String) {
        let _ = write!(out, "{self}");
    }
}

impl Cell for u64 {
    fn cell(&self, out: &mut String) {
        let _ = write!(out, "{self}");
    }
}

impl Cell for &'static str {
    fn cell(&self, out: &mut String) {
        out.push_str(self);
    }
}

impl Cell for f64 {
    fn cell(&self, out: &mut String) {
        let _ = write!(out, "{self:.3}");
    }
}

/// How a column is totalled over a run: summed, or its largest value.
pub trait Total: Copy {
    type Out: Copy + Default + std::fmt::Debug + PartialEq;
    fn sum(acc: &mut Self::Out, v: Self);
    fn max(acc: &mut Self::Out, v: Self);
}

impl Total for u32 {
    type Out = u64;
    fn sum(acc: &mut u64, v: u32) {
        *acc += u64::from(v);
    }
    fn max(acc: &mut u64, v: u32) {
        *acc = (*acc).max(u64::from(v));
    }
}

impl Total for u64 {
    type Out = u64;
    fn sum(acc: &mut u64, v: u64) {
        *acc = acc.saturating_add(v);
    }
    fn max(acc: &mut u64, v: u64) {
        *acc = (*acc).max(v);
    }
}

impl Total for f64 {
    type Out = f64;
    fn sum(acc: &mut f64, v: f64) {
        *acc += v;
    }
    fn max(acc: &mut f64, v: f64) {
        *acc = acc.max(v);
    }
}

/// Defines [`FrameMetrics`] and the [`LoaderCounters`] embedded in it from
/// one field list (`loader.name: type` for P_I's), with the CSV header and
/// row, whose columns follow the list, and the run's [`FrameTotals`] of the
/// columns marked `=> sum` or `=> max`.
macro_rules! frame_metrics {
    // Sorts each field into FrameMetrics' own or the loader's, keeps the
    // column order (`name (prefix)`) and the run totals (`name (prefix)
    // type how`).
    (@sort [$($own:tt)*] [$($ldr:tt)*] [$($col:tt)*] [$($tot:tt)*]
        $(#[$doc:meta])* loader . $field:ident : $ty:ty => $how:ident, $($rest:tt)*) => {
        frame_metrics!(@sort [$($own)*] [$($ldr)* $(#[$doc])* $field: $ty,]
            [$($col)* $field (loader)] [$($tot)* $field (loader) [$ty] $how] $($rest)*);
    };
    (@sort [$($own:tt)*] [$($ldr:tt)*] [$($col:tt)*] [$($tot:tt)*]
        $(#[$doc:meta])* loader . $field:ident : $ty:ty, $($rest:tt)*) => {
        frame_metrics!(@sort [$($own)*] [$($ldr)* $(#[$doc])* $field: $ty,]
            [$($col)* $field (loader)] [$($tot)*] $($rest)*);
    };
    (@sort [$($own:tt)*] [$($ldr:tt)*] [$($col:tt)*] [$($tot:tt)*]
        $(#[$doc:meta])* $field:ident : $ty:ty => $how:ident, $($rest:tt)*) => {
        frame_metrics!(@sort [$($own)* $(#[$doc])* $field: $ty,] [$($ldr)*]
            [$($col)* $field ()] [$($tot)* $field () [$ty] $how] $($rest)*);
    };
    (@sort [$($own:tt)*] [$($ldr:tt)*] [$($col:tt)*] [$($tot:tt)*]
        $(#[$doc:meta])* $field:ident : $ty:ty, $($rest:tt)*) => {
        frame_metrics!(@sort [$($own)* $(#[$doc])* $field: $ty,] [$($ldr)*]
            [$($col)* $field ()] [$($tot)*] $($rest)*);
    };
    (@sort [$($(#[$odoc:meta])* $own:ident : $oty:ty,)*]
        [$($(#[$ldoc:meta])* $ldr:ident : $lty:ty,)*]
        [$($col:ident ($($pre:ident)?))*]
        [$($tf:ident ($($tpre:ident)?) [$tty:ty] $how:ident)*]) => {
        /// A run's totals of the columns that add up (`=> sum`) and the
        /// largest value of those that are levels (`=> max`), integers in
        /// `u64`; [`FrameTotals::add`] takes one frame.
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        pub struct FrameTotals {
            $( pub $tf: <$tty as Total>::Out, )*
        }

        impl FrameTotals {
            /// Adds frame `f`.
            pub fn add(&mut self, f: &FrameMetrics) {
                $( <$tty as Total>::$how(&mut self.$tf, f $(.$tpre)? .$tf); )*
            }
        }

        /// What one frame did. `stage2_bytes` were fetched on demand while
        /// P_R waited to render; `prefetch_bytes` were loaded by P_I since
        /// the previous frame's Stage II ended (Stages III and I).
        ///
        /// The struct, P_I's [`LoaderCounters`] in it, the CSV header
        /// ([`CSV_HEADER`], [`FrameMetrics::COLUMNS`]) and the CSV row
        /// ([`FrameMetrics::csv_row`]) come from one list: a new counter is
        /// one line there (its CSV cell follows its type: integers and names
        /// as they are, milliseconds with three decimals).
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct FrameMetrics {
            $( $(#[$odoc])* pub $own: $oty, )*
            /// P_I's counters, as its Stage II reported them.
            pub loader: LoaderCounters,
        }

        /// P_I's counters since the previous frame's Stage II, reported at
        /// the end of this frame's (the loader fills them in place).
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        pub struct LoaderCounters {
            $( $(#[$ldoc])* pub $ldr: $lty, )*
        }

        /// The CSV header: [`FrameMetrics::COLUMNS`] joined by commas.
        pub const CSV_HEADER: &str = {
            const H: &str = concat!($(stringify!($col), ","),*);
            // Without the trailing comma.
            match H.as_bytes().split_last() {
                Some((_, rest)) => match std::str::from_utf8(rest) {
                    Ok(s) => s,
                    Err(_) => panic!("ASCII names"),
                },
                None => H,
            }
        };

        impl FrameMetrics {
            /// The CSV columns, in order: the field names (P_I's without
            /// their `loader.`).
            pub const COLUMNS: &'static [&'static str] = &[$(stringify!($col)),*];

            /// One CSV line (no newline), in [`CSV_HEADER`]'s order.
            pub fn csv_row(&self) -> String {
                let mut s = String::with_capacity(256);
                $(
                    Cell::cell(&self $(.$pre)? .$col, &mut s);
                    s.push(',');
                )*
                s.pop();
                s
            }
        }
    };
    ({ $($body:tt)* }) => {
        frame_metrics!(@sort [] [] [] [] $($body)*);
    };
}

frame_metrics! {
    {
        frame: u32,
        mode: &'static str,
        frame_ms: f64 => sum,
        front_ms: f64 => sum,
        wait_ms: f64 => sum,
        front_reps: u32,
        front_tris: u64,
        front_bytes: u64 => max,
        loader.missing_reps: u32 => sum,
        loader.stage2_bytes: u64 => sum,
        loader.prefetch_bytes: u64 => sum,
        loader.resident_bytes: u64,
        /// The largest resident footprint at any moment since the previous frame.
        loader.max_resident_bytes: u64 => max,
        budget_bytes: u64 => max,
        loader.evictions: u32 => sum,
        /// Front reps drawn as a resident ancestor.
        substituted: u32 => sum,
        /// Front reps drawn as themselves.
        drawn_reps: u32,
        drawn_tris: u64,
        loader.read_errors: u32 => sum,
        nodes_visited: u32,
        /// Occlusion culling (off: zeros): front reps rasterised as
        /// occluders, front reps left out as hidden (not in `front_reps`),
        /// triangles rasterised, both passes' time, and the occluder store's
        /// bytes (part of the footprint: `max_resident_bytes` +
        /// `occluder_bytes` never exceed `budget_bytes`).
        occluders: u32,
        occluded_reps: u32 => sum,
        occluder_tris: u64 => sum,
        occlusion_ms: f64 => sum,
        occluder_bytes: u64 => max,
        /// The tolerance this frame's front was computed for (the quality
        /// governor's; ε without it), in pixels, and the fronts computed to
        /// choose it.
        tolerance_px: f64 => max,
        front_tries: u32,
        /// Smooth LOD switches: front reps drawn fading in, and reps drawn
        /// fading out (both resident; their triangles in `drawn_tris`).
        fade_in: u32 => sum,
        fade_out: u32 => sum,
        /// Misses whose node was in the previous front (an LOD switch).
        loader.miss_lod: u32 => sum,
        /// Misses whose ancestor or descendant node was (an HLOD switch).
        loader.miss_hier: u32 => sum,
        /// Misses of newly visible parts of the scene.
        loader.miss_new: u32 => sum,
        /// Time P_I spent reading for Stage II and for prefetching since the
        /// previous frame (the disk's busy time).
        loader.stage2_io_ms: f64 => sum,
        loader.prefetch_io_ms: f64 => sum,
        /// Rep geometry held by the renderer on the GPU (0 without a GPU).
        gpu_bytes: u64 => max,
        /// Prefetch candidates queued in P_I's bins at the end of Stage II.
        loader.prefetch_queue: u32,
        /// View-dependence trees drawn this frame, their splits + collapses
        /// (*Adapt*), active triangles, misses (a wanted split or collapse whose
        /// meta-node was absent), meta-nodes read since the previous frame, the
        /// bytes their stores hold (in-core part + place holders, within the
        /// footprint reserved for them) and the refinement time.
        vdt_trees: u32,
        adapt: u32 => sum,
        vdt_tris: u64 => sum,
        vdt_misses: u32 => sum,
        metas_loaded: u32 => sum,
        vdt_bytes: u64 => max,
        vdt_ms: f64 => sum,
        /// Bytes of gaps P_I read through instead of seeking over (not kept).
        loader.skipped_bytes: u64 => sum,
        /// Prefetch reads continued after a fetch command preempted them.
        loader.resumed: u32 => sum,
        /// Bytes of prefetched reps evicted before they were ever drawn.
        loader.wasted_bytes: u64 => sum,
        /// Reads that did not continue where P_I's previous read ended, in
        /// Stage II and in prefetching.
        loader.stage2_seeks: u32 => sum,
        loader.prefetch_seeks: u32 => sum,
        /// Front reps drawn as an ancestor because the stall deadline passed
        /// (also counted in `substituted`), and bytes read on demand after
        /// their frame's deadline.
        loader.late_reps: u32 => sum,
        loader.late_bytes: u64 => sum,
        /// P_I's time classifying fronts for prefetching (the F_I front, its
        /// bins and the lookahead fronts) since the previous frame; CPU time
        /// on P_I's thread, not the disk's.
        loader.classify_ms: f64 => sum,
        /// Prefetch reads refused because no room could be made under the
        /// budget (what could be evicted was accessed this frame, pinned, or
        /// not speculative past the speculative cap).
        loader.prefetch_noroom: u32 => sum,
        /// Times P_I chose to wait for the fetch command, its next read not
        /// ending before it was due.
        loader.prefetch_waits: u32 => sum,
        /// P_I's time waiting for a command with nothing to read.
        loader.idle_ms: f64 => sum,
        /// Of `classify_ms`: the lookahead's fronts.
        loader.lookahead_ms: f64 => sum,
        /// The longest gap P_I reads through rather than seeking over (learnt
        /// from its reads), at the end of the frame's Stage II.
        loader.coalesce_gap: u32 => max,
        /// P_I's time expanding compressed reps (meshopt's decoders) and
        /// the bytes they expanded to, since the previous frame.
        loader.expand_ms: f64 => sum,
        loader.expanded_bytes: u64 => sum,
        /// Multi-Triangulations drawn this frame, their cut arcs and
        /// triangles, their refinements + coarsenings, the reads and
        /// partitions read this frame (P_R's, through the disk model),
        /// misses (nodes wanted and not read: footprint, checksum, I/O) and
        /// the nodes their stores hold (their bytes are in `vdt_bytes`).
        mt_trees: u32,
        mt_cut_arcs: u32,
        mt_tris: u64 => sum,
        mt_adapt: u32 => sum,
        mt_reads: u32 => sum,
        mt_partitions: u32 => sum,
        mt_read_bytes: u64 => sum,
        mt_misses: u32 => sum,
        mt_nodes: u32 => max,
        /// P_I's time waiting for room on the full reply channel (P_R
        /// still drawing what it was sent) since the previous frame.
        loader.reply_wait_ms: f64 => sum,
        /// Reads by pages on a seek-bound disk: reps copied out of a page
        /// already held (no read), and the pages' bytes at the end of Stage
        /// II (part of `resident_bytes`).
        loader.page_hits: u32 => sum,
        loader.page_bytes: u64,
    }
}

/// The whole CSV of a run.
pub fn to_csv(frames: &[FrameMetrics]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for f in frames {
        s.push_str(&f.csv_row());
        s.push('\n');
    }
    s
}

/// Summary of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    pub mode: &'static str,
    pub frames: usize,
    pub mean_ms: f64,
    pub median_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    pub over_period: usize,
    /// Bytes read on demand: in Stage II, and late (after a frame's stall
    /// deadline).
    pub stage2_bytes: u64,
    pub prefetch_bytes: u64,
    pub max_resident_bytes: u64,
    pub budget_bytes: u64,
    pub substituted: u64,
    /// Of `substituted`: front reps not loaded by the stall deadline.
    pub late_reps: u64,
    pub mean_front_ms: f64,
    /// Frames that drew a view-dependence tree or MT, and per such frame: mean
    /// Adapt, mean active tree triangles, Miss % (misses / (Adapt +
    /// misses)), mean refinement ms; meta-nodes read and the most bytes the
    /// tree stores held.
    pub vdt_frames: usize,
    pub mean_adapt: f64,
    pub mean_vdt_tris: f64,
    pub vdt_miss_pct: f64,
    pub mean_vdt_ms: f64,
    pub metas_loaded: u64,
    pub max_vdt_bytes: u64,
    /// Every column's run total (or largest value).
    pub totals: FrameTotals,
}

/// `q`-quantile (0..=1) of `v` by the nearest-rank method.
pub fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let rank = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len());
    s[rank - 1]
}

/// What a run keeps of a frame once its CSV row is written: what the
/// summary's quantiles, the plots and the image-quality table need (40
/// bytes instead of the whole [`FrameMetrics`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TracePoint {
    pub frame_ms: f64,
    pub front_bytes: u64,
    pub stage2_bytes: u64,
    pub max_resident_bytes: u64,
    pub substituted: u32,
}

/// A run's summary, accumulated one frame at a time (the frames themselves
/// go to a [`CsvStream`], not to memory).
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    mode: &'static str,
    totals: FrameTotals,
    trace: Vec<TracePoint>,
    /// Frames that drew a view-dependence tree or a Multi-Triangulation.
    vdt_frames: usize,
}

impl Recorder {
    /// Adds one frame.
    pub fn push(&mut self, f: &FrameMetrics) {
        if self.trace.is_empty() {
            self.mode = f.mode;
        }
        self.totals.add(f);
        if f.vdt_trees > 0 || f.mt_trees > 0 {
            self.vdt_frames += 1;
        }
        self.trace.push(TracePoint {
            frame_ms: f.frame_ms,
            front_bytes: f.front_bytes,
            stage2_bytes: f.loader.stage2_bytes,
            max_resident_bytes: f.loader.max_resident_bytes,
            substituted: f.substituted,
        });
    }

    /// What was kept of each frame, in order.
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }

    /// The kept frames, the recorder done with (no copy).
    pub fn into_trace(mut self) -> Vec<TracePoint> {
        self.trace.shrink_to_fit();
        self.trace
    }

    /// The summary against the frame period `period_ms`.
    pub fn summary(&self, period_ms: f64) -> Summary {
        let t: Vec<f64> = self.trace.iter().map(|p| p.frame_ms).collect();
        let tot = &self.totals;
        let n = t.len().max(1) as f64;
        // Tree columns are 0 in frames without a tree: their sums are the
        // sums over the frames with one.
        let k = self.vdt_frames.max(1) as f64;
        Summary {
            mode: self.mode,
            frames: t.len(),
            mean_ms: tot.frame_ms / n,
            median_ms: quantile(&t, 0.5),
            p99_ms: quantile(&t, 0.99),
            max_ms: t.iter().copied().fold(0.0, f64::max),
            over_period: t.iter().filter(|&&x| x > period_ms).count(),
            stage2_bytes: tot.stage2_bytes + tot.late_bytes,
            prefetch_bytes: tot.prefetch_bytes,
            max_resident_bytes: tot.max_resident_bytes,
            budget_bytes: tot.budget_bytes,
            substituted: tot.substituted,
            late_reps: tot.late_reps,
            mean_front_ms: tot.front_ms / n,
            vdt_frames: self.vdt_frames,
            mean_adapt: tot.adapt as f64 / k,
            // `+ 0.0`: an empty sum is -0.0.
            mean_vdt_tris: tot.vdt_tris as f64 / k + 0.0,
            vdt_miss_pct: 100.0 * tot.vdt_misses as f64
                / (tot.adapt + tot.vdt_misses).max(1) as f64,
            mean_vdt_ms: tot.vdt_ms / k + 0.0,
            metas_loaded: tot.metas_loaded,
            max_vdt_bytes: tot.vdt_bytes,
            totals: *tot,
        }
    }
}

/// Summarises frames against the frame period `period_ms`.
pub fn summarize(frames: &[FrameMetrics], period_ms: f64) -> Summary {
    let mut r = Recorder::default();
    for f in frames {
        r.push(f);
    }
    r.summary(period_ms)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generated_csv_is_the_one_the_tools_and_plots_read() {
        // The header and cell formats as they were written by hand before
        // the column list generated them (P_I's counters among P_R's).
        assert_eq!(
            CSV_HEADER,
            "frame,mode,frame_ms,front_ms,wait_ms,front_reps,front_tris,front_bytes,missing_reps,stage2_bytes,prefetch_bytes,resident_bytes,max_resident_bytes,budget_bytes,evictions,substituted,drawn_reps,drawn_tris,read_errors,nodes_visited,occluders,occluded_reps,occluder_tris,occlusion_ms,occluder_bytes,tolerance_px,front_tries,fade_in,fade_out,miss_lod,miss_hier,miss_new,stage2_io_ms,prefetch_io_ms,gpu_bytes,prefetch_queue,vdt_trees,adapt,vdt_tris,vdt_misses,metas_loaded,vdt_bytes,vdt_ms,skipped_bytes,resumed,wasted_bytes,stage2_seeks,prefetch_seeks,late_reps,late_bytes,classify_ms,prefetch_noroom,prefetch_waits,idle_ms,lookahead_ms,coalesce_gap,expand_ms,expanded_bytes,mt_trees,mt_cut_arcs,mt_tris,mt_adapt,mt_reads,mt_partitions,mt_read_bytes,mt_misses,mt_nodes,reply_wait_ms,page_hits,page_bytes"
        );
        let f = FrameMetrics {
            frame: 7,
            mode: "pre",
            frame_ms: 12.34567,
            loader: LoaderCounters {
                stage2_bytes: 4096,
                classify_ms: 0.5,
                ..Default::default()
            },
            ..Default::default()
        };
        let row = f.csv_row();
        assert!(
            row.starts_with("7,pre,12.346,0.000,0.000,0,0,0,0,4096,"),
            "{row}"
        );
        assert!(
            row.ends_with(",0,0,0.500,0,0,0.000,0.000,0,0.000,0,0,0,0,0,0,0,0,0,0,0.000,0,0"),
            "{row}"
        );
    }

    #[test]
    fn totals_sum_the_counters_and_keep_the_largest_levels() {
        let f = |i: u32| FrameMetrics {
            frame_ms: f64::from(i),
            substituted: i,
            gpu_bytes: u64::from(10 - i),
            loader: LoaderCounters {
                stage2_bytes: 100,
                late_bytes: 1,
                max_resident_bytes: u64::from(i) * 7,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut t = FrameTotals::default();
        for i in 1..=4 {
            t.add(&f(i));
        }
        assert_eq!(t.frame_ms, 10.0);
        assert_eq!(t.substituted, 10);
        assert_eq!(t.stage2_bytes, 400);
        assert_eq!(t.max_resident_bytes, 28);
        assert_eq!(t.gpu_bytes, 9);
        let s = summarize(&(1..=4).map(f).collect::<Vec<_>>(), 2.5);
        assert_eq!((s.stage2_bytes, s.over_period, s.totals), (404, 2, t));
        assert_eq!((s.mean_ms, s.max_ms), (2.5, 4.0));
    }

    #[test]
    fn quantiles_and_csv_shape() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.5), 50.0);
        assert_eq!(quantile(&v, 0.99), 99.0);
        assert_eq!(quantile(&v, 1.0), 100.0);
        let f = FrameMetrics {
            mode: "pre",
            frame_ms: 40.0,
            ..Default::default()
        };
        let csv = to_csv(&[f.clone(), f]);
        let cols = CSV_HEADER.split(',').count();
        assert_eq!(cols, FrameMetrics::COLUMNS.len());
        assert!(csv.lines().all(|l| l.split(',').count() == cols));
        let s = summarize(
            &[FrameMetrics {
                frame_ms: 40.0,
                ..Default::default()
            }],
            33.3,
        );
        assert_eq!(s.over_period, 1);
    }

    #[test]
    fn the_recorder_summarises_as_the_frames_do() {
        let frames: Vec<FrameMetrics> = (0..50)
            .map(|i| FrameMetrics {
                frame: i,
                mode: "pre",
                frame_ms: f64::from(i % 7) * 10.0,
                loader: LoaderCounters {
                    stage2_bytes: u64::from(i) * 100,
                    ..Default::default()
                },
                vdt_trees: i % 2,
                adapt: i,
                vdt_misses: i % 3,
                ..Default::default()
            })
            .collect();
        let s = summarize(&frames, 33.3);
        assert_eq!(s.frames, 50);
        assert_eq!(s.stage2_bytes, (0..50).map(|i| i * 100).sum::<u64>());
        assert_eq!(s.vdt_frames, 25);
        assert_eq!(s.max_ms, 60.0);
    }
}
