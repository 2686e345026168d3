//! Shared plumbing of the workspace's command-line programs.

use std::process::ExitCode;

/// Sets up logging to stderr (warnings of the builder and the I/O thread),
/// runs `body`, and turns an error into a message and exit code 2. Output
/// piped into a reader that stops early (`| head`) ends the program quietly
/// with exit code 141, as SIGPIPE would, instead of a panic message.
pub fn main_with(body: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !is_broken_pipe(info.payload()) {
            hook(info);
        }
    }));
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(body)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
        Err(p) if is_broken_pipe(p.as_ref()) => ExitCode::from(141),
        Err(p) => std::panic::resume_unwind(p),
    }
}

/// Whether a panic is `println!` failing on a closed pipe.
fn is_broken_pipe(payload: &(dyn std::any::Any + Send)) -> bool {
    let msg = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("");
    msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe")
}

/// Parses a memory footprint: bytes (with B/KB/MB/GB/KiB/MiB/GiB) or a
/// percentage of `data_bytes` (`2.5%`).
pub fn parse_budget(s: &str, data_bytes: u64) -> anyhow::Result<u64> {
    parse_budget_upto(s, data_bytes, 100.0)
}

/// [`parse_budget`] allowing percentages up to `max_percent` (a footprint
/// larger than the data, to show a case where everything fits).
pub fn parse_budget_upto(s: &str, data_bytes: u64, max_percent: f64) -> anyhow::Result<u64> {
    use anyhow::{Context, bail};
    let t = s.trim();
    if let Some(p) = t.strip_suffix('%') {
        let v: f64 = p
            .trim()
            .parse()
            .with_context(|| format!("--budget {s:?}"))?;
        if !(v > 0.0 && v <= max_percent) {
            bail!("--budget {s:?}: a percentage must be in (0, {max_percent}]");
        }
        return Ok((data_bytes as f64 * v / 100.0) as u64);
    }
    let (num, mult) = [
        ("GiB", 1u64 << 30),
        ("MiB", 1 << 20),
        ("KiB", 1 << 10),
        ("GB", 1_000_000_000),
        ("MB", 1_000_000),
        ("KB", 1000),
        ("B", 1),
    ]
    .iter()
    .find_map(|(suf, m)| t.strip_suffix(suf).map(|n| (n.trim(), *m)))
    .unwrap_or((t, 1));
    let v: f64 = num
        .parse()
        .with_context(|| format!("--budget {s:?}: expected e.g. 25MiB or 2.5%"))?;
    if !(v.is_finite() && v > 0.0) {
        bail!("--budget {s:?} must be positive");
    }
    Ok((v * mult as f64) as u64)
}
