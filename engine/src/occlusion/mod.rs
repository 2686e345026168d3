//! Occlusion culling of the front (issue: architectural walkthroughs).
//!
//! Two passes per frame, on P_R's thread and on the CPU, so that lavapipe
//! and a GPU decide alike:
//!
//! 1. Stage I computes the front `F` (frustum and simplification culling).
//!    The reps of `F` that were visible in the previous frame and whose
//!    occluder triangles P_R holds are the *occluders*: they stay in the
//!    front, so they are drawn this frame, and their triangles are
//!    rasterised into an [`OcclusionBuffer`]. Every other rep of `F` is
//!    tested by its node's box and left out of the front when the box is
//!    hidden. P_I never sees the hidden reps as front reps: they are not
//!    fetched on demand, and prefetching ranks them last.
//! 2. After the frame, the occluder triangles of the reps drawn for the
//!    first time are added, and every front rep is tested against the
//!    complete buffer: those not hidden are the next frame's candidates.
//!
//! The test is conservative for the image: a rep is left out only when its
//! box is behind triangles that this very frame draws, at every pixel
//! centre the box covers (up to float rounding against the GPU's own
//! vertex transform and the test's relative depth margin of 1e-4). Occluder triangles are a rep's largest ones
//! (walls, slabs), kept by P_R in an [`OccluderStore`] of bounded bytes,
//! which come out of the footprint.

mod buffer;
mod store;

pub use buffer::{BoxSamples, DEPTH_MARGIN, OcclusionBuffer, Projector, TILE, clip_near};
pub use store::{OccluderStore, occluder_triangles};

type Tris = Arc<[[Vec3; 3]]>;

/// A drawn rep whose node box spans fewer pixels is not kept as an
/// occluder: it hides little, and scanning its triangles costs as much.
const MIN_OCCLUDER_PX: f32 = 24.0;
/// Triangles scanned for occluders per frame, at most (a bound on the
/// frame after a jump, when every rep is new).
const SCAN_PER_FRAME: u64 = 1 << 21;

use std::sync::Arc;

use glam::Vec3;

use crate::camera::{View, box_distance};
use crate::format::RepRecord;
use crate::front::FrontIndex;
use crate::skeleton::{RepId, Skeleton};

/// What the culling did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CullStats {
    /// Front reps rasterised as occluders before the test.
    pub occluders: u32,
    /// Front reps left out as hidden.
    pub occluded: u32,
    /// Triangles rasterised this frame (both passes).
    pub triangles: u64,
    /// Time of both passes, in milliseconds (measured by the caller).
    pub ms: f64,
}

/// The culler: its occluder store, its buffer and who was visible.
#[derive(Debug)]
pub struct OcclusionCuller {
    store: OccluderStore,
    buffer: Option<OcclusionBuffer>,
    /// Frame number (from 1) in which each rep was last seen not hidden.
    visible: Vec<u32>,
    /// Pass in which each rep's triangles went into the buffer.
    rasterised: Vec<u32>,
    frame: u32,
    /// Pass 1 may run more than once a frame (the governor tries several
    /// tolerances); each run starts a new buffer.
    pass: u32,
    /// Reps drawn as themselves this frame and not yet in the buffer.
    drawn: Vec<RepId>,
    /// The eye of this frame's view, its pixels per radian and near plane.
    eye: Vec3,
    ppr: f32,
    near: f32,
    /// Triangles scanned for occluders this frame.
    scanned: u64,
    /// The reps found visible at the end of the last frame.
    last_visible: Vec<RepId>,
    /// The tolerance of this frame's last pass 1, and of the last frame's.
    tol: f32,
    prev_tol: f32,
    stats: CullStats,
}

impl OcclusionCuller {
    /// A culler for `reps` reps whose occluder store holds at most
    /// `store_bytes`.
    pub fn new(reps: usize, store_bytes: u64) -> Self {
        Self {
            store: OccluderStore::new(store_bytes),
            buffer: None,
            visible: vec![0; reps],
            rasterised: vec![0; reps],
            frame: 0,
            pass: 0,
            drawn: Vec::new(),
            eye: Vec3::ZERO,
            ppr: 1.0,
            near: 1.0,
            scanned: 0,
            last_visible: Vec::new(),
            tol: f32::NAN,
            prev_tol: f32::NAN,
            stats: CullStats::default(),
        }
    }

    /// Bytes the occluder store holds now (never above its capacity).
    pub fn store_bytes(&self) -> u64 {
        self.store.bytes()
    }

    /// Starts a frame seen from `view`.
    pub fn begin_frame(&mut self, view: &View) {
        self.frame += 1;
        self.drawn.clear();
        self.eye = view.pose.position;
        self.ppr = view.pixels_per_radian();
        self.near = view.near;
        self.scanned = 0;
        self.prev_tol = self.tol;
    }

