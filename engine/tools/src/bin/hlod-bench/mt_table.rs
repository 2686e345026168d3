//! The Multi-Triangulation figures of a run (from the frame totals).

use std::fmt::Write as _;

use engine::metrics::Summary;

/// A Markdown table of the summaries' MT figures: per frame that drew a
/// paged rep, the cut's triangles, refinements + coarsenings (Adapt), Miss %
/// (misses / (Adapt + misses), as the trees' table) and the cut's time
/// (reads included); the reads, partitions and bytes read over the run; the
/// most nodes cached.
pub fn mt_table(rows: &[Summary]) -> String {
    let mut s = String::from(
        "| mode | budget MiB | frames with MTs | MT tris | Adapt | Miss % | cut ms | reads | partitions read | MiB read | max nodes cached | max store MiB |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    for r in rows {
        let t = &r.totals;
        let k = r.vdt_frames.max(1) as f64;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.0} | {:.1} | {:.2} | {:.3} | {} | {} | {:.2} | {} | {:.2} |",
            r.mode,
            engine_cli::report::budget_cell(r),
            r.vdt_frames,
            t.mt_tris as f64 / k,
            t.mt_adapt as f64 / k,
            100.0 * t.mt_misses as f64 / (t.mt_adapt + t.mt_misses).max(1) as f64,
            r.mean_vdt_ms,
            t.mt_reads,
            t.mt_partitions,
            mib(t.mt_read_bytes),
            t.mt_nodes,
            mib(r.max_vdt_bytes)
        );
    }
    s
}
