//! `hlod-bench`'s command line.

use std::path::PathBuf;

use clap::Parser;
use engine_cli::{in_range, zero_or_in};

#[derive(Parser, Debug)]
#[command(
    name = "hlod-bench",
    version,
    about = "Walk a camera path through a scene in-core and out-of-core"
)]
pub struct Args {
    /// Scene file, or its URL (http://, https://, s3://BUCKET/KEY; S3
    /// credentials from the AWS_* variables).
    pub scene: PathBuf,
    /// Camera path file (default: the scene's generated fly-through).
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Generated path when no --path: flythrough, approach, orbit,
    /// approach-orbit, random (a hostile random walk with jumps, for soak
    /// runs; see --seed), interior or walk (a walk at eye height that a
    /// walker walks on the scene's walk section, from a place indoors to
    /// each storey in turn: never through geometry, every storey it reports
    /// reached; see --seed) or rooms (the earlier interior walk, storeys and
    /// rooms found from the geometry, which may pass walls and jump storeys;
    /// what interior falls back to on a scene without a walk section).
    #[arg(long, default_value = "flythrough")]
    pub path_kind: String,
    /// Seed of the random path.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Frames of a generated path.
    #[arg(long, default_value_t = 600, value_parser = in_range(1usize, 1_000_000))]
    pub frames: usize,
    #[arg(long, default_value = "incore,nopre,pre")]
    pub modes: String,
    /// Memory footprint: bytes, with KiB/MiB/GiB, or a percentage of the rep data (e.g. 2.5%).
    #[arg(long, default_value = "2.5%")]
    pub budget: String,
    /// A sweep over several footprints (comma-separated, like --budget); replaces --budget.
    #[arg(long)]
    pub budgets: Option<String>,
    /// Error tolerance ε in pixels.
    #[arg(long, default_value_t = 2.0, value_parser = in_range(0.01f32, 10_000.0))]
    pub tolerance: f32,
    /// none (no rasterisation) or wgpu (a GPU, or lavapipe without one).
    #[arg(long, default_value = "none")]
    pub renderer: String,
    /// Debug colouring of the wgpu renderer: object, lod, kind or substituted.
    #[arg(long, default_value = "object")]
    pub colouring: String,
    /// With wgpu: read back every N-th frame and compare it with the in-core
    /// frame (PSNR); 0 = off.
    #[arg(long, default_value_t = 30, value_parser = in_range(0u32, 1_000_000))]
    pub psnr_every: u32,
    /// With wgpu: save the sampled frames as PNG under OUT/frames.
    #[arg(long)]
    pub save_frames: bool,
    /// Modelled speed of the none renderer in triangles per second (0: free).
    #[arg(long, default_value_t = 0.0, value_parser = zero_or_in(1e3, 1e13))]
    pub render_rate: f64,
    /// file (the real file, page cache dropped), hdd, ssd, nvme, or LATENCY_MS:MB_PER_S.
    #[arg(long, default_value = "file")]
    pub disk: String,
    /// For a scene given by URL: keep the bytes fetched in this folder, so
    /// that the next run on the same version reads them from disk.
    #[arg(long, value_name = "DIR")]
    pub disk_cache: Option<PathBuf>,
    /// The disk cache's bound (B, KB, MB, GB, TB, KiB, MiB, GiB, TiB).
    #[arg(long, default_value = "4GiB")]
    pub disk_cache_size: String,
    /// For a scene given by URL: requests in flight at once for the reads
    /// P_I does next (1: one at a time).
    #[arg(long, default_value_t = engine_cli::scene_handle::DEFAULT_REQUESTS, value_parser = in_range(1usize, 256))]
    pub requests: usize,
    /// For a scene given by URL: the most bytes those requests may hold
    /// (taken out of the footprint; at most an eighth of P_I's share).
    #[arg(long, default_value = "4MiB")]
    pub read_ahead: String,
    /// Frame pacing (0: as fast as possible).
    #[arg(long, default_value_t = 30.0, value_parser = zero_or_in(1.0f32, 1000.0))]
    pub fps: f32,
    #[arg(long, default_value_t = 1280, value_parser = in_range(16u32, 8192))]
    pub width: u32,
    #[arg(long, default_value_t = 720, value_parser = in_range(16u32, 8192))]
    pub height: u32,
    /// Bins B of the prefetcher.
    #[arg(long, default_value_t = 16, value_parser = in_range(1usize, 4096))]
    pub bins: usize,
    /// δ in pixels (0: 4 ε).
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 100_000.0))]
    pub delta: f32,
    /// Base widening of F_I, degrees.
    #[arg(long, default_value_t = 30.0, value_parser = in_range(0.0f32, 180.0))]
    pub margin: f32,
    /// Widest F_I, degrees (90 or more: all around the eye).
    #[arg(long, default_value_t = 60.0, value_parser = in_range(0.0f32, 180.0))]
    pub max_margin: f32,
    /// Levels of PAR/CHD prefetched.
    #[arg(long, default_value_t = 1, value_parser = in_range(0u8, 16))]
    pub prefetch_depth: u8,
    /// Sweep: reps of F_I's front up to this size (bytes, KiB, MiB) are also
    /// read in file order, alternating with the bins; 0 = off.
    #[arg(long, default_value = "0")]
    pub sweep: String,
    /// Largest share of the budget for prefetched reps not yet drawn.
    #[arg(long, default_value_t = 0.6, value_parser = in_range(0.01f32, 1.0))]
    pub speculative_share: f32,
    /// Lookahead: P_I also prefetches the fronts of the positions the
    /// camera's motion reaches in this many frames (and a third of it); 0 = off.
    #[arg(long, default_value_t = 10, value_parser = in_range(0u32, 10_000))]
    pub lookahead: u32,
    /// F_I goes all around the eye whenever the all-around front takes at
    /// most this share of the reps' room (the budget less the pages'
    /// share); 0 = never.
    #[arg(long, default_value_t = 1.0, value_parser = in_range(0.0f32, 1000.0))]
    pub all_around: f32,
    /// Print what any fetching policy could do on this path (from the
    /// fronts alone: the first-time reps, the oracle's working set, the disk
    /// time of reading the path's reps in file order, demand fetching with
    /// optimal eviction), write it to OUT/bounds.md, and run nothing.
    #[arg(long)]
    pub bounds: bool,
    /// Start-up: frames rendered at the path's first pose before the path
    /// begins (P_I loads the first front and prefetches around it, as an
    /// in-core viewer loads everything before its first frame); they are
    /// reported as the start-up, not as path frames.
    #[arg(long, default_value_t = 0, value_parser = in_range(0usize, 1_000_000))]
    pub warmup: usize,
    /// Output directory for CSVs, the summary, plots and the path used.
    #[arg(long, default_value = "out/bench")]
    pub out: PathBuf,
    /// Place-holder bytes reserved per resident view-dependence tree (bytes
    /// or a percentage of the scene data), out of the footprint.
    #[arg(long, default_value = "4MiB")]
    pub vdt_pool: String,
    /// What a Multi-Triangulation's store keeps after a frame: p-c (the
    /// paper's caching), p-cc, p-nc or np-nc.
    #[arg(long, default_value = "p-c")]
    pub mt_cache: String,
    /// Longest gap P_I reads through rather than seeking over (the
    /// break-even gap is learnt; this caps it); 0 turns coalescing off.
    #[arg(long, default_value = "1MiB")]
    pub coalesce_gap: String,
    /// Reads by pages of this size (e.g. 128KiB) where a seek or a
    /// request costs at least a page's transfer (learnt; a fast disk never
    /// does); 0 turns pages off; auto (the default): 128KiB for a scene
    /// given by URL, else off.
    #[arg(long, default_value = "auto")]
    pub page: String,
    /// The share of the budget that pages may take from prefetching.
    #[arg(long, default_value_t = 0.25, value_parser = in_range(0.0f32, 0.9))]
    pub page_share: f32,
    /// Stall deadline in ms (0: off, the paper's protocol, P_R waits for
    /// every missing rep): Stage II reads only what it can finish this long
    /// after the fetch command; the rest is drawn as its nearest resident
    /// ancestor (counted as substituted and late) and read after the frame.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 60_000.0))]
    pub stall_deadline: f32,
    /// Occlusion culling (0: off): the share of the budget that P_R's
    /// occluder store takes (P_I's reps get the rest), e.g. 0.05.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 0.5))]
    pub occlusion: f32,
    #[command(flatten)]
    pub cut: engine_cli::SectionArgs,
    /// Hide every element whose description (name, mesh name, `extras`:
    /// IFC type, GlobalId) contains this text (repeatable): hidden
    /// elements leave the front and are not fetched.
    #[arg(long, value_name = "TEXT")]
    pub hide: Vec<String>,
    /// X-ray every element whose description contains this text
    /// (repeatable): drawn translucent, kept in the front, no occluder.
    #[arg(long, value_name = "TEXT")]
    pub xray: Vec<String>,
    /// Walk the path instead of flying it: each frame a walker (eye at
    /// 1.6 m, gravity, doors open) steers towards the path's position and
    /// collides with the scene's walk section; prints what walking costs.
    #[arg(long)]
    pub walk: bool,
    /// The quality governor: raise ε for the whole frame when the front
    /// does not fit the footprint (or --max-tris), instead of substituting.
    #[arg(long)]
    pub governor: bool,
    /// The governor's triangle target for the front (0: none).
    #[arg(long, default_value_t = 0)]
    pub max_tris: u64,
    /// The governor's frame-time target in ms (0: none): the front's
    /// triangles are held to what the measured drawing rate fits in it.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 60_000.0))]
    pub max_frame_ms: f32,
    /// Smooth LOD switches (0: off): a rep that replaces another fades in
    /// over this many seconds while the other fades out, both resident.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 10.0))]
    pub fade: f32,
    /// Fidelity against full resolution (needs --renderer wgpu): walk the
    /// path in core with every object at its finest rep, then at each of
    /// these tolerances (comma-separated, px), and compare the sampled
    /// frames (PSNR, pixels differing beyond one pixel); runs nothing else.
    #[arg(long)]
    pub fidelity: Option<String>,
    /// Where the front's triangles go, at each of these tolerances
    /// (comma-separated, px): reps, triangles, bytes, the share in HLODs,
    /// the depth where refinement stops, and on rasterised frames (see
    /// --anatomy-every) the visible, hidden and sub-pixel triangles and
    /// those whose error a thin member set; writes OUT/anatomy.md and
    /// OUT/anatomy.csv and runs nothing else.
    #[arg(long)]
    pub anatomy: Option<String>,
    /// --anatomy rasterises every N-th frame of the path on the CPU.
    #[arg(long, default_value_t = 20, value_parser = in_range(1usize, 1_000_000))]
    pub anatomy_every: usize,
}
