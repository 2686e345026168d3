//! Shared plumbing of the workspace's programs: the error report, and the
//! one validated parameter layer every binary parses its numbers and sizes
//! through (ranges for every number; sizes capped by what the machine
//! allows); and what the `engine` library leaves to programs because it is
//! I/O or process policy rather than data and algorithms:
//! - [`outfile`]: the output-file policy of every writer (regular or new
//!   files only, never an input, atomic, cleaned up on a signal);
//! - [`png`]: images as PNG files;
//! - [`disk`]: a scene file behind a disk model (page cache dropped or
//!   warmed, precise sleeps);
//! - [`scene_handle`], [`remote`] and [`disk_cache`]: a scene opened once,
//!   from a file, a web server or object storage, through a local cache;
//! - [`paths`]: the generated camera paths; [`report`]: the per-frame CSV and
//!   the summary tables.

pub mod disk;
#[cfg(feature = "remote")]
pub mod disk_cache;
pub mod outfile;
pub mod paths;
pub mod png;
#[cfg(feature = "remote")]
pub mod read_ahead;
#[cfg(feature = "remote")]
pub mod remote;
pub mod report;
pub mod scene_handle;

pub use scene_handle::SceneHandle;

use engine::section::Section;
use std::fmt::Display;
use std::process::ExitCode;
use std::str::FromStr;

/// Sets up logging to stderr (warnings of the builder and the I/O thread),
/// remembers every file the program reads as one it may not write
/// ([`engine::infile::track_inputs`]), runs `body`, and turns an error into one message ([`report`]) and exit
/// code 2. A run that logged an error (a screenshot that could not be
/// written, a CSV that failed) but went on to the end exits with 1, never
/// 0. Output piped into a reader that stops early (`| head`) ends the
/// program quietly with exit code 141, as SIGPIPE would, instead of a panic
/// message.
pub fn main_with(body: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    // A command never writes a file it read (engine::infile).
    engine::infile::track_inputs();
    use tracing_subscriber::Layer as _;
    use tracing_subscriber::layer::SubscriberExt as _;
    // Set directly, not with `SubscriberInitExt::init`: that also routes
    // the `log` crate's records (wgpu's, winit's: thousands) here whenever
    // some dependency turns on tracing-subscriber's `tracing-log` feature,
    // as a workspace build's feature unification can.
    let subscriber = tracing_subscriber::registry()
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_target(false)
                .without_time()
                .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
                // Information, warnings and errors: not the HTTP stack's
                // debug and trace events (object_store, reqwest, hyper).
                .with_filter(tracing_subscriber::filter::LevelFilter::INFO),
        )
        .with(ErrorCount);
    let _ = tracing::subscriber::set_global_default(subscriber);
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !is_broken_pipe(info.payload()) {
            hook(info);
        }
    }));
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(body)) {
        Ok(Ok(())) => match logged_errors() {
            0 => ExitCode::SUCCESS,
            n => {
                eprintln!("error: {n} error(s) logged above");
                ExitCode::from(1)
            }
        },
        Ok(Err(e)) => {
            eprintln!("error: {}", report(&e));
            ExitCode::from(2)
        }
        Err(p) if is_broken_pipe(p.as_ref()) => ExitCode::from(141),
        Err(p) => std::panic::resume_unwind(p),
    }
}

static LOGGED_ERRORS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Errors logged (`tracing::error!`) so far in this process.
pub fn logged_errors() -> usize {
    LOGGED_ERRORS.load(std::sync::atomic::Ordering::Relaxed)
}

/// Counts the error events, so that a run that logged one fails.
struct ErrorCount;

