//! `hlod-view`: the interactive walkthrough viewer.
//!
//! Architecture: a winit window whose surface the wgpu scene renderer and the
//! egui painter share (`gfx`); an open scene is a `session` (skeleton, the
//! out-of-core walkthrough P_R/P_I, the renderer sized to the budget) that
//! restarts when the mode, budget, ε or prefetch parameters change; `controls`
//! turns keys and mouse into a camera pose (plain Rust, tested); `ui` is the
//! overlay (metrics, live plots, settings, actions); `app` ties them together
//! in winit's event loop, one frame per redraw: camera → front and loads →
//! scene → overlay → screenshot → present. Path playback and recording use
//! the `paths/` format; playback writes the same per-frame CSV as `hlod-bench`.
//! A scene that fails to open or to read shows its error in the overlay and
//! the log; the viewer stays usable.

mod app;
mod build;
mod controls;
mod gfx;
mod overlay;
mod picking;
mod session;
mod tree_panel;
mod ui;
mod viewpoint;

use engine_cli::in_range;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::Parser;

/// Command line.
#[derive(Parser, Debug, Clone)]
#[command(
    name = "hlod-view",
    version,
    about = "Walk through an out-of-core HLOD scene"
)]
pub struct Args {
    /// Scene file (`hlod-build build` output) or its URL (http://, https://,
    /// s3://BUCKET/KEY; S3 credentials from the AWS_* variables), or a glTF
    /// model (`.glb`, `.gltf`) which is built into the cache first (reused
    /// while the model and the build parameters are unchanged); can also be
    /// opened from the overlay.
    pub scene: Option<PathBuf>,
    /// Build cache directory for models opened directly (default:
    /// $HLOD_CACHE_DIR, else $XDG_CACHE_HOME/hlod, else ~/.cache/hlod, else
    /// a private hlod-cache-UID in the temporary folder); it must be yours
    /// and writable by no one else.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// A folder a model's buffer and image `uri`s may name besides the
    /// model's own (repeatable); a `uri` that leaves both is refused.
    #[arg(long, value_name = "DIR")]
    pub allow_dir: Vec<PathBuf>,
    /// incore, nopre or pre.
    #[arg(long, default_value = "pre")]
    pub mode: String,
    /// Memory footprint: `auto` (all the rep data up to 1 GiB and a quarter
    /// of this machine's memory, never below what the scene's minimal front
    /// needs), bytes (KiB/MiB/GiB) or a percentage of the rep data.
    #[arg(long, default_value = "auto")]
    pub budget: String,
    /// Error tolerance ε in pixels.
    #[arg(long, default_value_t = 2.0, value_parser = in_range(0.01f32, 10_000.0))]
    pub tolerance: f32,
    /// Stall deadline in ms (0: wait for every missing rep, the paper's
    /// protocol): what Stage II cannot read in time is drawn as its nearest
    /// resident ancestor and read after the frame.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 60_000.0))]
    pub stall_deadline: f32,
    /// Smooth LOD switches: a rep that replaces another dissolves into it
    /// over this many seconds (screen-door dither; 0: off).
    #[arg(long, default_value_t = 0.25, value_parser = in_range(0.0f32, 10.0))]
    pub fade: f32,
    /// file, hdd, ssd, nvme or LATENCY_MS:MB_PER_S.
    #[arg(long, default_value = "file")]
    pub disk: String,
    /// object, lod, kind or substituted.
    #[arg(long, default_value = "object")]
    pub colouring: String,
    /// Play this camera path (one pose per frame).
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Record the camera path to this file (written when recording stops or at exit).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Per-frame metrics CSV of the run (as `hlod-bench` writes), plus `*-loop.csv` with the whole loop time.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Quit after this many frames.
    #[arg(long)]
    pub exit_after: Option<u64>,
    /// Quit at the first complete frame (nothing missing, nothing
    /// substituted, nothing still loading), after `--pick`; prints the time
    /// to it from the start.
    #[arg(long)]
    pub exit_when_complete: bool,
    /// Click pixel X,Y (from the top left) once the view is complete, as a
    /// left click would: the element there is selected and printed.
    #[arg(long, value_parser = parse_pixel)]
    pub pick: Option<(f32, f32)>,
    #[command(flatten)]
    pub cut: engine_cli::SectionArgs,
    /// Open at a BCF 2.1 viewpoint (`.bcfv`): its camera and clipping planes
    /// (BCF's Z-up project coordinates; the scene's origin is taken out).
    #[arg(long, value_name = "FILE.bcfv")]
    pub viewpoint: Option<PathBuf>,
    /// Write the view (camera, section, selected element) as a BCF 2.1
    /// viewpoint at exit; key V writes `hlod-view-N.bcfv` at any time.
    #[arg(long, value_name = "FILE.bcfv")]
    pub save_viewpoint: Option<PathBuf>,
    /// Measure between pixels X0,Y0 and X1,Y1 once the view is complete, as
    /// two clicks in measuring mode (key M) would: each point snaps to the
    /// picked triangle's corner or edge within 8 pixels; the distance is
    /// printed in metres and drawn.
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = parse_two_pixels)]
    pub measure: Option<[f32; 4]>,
    /// Find the elements whose name, mesh name or `extras` (IFC type,
    /// GlobalId) hold this text once the scene opens, select the first and
    /// fly to it (the overlay's Find does the same).
    #[arg(long, value_name = "TEXT")]
    pub find: Option<String>,
    /// Start in walk mode where the view opens (after --viewpoint or
    /// --find): eye at 1.6 m, gravity, walls and stairs from the scene's walk
    /// section; key G toggles walk and fly.
    #[arg(long)]
    pub walk: bool,
    /// Open the main panel on the model tree (key T): site, building,
    /// storey, IFC type and element, or the glTF node hierarchy.
    #[arg(long)]
    pub tree: bool,
    /// Once the scene opens, show only these elements: a group of the
    /// model tree by its name (a storey, a type, a glTF node), else every
    /// element whose name, type or GlobalId holds the text (repeatable;
    /// applied before --xray and --hide).
    #[arg(long, value_name = "GROUP|TEXT")]
    pub isolate: Vec<String>,
    /// X-ray these elements (a tree group or a text, as --isolate): drawn
    /// translucent, hiding nothing behind them.
    #[arg(long, value_name = "GROUP|TEXT")]
    pub xray: Vec<String>,
    /// Hide these elements (a tree group or a text, as --isolate): they
    /// leave the front and are not fetched.
    #[arg(long, value_name = "GROUP|TEXT")]
    pub hide: Vec<String>,
    /// Save the last frame (with the overlay) as PNG at exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    #[arg(long, default_value_t = 1280, value_parser = in_range(16u32, 8192))]
    pub width: u32,
    #[arg(long, default_value_t = 720, value_parser = in_range(16u32, 8192))]
    pub height: u32,
    /// Wait for vertical sync (default: present as fast as possible).
    #[arg(long)]
    pub vsync: bool,
    /// Hide the overlay.
    #[arg(long)]
    pub no_overlay: bool,
    /// Overlay refreshes per second (it is cached in between; input refreshes it at once).
    #[arg(long, default_value_t = 2.0, value_parser = in_range(0.1f64, 1000.0))]
    pub overlay_hz: f64,
    /// For a scene opened by URL: keep the bytes fetched in this folder, so
    /// that the next visit of the same version reads them from disk.
    #[arg(long, value_name = "DIR")]
    pub disk_cache: Option<PathBuf>,
    /// The disk cache's bound (B, KB, MB, GB, TB, KiB, MiB, GiB, TiB).
    #[arg(long, default_value = "4GiB", value_parser = disk_size)]
    pub disk_cache_size: u64,
}