    /// Pass 1: removes from `front`, the front at tolerance `tol`, the
    /// reps hidden behind the occluders, appending them to `hidden`.
    /// Called after [`begin_frame`](Self::begin_frame), once or more (the
    /// last call's front is the one drawn).
    ///
    /// At the last frame's tolerance the occluders are the front's reps
    /// that were visible in the last frame. At another tolerance (the
    /// governor searching) the front holds other reps of the same nodes,
    /// few of them ever drawn, so those would leave culling with almost no
    /// occluders and the front would balloon at every step; there the
    /// occluders are all of the last frame's visible reps, which the
    /// front's reps approximate to within the larger of the two
    /// tolerances (see `docs/design/runtime.md`, *Occlusion culling*).
    pub fn cull(
        &mut self,
        view: &View,
        skeleton: &Skeleton,
        index: &FrontIndex,
        tol: f32,
        front: &mut Vec<RepId>,
        hidden: &mut Vec<RepId>,
    ) {
        self.pass += 1;
        self.stats = CullStats::default();
        self.tol = tol;
        let buf = match &mut self.buffer {
            Some(b) => {
                b.reset(view);
                b
            }
            None => self.buffer.insert(OcclusionBuffer::new(view)),
        };
        let (prev, now) = (self.frame - 1, self.pass);
        let mut near: Vec<(f32, u32, Tris)> = Vec::new();
        let mut take = |r: RepId, near: &mut Vec<(f32, u32, Tris)>| {
            if self.rasterised[r as usize] == now {
                return;
            }
            if let Some(t) = self.store.get(r, self.frame) {
                let (mn, mx) = index.node_box(skeleton.reps[r as usize].node);
                near.push((box_distance(view.pose.position, mn, mx), r, t));
                self.rasterised[r as usize] = now;
            }
        };
        if prev > 0 {
            if tol == self.prev_tol {
                for &r in front.iter() {
                    if self.visible[r as usize] == prev {
                        take(r, &mut near);
                    }
                }
            } else {
                for &r in &self.last_visible {
                    take(r, &mut near);
                }
            }
        }
        rasterise_nearest_first(buf, &mut near);
        self.stats.occluders = near.len() as u32;
        let rasterised = &self.rasterised;
        front.retain(|&r| {
            let keep = rasterised[r as usize] == now || {
                let (mn, mx) = index.node_box(skeleton.reps[r as usize].node);
                !buf.box_occluded(mn, mx)
            };
            if !keep {
                hidden.push(r);
            }
            keep
        });
        self.stats.occluded = hidden.len() as u32;
        self.stats.triangles = buf.triangles;
    }

    /// A rep drawn as itself this frame (a static rep's raw payload, its
    /// node's box): its occluder triangles are kept (when the box is large
    /// on the screen), and go into the buffer after the frame.
    /// A shared payload's triangles are placed by `placement`.
    pub fn drawn(
        &mut self,
        r: RepId,
        (rec, placement): (&RepRecord, Option<&crate::records::RepPlacement>),
        payload: &Arc<[u8]>,
        bbox: (Vec3, Vec3),
    ) {
        if rec.is_paged() || self.buffer.is_none() {
            return;
        }
        if !self.store.contains(r) {
            let (mn, mx) = bbox;
            let dist = box_distance(self.eye, mn, mx).max(self.near);
            let tris = u64::from(rec.tri_count);
            if (mx - mn).length() * self.ppr / dist < MIN_OCCLUDER_PX
                || self.scanned + tris > SCAN_PER_FRAME
            {
                return;
            }
            self.scanned += tris;
            self.store.insert_from(r, payload, placement, self.frame);
        }
        if self.rasterised[r as usize] != self.pass {
            self.drawn.push(r);
        }
    }

    /// Pass 2, after the frame: the visibility of `front` (the reps kept
    /// by [`cull`](Self::cull)) against everything drawn.
    pub fn end_frame(&mut self, skeleton: &Skeleton, index: &FrontIndex, front: &[RepId]) {
        let Some(buf) = &mut self.buffer else {
            return;
        };
        let (now, frame) = (self.pass, self.frame);
        let mut near: Vec<(f32, RepId, Tris)> = Vec::new();
        for &r in &self.drawn {
            if self.rasterised[r as usize] == now {
                continue;
            }
            self.rasterised[r as usize] = now;
            if let Some(t) = self.store.get(r, self.frame) {
                let (mn, mx) = index.node_box(skeleton.reps[r as usize].node);
                near.push((box_distance(self.eye, mn, mx), r, t));
            }
        }
        rasterise_nearest_first(buf, &mut near);
        self.last_visible.clear();
        for &r in front {
            let (mn, mx) = index.node_box(skeleton.reps[r as usize].node);
            if !buf.box_occluded(mn, mx) {
                self.visible[r as usize] = frame;
                self.last_visible.push(r);
            }
        }
        self.stats.triangles = buf.triangles;
    }

    /// This frame's counts (the caller adds the time).
    pub fn stats(&self) -> CullStats {
        self.stats
    }
}

/// Rasterises occluders `(distance, tie-break key, triangles)`, nearest
/// first: what is near hides most, and the tiles it covers turn the
/// triangles behind away early.
fn rasterise_nearest_first(buf: &mut OcclusionBuffer, near: &mut [(f32, u32, Tris)]) {
    near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    for (_, _, t) in near.iter() {
        for &tri in t.iter() {
            buf.add_triangle(tri);
        }
    }
}

#[cfg(test)]
mod tests;