impl<S: tracing::Subscriber> tracing_subscriber::Layer<S> for ErrorCount {
    fn on_event(&self, event: &tracing::Event<'_>, _: tracing_subscriber::layer::Context<'_, S>) {
        if *event.metadata().level() == tracing::Level::ERROR {
            LOGGED_ERRORS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// An error and its causes on one line, `outer: inner: …`, each cause
/// printed once: a cause whose text its outer message already contains
/// (`"I/O error: No space left"` around `"No space left"`) is left out.
pub fn report(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if parts.iter().any(|p| p.contains(&text)) {
            continue;
        }
        parts.push(text);
    }
    parts.join(": ")
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

/// A clap value parser for numbers in `lo..=hi` (NaN and infinities are
/// outside every range).
pub fn in_range<T>(lo: T, hi: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync + 'static,
{
    move |s: &str| {
        let v: T = s
            .trim()
            .parse()
            .map_err(|_| format!("{s:?} is not a number"))?;
        if lo <= v && v <= hi {
            Ok(v)
        } else {
            Err(format!("{s} is outside {lo}..={hi}"))
        }
    }
}

/// A clap value parser for `0` (off) or a number in `lo..=hi`.
pub fn zero_or_in<T>(lo: T, hi: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync
where
    T: FromStr + PartialOrd + Display + Copy + Default + Send + Sync + 'static,
{
    let inner = in_range(lo, hi);
    move |s: &str| match s.trim().parse::<T>() {
        Ok(v) if v == T::default() => Ok(v),
        _ => inner(s).map_err(|e| format!("{e} (or 0: off)")),
    }
}

/// Parses a memory footprint for `--budget`: see [`parse_size`].
pub fn parse_budget(s: &str, data_bytes: u64) -> anyhow::Result<u64> {
    parse_size("--budget", s, data_bytes, 100.0)
}

/// Parses the size given to `option`: bytes (with B/KB/MB/GB/KiB/MiB/GiB)
/// or a percentage of `data_bytes` up to `max_percent` (`2.5%`). Sizes are
/// positive and at most the machine's memory (they are memory footprints);
/// errors name `option`.
pub fn parse_size(option: &str, s: &str, data_bytes: u64, max_percent: f64) -> anyhow::Result<u64> {
    use anyhow::bail;
    let t = s.trim();
    let bytes = if let Some(p) = t.strip_suffix('%') {
        let v: f64 = match p.trim().parse() {
            Ok(v) => v,
            Err(_) => bail!("{option} {s:?}: expected e.g. 25MiB or 2.5%"),
        };
        if !(v > 0.0 && v <= max_percent) {
            bail!("{option} {s:?}: a percentage must be in (0, {max_percent}]");
        }
        data_bytes as f64 * v / 100.0
    } else {
        bytes_of(option, t)?
    };
    within_memory(option, s, bytes)
}

/// `bytes` (of the size `s` given to `option`), unless more than this
/// machine's memory.
fn within_memory(option: &str, s: &str, bytes: f64) -> anyhow::Result<u64> {
    let limit = engine::limits::memory_total();
    if bytes > limit as f64 {
        anyhow::bail!(
            "{option} {s:?} is more than this machine's memory ({})",
            engine::limits::human(limit)
        );
    }
    Ok(bytes as u64)
}

/// A size on disk given to `option` (`--disk-cache-size`): bytes with
/// B/KB/MB/GB/TB/KiB/MiB/GiB/TiB, positive, not bounded by memory.
pub fn parse_disk_size(option: &str, s: &str) -> anyhow::Result<u64> {
    let v = bytes_of(option, s.trim())?;
    if v < 1.0 || v > (1u64 << 60) as f64 {
        anyhow::bail!("{option} {s:?}: from 1 B to 1 EiB");
    }
    Ok(v as u64)
}

fn bytes_of(option: &str, t: &str) -> anyhow::Result<f64> {
    let (num, mult) = [
        ("TiB", 1u64 << 40),
        ("GiB", 1 << 30),
        ("MiB", 1 << 20),
        ("KiB", 1 << 10),
        ("TB", 1_000_000_000_000),
        ("GB", 1_000_000_000),
        ("MB", 1_000_000),
        ("KB", 1000),
        ("B", 1),
    ]
    .iter()
    .find_map(|(suf, m)| t.strip_suffix(suf).map(|n| (n.trim(), *m)))
    .unwrap_or((t, 1));
    let v: f64 = match num.parse() {
        Ok(v) => v,
        Err(_) => anyhow::bail!("{option} {t:?}: expected e.g. 25MiB or 2.5%"),
    };
    if !(v.is_finite() && v > 0.0) {
        anyhow::bail!("{option} {t:?} must be positive");
    }
    Ok(v * mult as f64)
}

/// [`parse_size`], or 0 for `0` / `off`.
pub fn size_or_off(option: &str, s: &str, data_bytes: u64) -> anyhow::Result<u64> {
    match s.trim() {
        "0" | "off" => Ok(0),
        g => parse_size(option, g, data_bytes, 100.0),
    }
}

/// A `--budget` as given, parsed once: `auto`, a size, or a share of the
/// scene's rep data; [`BudgetArg::bytes`] resolves it once the scene is open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BudgetArg {
    Auto,
    Bytes(u64),
    /// A percentage in (0, 100].
    Percent(f64),
}

impl BudgetArg {
    /// Parses `auto`, a size (`64MiB`) or a percentage (`2.5%`).
    pub fn parse(s: &str) -> anyhow::Result<Self> {
        let t = s.trim();
        if t == "auto" {
            return Ok(Self::Auto);
        }
        if let Some(p) = t.strip_suffix('%') {
            return match p.trim().parse::<f64>() {
                Ok(v) if v > 0.0 && v <= 100.0 => Ok(Self::Percent(v)),
                Ok(_) => anyhow::bail!("--budget {s:?}: a percentage must be in (0, 100]"),
                Err(_) => anyhow::bail!("--budget {s:?}: expected e.g. 25MiB or 2.5%"),
            };
        }
        // A size: checked against the machine's memory now.
        parse_budget(t, 0).map(Self::Bytes)
    }

    /// The budget in bytes for the scene of `skeleton`.
    pub fn bytes(&self, skeleton: &engine::Skeleton) -> anyhow::Result<u64> {
        Ok(match *self {
            Self::Auto => auto_budget(skeleton),
            Self::Bytes(b) => b,
            Self::Percent(p) => {
                let bytes = skeleton.in_core_bytes() as f64 * p / 100.0;
                within_memory("--budget", &format!("{p}%"), bytes)?.max(1)
            }
        })
    }
}

/// The most `--budget auto` gives: 1 GiB (further capped at a quarter of
/// the machine's memory).
pub const AUTO_BUDGET_CAP: u64 = 1 << 30;

/// `--budget auto` for a scene: all of it in core
/// ([`engine::Skeleton::in_core_bytes`]) up to [`AUTO_BUDGET_CAP`] and a
/// quarter of this machine's memory, and never less than what drawing every
/// rep as itself needs ([`engine::Skeleton::full_detail_bytes`]: the root's
/// coarsest rep, which stays resident, beside the largest rep while it
/// loads), so that it can always be shown and refined.
pub fn auto_budget(skeleton: &engine::Skeleton) -> u64 {
    let cap = AUTO_BUDGET_CAP.min(engine::limits::memory_total() / 4);
    skeleton
        .in_core_bytes()
        .min(cap)
        .max(skeleton.full_detail_bytes())
        .max(1)
}

/// `--section` and `--section-box`, as `hlod-view` and `hlod-bench` take
/// them (`#[command(flatten)]`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SectionArgs {
    /// A section plane X,Y,Z,DX,DY,DZ (repeatable; scene coordinates, as in
    /// camera paths): what lies on the side the direction points to is cut
    /// away, leaves every front and is not fetched.
    #[arg(long, value_name = "X,Y,Z,DX,DY,DZ", allow_hyphen_values = true)]
    pub section: Vec<String>,
    /// A section box X0,Y0,Z0,X1,Y1,Z1: only what lies inside it stays.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    pub section_box: Option<String>,
}

impl SectionArgs {
    /// The section the options give ([`parse_section`]).
    pub fn section(&self) -> anyhow::Result<Section> {
        parse_section(&self.section, self.section_box.as_deref())
    }
}

/// The section of `--section X,Y,Z,DX,DY,DZ` (repeatable: a plane through
/// the point removing the side the direction points to, as BCF's clipping
/// planes) and `--section-box X0,Y0,Z0,X1,Y1,Z1` (only its inside stays),
/// in scene coordinates (those of camera paths); errors name the option.
pub fn parse_section(planes: &[String], section_box: Option<&str>) -> anyhow::Result<Section> {
    use anyhow::Context;
    let six = |option: &str, s: &str| -> anyhow::Result<[f32; 6]> {
        let v: Vec<f32> = s
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f32>| v.len() == 6 && v.iter().all(|x| x.is_finite()))
            .with_context(|| format!("{option} {s:?}: expected six numbers, e.g. 0,3,0,0,1,0"))?;
        Ok([v[0], v[1], v[2], v[3], v[4], v[5]])
    };
    let mut all = Vec::new();
    if let Some(b) = section_box {
        let v = six("--section-box", b)?;
        let (lo, hi) = (
            glam::Vec3::new(v[0], v[1], v[2]),
            glam::Vec3::new(v[3], v[4], v[5]),
        );
        let bx = Section::boxed(lo, hi).with_context(|| format!("--section-box {b:?}"))?;
        all.extend(bx.as_location_direction());
    }
    for p in planes {
        let v = six("--section", p)?;
        all.push((
            glam::Vec3::new(v[0], v[1], v[2]),
            glam::Vec3::new(v[3], v[4], v[5]),
        ));
    }
    Section::from_planes(&all).context("--section / --section-box")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_is_parsed_once_and_resolved_for_each_scene() {
        assert_eq!(BudgetArg::parse(" auto ").unwrap(), BudgetArg::Auto);
        assert_eq!(
            BudgetArg::parse("64MiB").unwrap(),
            BudgetArg::Bytes(64 << 20)
        );
        assert_eq!(BudgetArg::parse("2.5%").unwrap(), BudgetArg::Percent(2.5));
        for bad in ["", "x", "0%", "101%", "-1MiB", "1e30GiB", "NaN%"] {
            assert!(BudgetArg::parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn sections_parse_and_name_their_option() {
        let s = parse_section(&["0,3,0, 0,1,0".into()], Some("-1,-1,-1,1,1,1")).unwrap();
        assert_eq!(s.planes().len(), 7);
        assert!(s.keeps(glam::Vec3::ZERO));
        assert!(!s.keeps(glam::Vec3::new(0.0, 0.0, 1.5)));
        assert!(parse_section(&[], None).unwrap().is_empty());
        let e = |p: &[&str], b| {
            let p: Vec<String> = p.iter().map(|s| s.to_string()).collect();
            format!("{:#}", parse_section(&p, b).unwrap_err())
        };
        assert!(e(&["1,2,3"], None).contains("--section \"1,2,3\""));
        assert!(e(&["0,0,0,0,0,0"], None).contains("zero vector"));
        assert!(e(&[], Some("1,1,1,0,0,0")).contains("--section-box"));
        assert!(e(&["0,0,0,NaN,1,0"], None).contains("six numbers"));
        assert!(e(&["0,0,0,0,1,0"; 3], Some("0,0,0,1,1,1")).contains("at most 8"));
    }

    #[test]
    fn ranges_reject_nonsense() {
        let fps = zero_or_in(1.0f32, 1000.0);
        assert_eq!(fps("0").unwrap(), 0.0);
        assert_eq!(fps("30").unwrap(), 30.0);
        for bad in ["1e-9", "NaN", "inf", "-5", "1e30", "x"] {
            assert!(fps(bad).is_err(), "{bad}");
        }
        let frames = in_range(1usize, 1_000_000);
        assert!(frames("1000000000").is_err());
        assert_eq!(frames("5").unwrap(), 5);
    }

    #[test]
    fn sizes_name_their_option_and_stay_within_memory() {
        assert_eq!(parse_size("--x", "2KiB", 0, 100.0).unwrap(), 2048);
        assert_eq!(parse_budget("50%", 1000).unwrap(), 500);
        let e = parse_size("--vdt-pool", "0", 1000, 100.0).unwrap_err();
        assert!(e.to_string().contains("--vdt-pool"), "{e}");
        assert!(parse_budget("1e30GiB", 1000).is_err());
        assert!(parse_budget("101%", 1000).is_err());
        assert_eq!(size_or_off("--sweep", "off", 1).unwrap(), 0);
    }

    #[test]
    fn a_cause_already_in_its_context_is_printed_once() {
        let io = std::io::Error::from(std::io::ErrorKind::StorageFull);
        let inner = io.to_string();
        let e = anyhow::Error::new(io).context(format!("I/O error: {inner}"));
        let e = e.context("writing out.hlod");
        let r = report(&e);
        assert_eq!(r.matches(&inner).count(), 1, "{r}");
        assert!(r.starts_with("writing out.hlod: I/O error"), "{r}");
    }
}
