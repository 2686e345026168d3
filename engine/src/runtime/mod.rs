//! The out-of-core runtime (Varadhan & Manocha §4): P_R and P_I.
//!
//! [`Walkthrough`] is P_R: per frame it computes the front (Stage I, while P_I
//! keeps prefetching for the previous frame), sends P_I a fetch command with
//! the front, draws the resident reps (L_I) as P_I hands them over, then each
//! missing rep (L_O) as P_I loads it (Stage II), and returns the frame's
//! metrics. P_I (the `loader` module) owns the resident set: the StartTail
//! InMemoryList, the byte budget (never exceeded: reps being loaded count),
//! preemptible block-wise loading (a preempted prefetch read is kept and
//! resumed), reads in file order through gaps shorter than the learnt
//! break-even gap, and in `pre` mode binned priority prefetching with the
//! enlarged frustum in Stages III and I (up to all around the eye), with an
//! optional sweep of F_I's small reps in file order.
//!
//! A view-dependence tree rep (`trees`) is loaded by P_I like any rep; P_R
//! refines it once per frame it is drawn, its meta-node store's bytes
//! reserved by P_I out of the same budget.
//!
//! With fades on (`RuntimeParams::fade_s`, [`crate::fade`]), P_R asks P_I
//! with each fetch command for the reps fading out; P_I hands over and pins
//! those still resident, before the front, when the front leaves room.
//!
//! The two threads talk over bounded `crossbeam-channel`s only.

#[cfg(test)]
mod edge_tests;
#[cfg(test)]
mod fade_tests;
#[cfg(test)]
mod fault_tests;
pub mod footprint;
#[cfg(test)]
mod instance_tests;
mod loader;
#[cfg(test)]
mod lookahead_tests;
mod mts;
#[cfg(test)]
mod page_tests;
mod paged;
mod params;
mod protocol;
pub mod resident;
#[cfg(test)]
mod section_tests;
mod select;
#[cfg(test)]
mod tests;
mod trees;

use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

use crossbeam_channel::{Receiver, Sender, bounded};

use crate::camera::{Pose, View};
use crate::front::FrontIndex;
use crate::io::ByteSource;
use crate::metrics::FrameMetrics;
use crate::render::{DrawStyle, Fade, Renderer};
use crate::skeleton::{RepId, Skeleton};
pub use footprint::{Footprint, Held, Shares};
pub use params::{Mode, PrefetchParams, RuntimeError, RuntimeParams};
use protocol::{Cmd, Draw, Reply};

/// The page size for scenes read over a network (`hlod-bench --page auto`,
/// `hlod-view`): every request pays the round trip, so P_I reads the
/// neighbours of a small rep with it, under the footprint (measured in
/// docs/results.md, "Scenes over HTTP").
pub const REMOTE_PAGE_BYTES: u64 = 128 << 10;

/// P_R: drives frames against a running P_I.
pub struct Walkthrough {
    skeleton: Arc<Skeleton>,
    params: RuntimeParams,
    cmd: Sender<Cmd>,
    replies: Receiver<Reply>,
    loader: Option<JoinHandle<()>>,
    drawn_stamp: Vec<u32>,
    frame: u32,
    last_pose: Option<Pose>,
    trees: trees::Trees,
    /// Stage I: the front, occlusion culling, the quality governor.
    select: select::FrontSelect,
    /// The tolerance of the frame being drawn.
    frame_tol: f32,
    /// Smooth LOD switches, on P_R's clock.
    fades: crate::fade::Fades,
    clock: Arc<dyn crate::clock::Clock>,
    origin: Instant,
    footprint: Footprint,
}

impl std::fmt::Debug for Walkthrough {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Walkthrough")
            .field("mode", &self.params.mode)
            .field("frame", &self.frame)
            .finish_non_exhaustive()
    }
}

