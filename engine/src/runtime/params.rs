//! The runtime's parameters: the three modes, prefetching, the footprint,
//! and their checks.

use crate::camera::{Pose, View};
use crate::governor::GovernorParams;

/// The three systems of the paper's evaluation, on one code path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Everything loaded at start (the budget is ignored).
    Incore,
    /// Fetch on demand only; P_I idle in Stages I and III.
    NoPre,
    /// Fetch plus binned priority prefetching.
    Pre,
}

impl Mode {
    /// The name used in CSV files and tables.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Incore => "incore",
            Mode::NoPre => "nopre",
            Mode::Pre => "pre",
        }
    }

    /// Parses `incore`, `nopre` or `pre`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "incore" => Ok(Mode::Incore),
            "nopre" => Ok(Mode::NoPre),
            "pre" => Ok(Mode::Pre),
            _ => Err(format!("unknown mode {s:?}: use incore, nopre or pre")),
        }
    }
}

/// Prefetching parameters (§4.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrefetchParams {
    /// Upper end δ of the binned range, in pixels (δ > ε).
    pub delta_px: f32,
    /// Number of bins B.
    pub bins: usize,
    /// Base widening of F_I over F_R, in degrees (per side).
    pub margin_deg: f32,
    /// Extra widening per degree of camera turn per frame.
    pub margin_per_deg_turn: f32,
    /// Largest widening, in degrees (90 or more: F_I all around the eye).
    pub max_margin_deg: f32,
    /// Levels of PAR/CHD followed from the front.
    pub depth: u8,
    /// Largest share of the budget held by speculative reps (prefetched and
    /// not drawn since); at the cap a prefetch may evict only speculative reps,
    /// so speculation cannot flush what was drawn before (prefetch pollution).
    pub speculative_share: f32,
    /// Reps of the F_I front up to this many bytes are also read by the
    /// sweep, in file order (0: off; see `loader/sweep.rs`).
    pub sweep_bytes: u32,
    /// Frames of camera motion (position and rotation) extrapolated for the
    /// lookahead fronts, one view front per frame ahead (0: off; see
    /// `loader/ahead.rs`).
    pub lookahead_frames: u32,
    /// F_I goes all around the eye whenever the all-around front at ε takes
    /// at most this share of the reps' room (the footprint less the pages'
    /// share; 0: never; the margins above decide otherwise).
    pub all_around_fit: f32,
}

impl Default for PrefetchParams {
    fn default() -> Self {
        Self {
            delta_px: 0.0,
            bins: 16,
            margin_deg: 30.0,
            margin_per_deg_turn: 4.0,
            max_margin_deg: 60.0,
            depth: 1,
            speculative_share: 0.6,
            sweep_bytes: 0,
            lookahead_frames: 10,
            all_around_fit: 1.0,
        }
    }
}

/// Runtime parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeParams {
    pub mode: Mode,
    /// Hard bound on resident rep bytes (out-of-core modes).
    pub budget_bytes: u64,
    /// Error tolerance ε in pixels.
    pub tolerance_px: f32,
    pub width_px: u32,
    pub height_px: u32,
    pub near: f32,
    pub far: f32,
    /// P_I reads reps in blocks of this size and checks for a new fetch
    /// command after each block while prefetching.
    pub block_bytes: usize,
    /// `delta_px == 0` means `4 ε`.
    pub prefetch: PrefetchParams,
    /// Frame period P_R keeps (0: unpaced). P_I starts a prefetch read only
    /// when it expects to finish before the next fetch command is due.
    pub frame_period_s: f32,
    /// Place-holder bytes reserved for each resident view-dependence tree
    /// (and node bytes for each Multi-Triangulation)
    /// (raised to what its root meta-nodes need, capped at its meta-node
    /// data), out of the same footprint as the reps.
    pub vdt_pool_bytes: u64,
    /// Which nodes a Multi-Triangulation's store keeps after a frame (the
    /// paper's caching, P,C, by default; its reserve is planned as the
    /// trees' from `vdt_pool_bytes`).
    pub mt_cache: crate::mt::cache::CacheMode,
    /// Longest gap between two wanted reps that P_I reads through instead
    /// of seeking over (the break-even gap is learnt; this caps it; 0: off).
    pub coalesce_max_gap: u64,
    /// Reads by pages (0, the default: off): where a seek costs at least
    /// this many bytes' transfer (learnt), P_I reads the aligned page of
    /// this size a rep lies in and keeps it, stored, in `page_share` of the
    /// budget (see `loader::pages`). Off on a fast disk by itself. Off by
    /// default: on the DE-size plant on `hdd` it brings every path kind to
    /// in-core frame times, but on the PP-size plant its share of a tight
    /// budget costs more misses than it saves (docs/results.md).
    pub page_bytes: u64,
    /// The share of the budget that pages may take from prefetching (a
    /// demand fetch takes it back).
    pub page_share: f32,
    /// Stall deadline (0: off, the paper's protocol: P_R waits for every
    /// missing rep). Otherwise Stage II starts a read only when its first
    /// block ends within this many seconds of the fetch command; the reps
    /// left are drawn as their nearest resident ancestor (counted as
    /// substituted and late) and loaded right after the frame.
    pub stall_deadline_s: f32,
    /// Occlusion culling (0: off): the bytes of P_R's occluder store,
    /// taken out of `budget_bytes` (P_I's reps get the rest). See
    /// [`crate::occlusion`].
    pub occlusion_bytes: u64,
    /// The quality governor (`None`: off; the front is always computed at
    /// `tolerance_px`). In `incore` mode only its triangle and frame-time
    /// targets apply.
    pub governor: Option<GovernorParams>,
    /// Smooth LOD switches (0: off): a rep that replaces another fades in
    /// over this many seconds while the other fades out (see
    /// [`crate::fade`]); both are resident, pinned, counted.
    pub fade_s: f32,
    /// Section planes (none by default): what they remove leaves every
    /// front, P_R's and P_I's (see [`crate::section`]).
    pub section: crate::section::Section,
}