fn disk_size(s: &str) -> Result<u64, String> {
    engine_cli::parse_disk_size("--disk-cache-size", s).map_err(|e| e.to_string())
}

impl Args {
    /// The disk cache for scenes opened by URL, if asked for.
    pub fn disk_cache(&self) -> Option<engine_cli::scene_handle::DiskCacheSpec> {
        let dir = self.disk_cache.clone()?;
        let max_bytes = self.disk_cache_size;
        Some(engine_cli::scene_handle::DiskCacheSpec { dir, max_bytes })
    }

    /// The outputs named on the command line, checked before the window opens
    /// (a refused one is an error now, not after the walk): none may be the
    /// scene, the model or the path file, a link, or a device. Each is checked
    /// again when it is written (by then the model's buffers have been read
    /// and are refused too).
    pub fn check_outputs(&self) -> anyhow::Result<()> {
        let inputs: Vec<&std::path::Path> = self
            .scene
            .iter()
            .chain(&self.path)
            .chain(&self.viewpoint)
            .map(PathBuf::as_path)
            .collect();
        for (flag, out) in [
            ("--csv", &self.csv),
            ("--screenshot", &self.screenshot),
            ("--record", &self.record),
            ("--save-viewpoint", &self.save_viewpoint),
        ] {
            if let Some(p) = out {
                engine_cli::outfile::check_output(p, &inputs).with_context(|| flag.to_string())?;
            }
        }
        Ok(())
    }
}

fn parse_pixel(s: &str) -> Result<(f32, f32), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: expected X,Y"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| (0.0..=8192.0).contains(v))
            .ok_or_else(|| format!("{s:?}: coordinates must be pixels in 0..=8192"))
    };
    Ok((p(x)?, p(y)?))
}

fn parse_two_pixels(s: &str) -> Result<[f32; 4], String> {
    let v: Vec<&str> = s.split(',').collect();
    if v.len() != 4 {
        return Err(format!("{s:?}: expected X0,Y0,X1,Y1"));
    }
    let (a, b) = (
        parse_pixel(&v[..2].join(","))?,
        parse_pixel(&v[2..].join(","))?,
    );
    Ok([a.0, a.1, b.0, b.1])
}

fn main() -> ExitCode {
    engine_cli::main_with(|| app::run(Args::parse()))
}
