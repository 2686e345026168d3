//! Shared payloads (format version 6): P_I reads, holds and counts a
//! payload placed by several reps once, and P_R draws each rep with its
//! placement.

use std::sync::Arc;

use super::tests::{check_frames, params, pose, scene_of, start, wide_shape};
use super::*;
use crate::format::RepMesh;
use crate::render::Renderer;
use crate::testutil::{build, build_instanced};

/// Records each draw's rep, placement and payload.
#[derive(Default)]
struct Recorder {
    draws: Vec<(RepId, Option<crate::records::RepPlacement>, Arc<[u8]>)>,
}

impl Renderer for Recorder {
    fn begin_frame(&mut self, _view: &View) {}
    fn draw(&mut self, rep: RepId, _rec: &crate::format::RepRecord, p: &Arc<[u8]>, s: DrawStyle) {
        self.draws.push((rep, s.placement, p.clone()));
    }
    fn end_frame(&mut self) {}
    fn name(&self) -> &'static str {
        "recorder"
    }
}

#[test]
fn a_shared_payload_is_resident_once_and_each_rep_is_drawn_where_it_belongs() {
    let (reps, children) = wide_shape(64);
    let (plain, _) = scene_of(build(&reps, &children).0);
    let (skel, src) = scene_of(build_instanced(&reps, &children).0);
    assert!(!skel.placements.is_empty());
    // 64 leaves of three levels place three payloads.
    let owners = (0..skel.reps.len() as RepId)
        .filter(|&r| skel.placement(r).is_some_and(|p| p.source == r))
        .count();
    assert_eq!(owners, 3);
    assert!(skel.in_core_bytes() < plain.in_core_bytes() / 10);
    let budget = skel.in_core_bytes();
    let mut walk = start(skel.clone(), src, params(Mode::Incore, budget)).unwrap();
    let mut r = Recorder::default();
    let poses: Vec<_> = (0..20)
        .map(|i| pose(i as f32 * 3.0, 0.5, 3.0, 0.0))
        .collect();
    let mut frames = Vec::new();
    for p in &poses {
        frames.push(walk.frame(p, &mut r).unwrap());
    }
    check_frames(&frames, budget);
    // In core, every payload once: the resident bytes are the unique ones.
    let last = frames.last().unwrap();
    assert_eq!(
        last.loader.resident_bytes,
        budget - skel.reps[0].load_scratch()
    );
    assert!(frames.iter().all(|f| f.substituted == 0));
    let mut placed = 0;
    for (rep, placement, payload) in &r.draws {
        assert_eq!(placement.as_ref(), skel.placement(*rep));
        let Some(pl) = placement else { continue };
        placed += 1;
        // Decoded as its owner's and placed, it lies in its own box: the
        // plain scene's rep.
        let owner = &skel.reps[pl.source as usize];
        let mut mesh = RepMesh::decode(payload, pl.source, owner).unwrap();
        mesh.placement = Some(*pl);
        let want = &plain.reps[*rep as usize];
        for v in &mesh.vertices {
            let p = mesh.position(v);
            for a in 0..3 {
                assert!(
                    p[a] >= want.bbox_min[a] - 1e-4 && p[a] <= want.bbox_max[a] + 1e-4,
                    "rep {rep}: {p:?} outside {want:?}"
                );
            }
        }
    }
    assert!(placed > 0, "no placed rep was drawn");
}

#[test]
fn out_of_core_a_payload_is_read_once_for_all_its_placements() {
    let (reps, children) = wide_shape(64);
    let (skel, src) = scene_of(build_instanced(&reps, &children).0);
    let budget = skel.in_core_bytes();
    let mut walk = start(skel.clone(), src, params(Mode::NoPre, budget)).unwrap();
    let mut r = Recorder::default();
    // Along the row, near enough that the leaves' finest levels are drawn.
    let poses: Vec<_> = (0..40)
        .map(|i| pose(i as f32 * 1.5, 0.5, 1.5, 0.0))
        .collect();
    let mut frames = Vec::new();
    for p in &poses {
        frames.push(walk.frame(p, &mut r).unwrap());
    }
    check_frames(&frames, budget);
    let stage2: u64 = frames.iter().map(|f| f.loader.stage2_bytes).sum();
    let stored: u64 = (skel.reps.iter().enumerate())
        .filter(|&(r, _)| skel.owns_payload(r as RepId))
        .map(|(_, r)| u64::from(r.len))
        .sum();
    // Nothing is evicted at this budget, so nothing is read twice, though
    // many more reps than payloads were drawn.
    assert!(stage2 <= stored, "{stage2} bytes read of {stored} stored");
    let mut placed: Vec<RepId> = (r.draws.iter())
        .filter(|d| d.1.is_some())
        .map(|d| d.0)
        .collect();
    placed.sort_unstable();
    placed.dedup();
    assert!(placed.len() > 20, "{} placed reps drawn", placed.len());
    assert!(frames.iter().all(|f| f.substituted == 0));
}
