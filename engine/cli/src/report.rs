//! A run's report: the per-frame CSV written as the frames come, and the
//! Markdown tables of its summaries.

use engine::metrics::{CSV_HEADER, FrameMetrics, Summary};
use std::fmt::Write as _;

/// A run's per-frame CSV written as the frames come (header first), under
/// the output-file policy: the file appears complete at [`finish`](Self::finish).
#[derive(Debug)]
pub struct CsvStream {
    out: crate::outfile::OutputFile,
    w: std::io::BufWriter<std::fs::File>,
}

impl CsvStream {
    /// Starts the per-frame CSV ([`CSV_HEADER`]) at `path`.
    pub fn create(path: &std::path::Path) -> std::io::Result<Self> {
        Self::with_header(path, CSV_HEADER)
    }

    /// Starts a CSV with another `header` (a line without its newline).
    pub fn with_header(path: &std::path::Path, header: &str) -> std::io::Result<Self> {
        let out = crate::outfile::OutputFile::create(path, &[])?;
        let w = std::io::BufWriter::with_capacity(1 << 16, out.file().try_clone()?);
        let mut s = Self { out, w };
        s.line(header)?;
        Ok(s)
    }

    /// Writes one frame's row.
    pub fn push(&mut self, f: &FrameMetrics) -> std::io::Result<()> {
        self.line(&f.csv_row())
    }

    /// Writes one line (without its newline).
    pub fn line(&mut self, row: &str) -> std::io::Result<()> {
        use std::io::Write;
        writeln!(self.w, "{row}")
    }

    /// Flushes and puts the file in place.
    pub fn finish(mut self) -> std::io::Result<()> {
        use std::io::Write;
        self.w.flush()?;
        drop(self.w);
        self.out.commit()?;
        Ok(())
    }
}

/// The budget column: in-core runs hold every rep, whatever footprint the
/// out-of-core runs beside them were given.
pub fn budget_cell(r: &Summary) -> String {
    if r.mode == "incore" {
        "— (all)".to_string()
    } else {
        format!("{:.2}", r.budget_bytes as f64 / 1048576.0)
    }
}

/// A Markdown table of the summaries' view-dependence-tree figures.
pub fn vdt_table(rows: &[Summary]) -> String {
    let mut s = String::from(
        "| mode | budget MiB | frames with trees | Adapt | tree tris | Miss % | refine ms | meta-nodes read | max tree store MiB |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.0} | {:.2} | {:.3} | {} | {:.2} |",
            r.mode,
            budget_cell(r),
            r.vdt_frames,
            r.mean_adapt,
            r.mean_vdt_tris,
            r.vdt_miss_pct,
            r.mean_vdt_ms,
            r.metas_loaded,
            mib(r.max_vdt_bytes)
        );
    }
    s
}

/// A Markdown table of summaries.
pub fn summary_table(rows: &[Summary]) -> String {
    let mut s = String::from(
        "| mode | frames | mean ms | median ms | p99 ms | max ms | over period | Stage II MiB | prefetch MiB | max resident MiB | budget MiB | substituted | front ms |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {:.2} | {:.2} | {:.2} | {} | {} | {:.3} |",
            r.mode,
            r.frames,
            r.mean_ms,
            r.median_ms,
            r.p99_ms,
            r.max_ms,
            r.over_period,
            mib(r.stage2_bytes),
            mib(r.prefetch_bytes),
            mib(r.max_resident_bytes),
            budget_cell(r),
            r.substituted,
            r.mean_front_ms
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use engine::metrics::to_csv;

    #[test]
    fn the_csv_streams_and_appears_only_when_finished() {
        let frames: Vec<FrameMetrics> = (0..50)
            .map(|i| FrameMetrics {
                frame: i,
                mode: "pre",
                frame_ms: f64::from(i % 7) * 10.0,
                ..Default::default()
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("pre.csv");
        let mut c = CsvStream::create(&p).unwrap();
        for f in &frames {
            c.push(f).unwrap();
        }
        assert!(!p.exists(), "appears only when finished");
        c.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), to_csv(&frames));
    }
}