impl Walkthrough {
    /// Starts P_I over the skeleton and the rep source. In `incore` mode every
    /// rep is loaded before this returns; otherwise the root's coarsest rep is
    /// loaded and kept as the last-resort substitute.
    pub fn start(
        skeleton: Arc<Skeleton>,
        source: Arc<dyn ByteSource>,
        params: RuntimeParams,
    ) -> Result<Self, RuntimeError> {
        Self::start_with_clock(
            skeleton,
            source,
            params,
            Arc::new(crate::clock::SystemClock),
        )
    }

    /// [`Walkthrough::start`] with P_I's timing read from `clock` (tests
    /// pass a [`crate::clock::ManualClock`] that a simulated disk advances).
    pub fn start_with_clock(
        skeleton: Arc<Skeleton>,
        source: Arc<dyn ByteSource>,
        params: RuntimeParams,
        clock: Arc<dyn crate::clock::Clock>,
    ) -> Result<Self, RuntimeError> {
        // The parameters are checked as the footprint is derived from them.
        let fp = Footprint::new(&params)?;
        if skeleton.reps.is_empty() {
            return Err(RuntimeError::NoReps);
        }
        let index = Arc::new(FrontIndex::new(&skeleton));
        let pools = Arc::new(trees::plan_pools(
            &skeleton,
            source.as_ref(),
            params.vdt_pool_bytes,
        ));
        let trees = trees::Trees::new(
            source.clone(),
            skeleton.clone(),
            pools.clone(),
            params.mode == Mode::Incore,
            params.mt_cache,
            clock.clone(),
        );
        let (cmd_tx, cmd_rx) = bounded(2);
        let (reply_tx, reply_rx) = bounded(loader::reply_capacity(skeleton.reps.len()));
        let (ready_tx, ready_rx) = bounded(1);
        // P_I's reps get the footprint less the occluder store.
        // Requests started ahead on a network source get their share.
        let fp = fp.with_read_ahead(source.read_ahead_max());
        source.set_read_ahead(fp.in_flight());
        let l = loader::Loader::new(
            skeleton.clone(),
            index.clone(),
            source,
            &pools,
            (params, fp),
            (cmd_rx, reply_tx),
            clock.clone(),
        );
        let handle = std::thread::Builder::new()
            .name("P_I".into())
            .spawn(move || l.run(ready_tx))
            .map_err(|_| RuntimeError::LoaderGone)?;
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                let _ = handle.join();
                return Err(e);
            }
            Err(_) => return Err(RuntimeError::LoaderGone),
        }
        let skeleton_reps = skeleton.reps.len();
        if let Some(need) = fp.unfit(skeleton.full_detail_bytes()) {
            tracing::warn!(
                "the footprint for reps ({} B: the budget of {} B less {} B for occluders) is \
                 below the {need} B that drawing every rep as itself needs (the largest rep \
                 while it loads, beside the root's coarsest): the reps that do not fit are \
                 drawn as coarser ancestors, and the view never completes",
                fp.reps().unwrap_or(0),
                params.budget_bytes,
                fp.occluders()
            );
        }
        Ok(Self {
            drawn_stamp: vec![0; skeleton.reps.len()],
            skeleton,
            params,
            cmd: cmd_tx,
            replies: reply_rx,
            loader: Some(handle),
            frame: 0,
            last_pose: None,
            trees,
            select: select::FrontSelect::new(
                index.clone(),
                skeleton_reps,
                fp.occluders(),
                params.governor,
                params.tolerance_px,
                // In core nothing is loaded: only a triangle target applies.
                fp.reps(),
                clock.clone(),
            ),
            frame_tol: params.tolerance_px,
            fades: crate::fade::Fades::new(params.fade_s, skeleton_reps),
            footprint: fp,
            origin: clock.now(),
            clock,
        })
    }

    /// The clock P_R and P_I read.
    pub fn clock(&self) -> &Arc<dyn crate::clock::Clock> {
        &self.clock
    }

    /// Returns once P_I has done what it would do before the next frame
    /// (its queued prefetches, up to what its pacing allows). On a
    /// simulated clock ([`crate::clock::Clock::is_simulated`]) time passes
    /// only as reads and waits say, so a paced walk lets P_I work this way
    /// where a real one would sleep ([`run_path_each`]).
    pub fn settle(&mut self) -> Result<(), RuntimeError> {
        let (tx, rx) = bounded(1);
        self.cmd
            .send(Cmd::Settle(tx))
            .map_err(|_| RuntimeError::LoaderGone)?;
        rx.recv().map_err(|_| RuntimeError::LoaderGone)
    }

    /// `None` when every rep can be drawn as itself under this footprint;
    /// else the footprint that would take (see [`Skeleton::full_detail_bytes`]).
    pub fn full_detail_need(&self) -> Option<u64> {
        self.footprint.unfit(self.skeleton.full_detail_bytes())
    }

    /// The footprint and its shares.
    pub fn footprint(&self) -> &Footprint {
        &self.footprint
    }

    /// The parameters in force.
    pub fn params(&self) -> &RuntimeParams {
        &self.params
    }

    /// Changes the viewport (a window resize); P_I gets it with each view.
    pub fn set_viewport(&mut self, width_px: u32, height_px: u32) -> Result<(), RuntimeError> {
        let p = RuntimeParams {
            width_px,
            height_px,
            ..self.params
        };
        p.check()?;
        self.params = p;
        Ok(())
    }

    /// Cuts the model open from the next frame on: what `section` removes
    /// leaves P_R's front and the fronts P_I plans from (each fetch
    /// command carries the view, and the view its section).
    pub fn set_section(&mut self, section: crate::section::Section) {
        self.params.section = section;
    }

    /// Hides elements from the next frame on: a node whose objects are all
    /// hidden leaves P_R's front and every front P_I plans from (they share
    /// the front index); see [`crate::hide`]. The renderer draws a merged
    /// leaf in part from [`crate::hide::Hiding::parts`].
    pub fn set_hiding(&mut self, hiding: &crate::hide::Hiding) {
        self.select.index().set_visibility(hiding.nodes());
    }

    /// The view for a pose under these parameters.
    pub fn view(&self, pose: &Pose) -> View {
        self.params.view(pose)
    }

    /// Renders one frame from `pose`.
    pub fn frame(
        &mut self,
        pose: &Pose,
        renderer: &mut dyn Renderer,
    ) -> Result<FrameMetrics, RuntimeError> {
        self.frame_split(pose, pose, renderer)
    }

    /// Computes the front (and loads it) for `front_pose` but draws it seen
    /// from `draw_pose`: a frozen front inspected from elsewhere.
    pub fn frame_split(
        &mut self,
        front_pose: &Pose,
        draw_pose: &Pose,
        renderer: &mut dyn Renderer,
    ) -> Result<FrameMetrics, RuntimeError> {
        let pose = front_pose;
        let t0 = self.clock.now();
        let view = self.view(pose);
        let sel = self.select.select(&self.skeleton, &view);
        let (front, hidden) = (sel.front, sel.hidden);
        self.frame_tol = sel.tolerance_px;
        let turn_rad = self.last_pose.map_or(0.0, |p| p.angle_to(pose));
        self.last_pose = Some(*pose);
        let skel = &self.skeleton;
        let fading = self.fades.plan(
            (self.clock.now() - self.origin).as_secs_f64(),
            &front,
            |r| skel.par(r),
            |r| !skel.reps[r as usize].is_paged(),
        );
        let front = Arc::new(front);
        self.cmd
            .send(Cmd::Fetch {
                view: Box::new(view),
                turn_rad,
                front: front.clone(),
                hidden: Arc::new(hidden),
                tolerance_px: sel.tolerance_px,
                fading: Arc::new(fading),
            })
            .map_err(|_| RuntimeError::LoaderGone)?;
        self.frame += 1;
        let stamp = self.frame;
        let mut m = FrameMetrics {
            frame: self.frame - 1,
            mode: self.params.mode.name(),
            front_ms: sel.front_ms,
            occlusion_ms: sel.occlusion_ms,
            tolerance_px: f64::from(sel.tolerance_px),
            front_tries: sel.tries,
            front_reps: front.len() as u32,
            front_bytes: sel.cost.bytes,
            front_tris: sel.cost.tris,
            budget_bytes: self.params.budget_bytes,
            nodes_visited: sel.nodes_visited,
            ..Default::default()
        };
        renderer.begin_frame(&self.view(draw_pose));
        let mut wait = 0.0;
        let mut tf = paged::TreeFrame::default();
        let mut unusable = Vec::new();
        let stats = loop {
            let reply = match self.replies.try_recv() {
                Ok(r) => r,
                Err(_) => {
                    let w = self.clock.now();
                    let r = self.replies.recv().map_err(|_| RuntimeError::LoaderGone)?;
                    wait += self.clock.ms_since(w);
                    r
                }
            };
            match reply {
                Reply::Fading(ds) => {
                    for d in ds {
                        self.draw_fading(d, renderer, &mut m);
                    }
                }
                Reply::Draws(ds) => {
                    for d in ds {
                        self.draw(d, &view, stamp, renderer, (&mut m, &mut tf), &mut unusable);
                    }
                }
                Reply::Missing => m.substituted += 1,
                Reply::Evicted(reps) => {
                    for r in reps {
                        // P_I pins the front and its substitutes for the
                        // frame (`loader::outbox` relies on it).
                        debug_assert_ne!(
                            self.drawn_stamp[r as usize], stamp,
                            "rep {r} evicted in the frame that draws it"
                        );
                        renderer.evict(r);
                        self.trees.evict(r);
                    }
                }
                Reply::Done(s) => break s,
            }
        };
        renderer.end_frame();
        self.fades.end_frame();
        self.select.end_frame(&self.skeleton, &front, &mut m);
        for r in unusable {
            self.cmd
                .send(Cmd::Unusable(r))
                .map_err(|_| RuntimeError::LoaderGone)?;
        }
        m.front_tris += tf.tris + tf.mt_tris;
        m.mt_trees = tf.mt_trees;
        m.mt_cut_arcs = tf.mt_arcs;
        m.mt_tris = tf.mt_tris;
        m.mt_adapt = tf.mt_adapt;
        m.mt_reads = tf.mt_reads;
        m.mt_partitions = tf.mt_partitions;
        m.mt_read_bytes = tf.mt_read_bytes;
        m.mt_misses = tf.mt_misses;
        m.mt_nodes = tf.mt_nodes;
        m.vdt_trees = tf.trees;
        m.adapt = tf.adapt;
        m.vdt_tris = tf.tris;
        m.vdt_misses = tf.misses;
        m.metas_loaded = tf.metas_loaded;
        m.vdt_ms = tf.ms;
        m.vdt_bytes = self.trees.bytes();
        m.gpu_bytes = renderer.gpu_bytes();
        m.wait_ms = wait;
        m.loader = stats;
        m.frame_ms = self.clock.ms_since(t0);
        let draw_ms = m.frame_ms - m.front_ms - m.occlusion_ms - m.wait_ms;
        self.select
            .observe_frame(m.frame_ms, draw_ms.max(0.0), m.drawn_tris);
        Ok(m)
    }

    /// Draws one rep P_I handed over: a view-dependence tree refined for
    /// `view`, or a static rep once per frame (`stamp`).
    fn draw(
        &mut self,
        d: Draw,
        view: &View,
        stamp: u32,
        renderer: &mut dyn Renderer,
        (m, tf): (&mut FrameMetrics, &mut paged::TreeFrame),
        unusable: &mut Vec<RepId>,
    ) {
        let Draw {
            rep,
            for_rep,
            payload,
        } = d;
        let rec = &self.skeleton.reps[rep as usize];
        if rec.is_paged() {
            let before = tf.tris + tf.mt_tris;
            if self
                .trees
                .draw(rep, &payload, view, self.frame_tol, renderer, tf)
            {
                m.drawn_reps += 1;
                m.drawn_tris += tf.tris + tf.mt_tris - before;
            } else {
                m.substituted += 1;
                unusable.push(rep);
            }
            return;
        }
        if rep == for_rep {
            m.drawn_reps += 1;
        } else {
            m.substituted += 1;
        }
        let placement = self.skeleton.placement(rep).copied();
        if rep == for_rep {
            self.select.drawn(rep, (rec, placement.as_ref()), &payload);
        }
        if self.drawn_stamp[rep as usize] != stamp {
            self.drawn_stamp[rep as usize] = stamp;
            m.drawn_tris += u64::from(rec.tri_count);
            let mut style = if rep == for_rep {
                let fade = self.fades.fade_in(rep);
                m.fade_in += u32::from(fade != Fade::Opaque);
                DrawStyle {
                    substitute: false,
                    fade,
                    placement: None,
                }
            } else {
                self.fades.shown(rep);
                DrawStyle::opaque(true)
            };
            style.placement = placement;
            renderer.draw(rep, rec, &payload, style);
        }
    }

    /// Draws a rep fading out (P_I pinned it for this frame). It does not
    /// take the rep's once-a-frame stamp: drawn again as a substitute, it
    /// is drawn opaque.
    fn draw_fading(&mut self, d: Draw, renderer: &mut dyn Renderer, m: &mut FrameMetrics) {
        let Some(fade) = self.fades.fade_out(d.rep) else {
            return;
        };
        let rec = &self.skeleton.reps[d.rep as usize];
        m.fade_out += 1;
        m.drawn_tris += u64::from(rec.tri_count);
        renderer.draw(
            d.rep,
            rec,
            &d.payload,
            DrawStyle {
                substitute: false,
                fade,
                placement: self.skeleton.placement(d.rep).copied(),
            },
        );
    }
}