impl Default for RuntimeParams {
    fn default() -> Self {
        Self {
            mode: Mode::Pre,
            budget_bytes: 64 << 20,
            tolerance_px: 2.0,
            width_px: 1280,
            height_px: 720,
            near: 0.05,
            far: 1e6,
            block_bytes: 64 << 10,
            prefetch: PrefetchParams::default(),
            frame_period_s: 0.0,
            vdt_pool_bytes: 4 << 20,
            mt_cache: crate::mt::cache::CacheMode::PC,
            coalesce_max_gap: 1 << 20,
            page_bytes: 0,
            page_share: 0.25,
            stall_deadline_s: 0.0,
            occlusion_bytes: 0,
            governor: None,
            fade_s: 0.0,
            section: crate::section::Section::NONE,
        }
    }
}

/// Why the runtime cannot start or go on.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    #[error("invalid parameter: {0}")]
    Params(String),
    #[error(
        "budget of {budget} bytes is below the minimal front (the root's coarsest rep needs {need} bytes, with its compressed copy while it loads)"
    )]
    BudgetTooSmall { budget: u64, need: u64 },
    #[error("the scene has no object-reps")]
    NoReps,
    #[error("the root's coarsest rep cannot be read: {0}")]
    RootUnreadable(String),
    #[error("the I/O thread stopped unexpectedly")]
    LoaderGone,
}

impl RuntimeParams {
    /// Rejects nonsense values.
    pub fn check(&self) -> Result<(), RuntimeError> {
        let bad = |s: &str| Err(RuntimeError::Params(s.to_string()));
        // The footprint's shares ([`super::Footprint`] derives them).
        if !(self.page_share.is_finite() && (0.0..=0.9).contains(&self.page_share)) {
            return bad("the pages' share of the budget must be in [0, 0.9]");
        }
        let speculative_share = self.prefetch.speculative_share;
        if !(speculative_share > 0.0 && speculative_share <= 1.0) {
            return bad("the speculative share must be in (0, 1]");
        }
        if self.mode != Mode::Incore && self.occlusion_bytes > self.budget_bytes / 2 {
            return bad("the occluder store may take at most half the budget");
        }
        if !(self.tolerance_px > 0.0 && self.tolerance_px <= 1e5) {
            return bad("tolerance must be in (0, 100000] pixels");
        }
        if self.width_px == 0
            || self.height_px == 0
            || self.width_px > 1 << 15
            || self.height_px > 1 << 15
        {
            return bad("viewport size must be in 1..=32768");
        }
        if !(self.near > 0.0 && self.far > self.near && self.far.is_finite()) {
            return bad("need 0 < near < far");
        }
        if !(self.frame_period_s >= 0.0 && self.frame_period_s <= 60.0) {
            return bad("frame period must be in [0, 60] seconds");
        }
        if !(self.stall_deadline_s >= 0.0 && self.stall_deadline_s <= 60.0) {
            return bad("stall deadline must be in [0, 60] seconds");
        }
        if !(self.fade_s >= 0.0 && self.fade_s <= 10.0) {
            return bad("fade time must be in [0, 10] seconds");
        }
        if let Some(g) = &self.governor {
            g.check().map_err(RuntimeError::Params)?;
            if g.max_tolerance_px < self.tolerance_px {
                return bad("the governor's largest tolerance is below the tolerance");
            }
        }
        if self.page_bytes != 0 && !(4096..=16 << 20).contains(&self.page_bytes) {
            return bad("page size must be 0 (off) or in 4 KiB..=16 MiB");
        }
        if self.block_bytes < 512 {
            return bad("block size must be at least 512 bytes");
        }
        let p = &self.prefetch;
        if p.bins == 0 || p.bins > 4096 {
            return bad("bins must be in 1..=4096");
        }
        if !(p.delta_px == 0.0 || (p.delta_px.is_finite() && p.delta_px > self.tolerance_px)) {
            return bad("δ must exceed the tolerance ε");
        }
        for v in [p.margin_deg, p.margin_per_deg_turn, p.max_margin_deg] {
            if !(v.is_finite() && v >= 0.0) {
                return bad("F_I margins must be finite and non-negative");
            }
        }
        if !(p.all_around_fit.is_finite() && p.all_around_fit >= 0.0) {
            return bad("the all-around fit must be a non-negative share of the budget");
        }
        if p.lookahead_frames > 10_000 {
            return bad("lookahead at most 10000 frames");
        }
        if p.max_margin_deg > 180.0 {
            return bad("F_I margin at most 180 degrees");
        }
        Ok(())
    }

    /// The view of a pose on this viewport.
    pub fn view(&self, pose: &Pose) -> View {
        View {
            pose: *pose,
            width_px: self.width_px,
            height_px: self.height_px,
            near: self.near,
            far: self.far,
            section: self.section,
        }
    }

    pub(super) fn delta(&self) -> f32 {
        // (Above the tolerance; the governor may raise it past a given δ.)
        if self.prefetch.delta_px > self.tolerance_px {
            self.prefetch.delta_px
        } else {
            4.0 * self.tolerance_px
        }
    }
}