impl Drop for Walkthrough {
    fn drop(&mut self) {
        let _ = self.cmd.send(Cmd::Shutdown);
        // Dropping the receiver first unblocks a P_I stuck sending a reply
        // (P_R unwinding mid-frame), so the join cannot hang.
        drop(std::mem::replace(
            &mut self.replies,
            crossbeam_channel::never(),
        ));
        if let Some(h) = self.loader.take() {
            let _ = h.join();
        }
    }
}

/// Plays `poses` at `fps` frames per second (0: as fast as possible): each
/// frame starts a frame period after the previous one, or when it finished.
pub fn run_path(
    walk: &mut Walkthrough,
    poses: &[Pose],
    renderer: &mut dyn Renderer,
    fps: f32,
) -> Result<Vec<FrameMetrics>, RuntimeError> {
    let mut out = Vec::with_capacity(poses.len());
    run_path_each(walk, poses, renderer, fps, |m| {
        out.push(m);
        Ok::<(), std::convert::Infallible>(())
    })
    .map_err(|e| match e {
        PathRunError::Runtime(e) => e,
        PathRunError::Sink(never) => match never {},
    })?;
    Ok(out)
}

/// Why [`run_path_each`] stopped: the runtime, or the sink's error `E`.
#[derive(Debug, thiserror::Error)]
pub enum PathRunError<E: std::error::Error + 'static> {
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    #[error(transparent)]
    Sink(E),
}

/// [`run_path`], handing each frame's metrics to `each` as it ends instead
/// of keeping them (a long run's memory does not grow with its frames).
pub fn run_path_each<E: std::error::Error + 'static>(
    walk: &mut Walkthrough,
    poses: &[Pose],
    renderer: &mut dyn Renderer,
    fps: f32,
    mut each: impl FnMut(FrameMetrics) -> Result<(), E>,
) -> Result<(), PathRunError<E>> {
    let period = if fps > 0.0 {
        crate::limits::duration_s(1.0 / f64::from(fps))
    } else {
        std::time::Duration::ZERO
    };
    let clock = walk.clock().clone();
    let mut next = clock.now();
    for pose in poses {
        if !period.is_zero() && clock.is_simulated() {
            walk.settle()?;
        }
        clock.sleep_until(next);
        let start = clock.now();
        each(walk.frame(pose, renderer)?).map_err(PathRunError::Sink)?;
        next = start + period;
    }
    Ok(())
}
