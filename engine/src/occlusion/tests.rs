use super::*;
use crate::testutil::quad;

#[test]
fn occluders_are_a_reps_largest_opaque_triangles() {
    let big = quad([0.0, 0.0, 0.0], [10.0, 10.0, 0.0]).encode(0, 0);
    let t = occluder_triangles(&big);
    assert_eq!(t.len(), 2);
    assert!(t.iter().all(|t| t.iter().all(|p| p.z.abs() < 1e-3)));
    // Not a raw mesh payload: nothing.
    assert!(occluder_triangles(&big[..40]).is_empty());
    assert!(occluder_triangles(b"REPZ and more bytes than a header holds, surely").is_empty());
    // Glass hides nothing.
    let mut glass = quad([0.0, 0.0, 0.0], [10.0, 10.0, 0.0]);
    for v in &mut glass.vertices {
        v.color[3] = 38;
    }
    assert!(occluder_triangles(&glass.encode(0, 0)).is_empty());
}

#[test]
fn the_store_stays_within_its_bytes() {
    let payload = quad([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]).encode(0, 0);
    let per = 64 + 2 * 36;
    let mut s = OccluderStore::new(3 * per + 10);
    for r in 0..10 {
        s.insert_from(r, &payload, None, r);
        s.validate().unwrap();
        assert!(s.bytes() <= 3 * per + 10);
    }
    assert_eq!(s.len(), 3);
    // The most recent three are held; a read marks an entry as used.
    assert!(s.get(7, 10).is_some() && s.get(9, 10).is_some());
    s.insert_from(10, &payload, None, 10);
    assert!(s.get(7, 10).is_some() && s.get(8, 10).is_none());
    // A store too small for one entry holds nothing.
    let mut tiny = OccluderStore::new(10);
    tiny.insert_from(0, &payload, None, 0);
    assert!(tiny.is_empty());
}

/// The occluders by their definition: every triangle of at least the
/// least area, by area (largest first, ties in mesh order), the first
/// [`store::MAX_TRIS`].
fn occluders_by_definition(m: &crate::format::RepMesh) -> Vec<[glam::Vec3; 3]> {
    let pos = |i: u32| glam::Vec3::from(m.position(&m.vertices[i as usize]));
    let diag = glam::Vec3::from_array(m.quant_scale).length() * 65535.0;
    let mut all: Vec<(f32, [glam::Vec3; 3])> = m
        .indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| m.vertices[i as usize].color[3] == 255))
        .map(|t| {
            let p = [pos(t[0]), pos(t[1]), pos(t[2])];
            (0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length(), p)
        })
        .filter(|(a, _)| a.is_finite() && *a >= 1e-3 * diag * diag)
        .collect();
    all.sort_by(|a, b| b.0.total_cmp(&a.0));
    all.truncate(store::MAX_TRIS);
    all.into_iter().map(|(_, p)| p).collect()
}

proptest::proptest! {
    #[test]
    fn occluders_are_the_largest_triangles_in_mesh_order_of_ties(
        pts in proptest::collection::vec((0u8..6, 0u8..6, 0u8..3, proptest::bool::weighted(0.8)), 3..40),
        tris in proptest::collection::vec((0usize..40, 0usize..40, 0usize..40), 1..200),
    ) {
        // Coarse coordinates: many triangles of equal area (ties).
        let p: Vec<[f32; 3]> = pts.iter().map(|&(x, y, z, _)| [f32::from(x), f32::from(y), f32::from(z)]).collect();
        // Some corners translucent: their triangles are no occluders.
        let c: Vec<[u8; 4]> = pts.iter().map(|&(.., opaque)| [9, 9, 9, if opaque { 255 } else { 40 }]).collect();
        let n = p.len();
        let idx: Vec<u32> = tris.iter().flat_map(|&(a, b, c)| [a % n, b % n, c % n]).map(|i| i as u32).collect();
        let m = crate::format::RepMesh::quantize(&p, &vec![[0.0, 0.0, 1.0]; n], &c, idx);
        proptest::prop_assert_eq!(occluder_triangles(&m.encode(0, 0)), occluders_by_definition(&m));
    }
}

/// Pass 1's occluders: at the last frame's tolerance, only the front's reps
/// that were visible last frame; at another tolerance (the governor
/// searching, its front holding other reps of the same nodes), every rep
/// visible last frame, so that culling keeps its occluders across a change
/// of tolerance.
#[test]
fn occluders_follow_the_last_frame_across_a_change_of_tolerance() {
    use crate::camera::{Pose, View};
    use crate::front::FrontIndex;
    use crate::testutil::build;
    // A root over 4 leaves of 2 LODs: reps 0 (root), then (1, 2), (3, 4), ...
    let (bytes, skel) = build(&[1, 2, 2, 2, 2], &[4, 0, 0, 0, 0]);
    let file = crate::format::SceneFile::from_source(crate::io::MemSource::new(bytes)).unwrap();
    let index = FrontIndex::new(&skel);
    let view = View {
        pose: Pose::look_at(Vec3::new(2.0, 0.5, 3.0), Vec3::new(2.0, 0.5, 0.0), 90.0),
        width_px: 640,
        height_px: 480,
        near: 0.1,
        far: 100.0,
        section: crate::section::Section::NONE,
    };
    let payload = |r: u32| -> Arc<[u8]> { file.read_rep_bytes(r).unwrap().into() };
    let mut c = OcclusionCuller::new(skel.reps.len(), 1 << 20);
    // Frame 1 draws the finer LOD of every leaf.
    let fine: Vec<u32> = vec![2, 4, 6, 8];
    c.begin_frame(&view);
    let (mut front, mut hidden) = (fine.clone(), Vec::new());
    c.cull(&view, &skel, &index, 1.0, &mut front, &mut hidden);
    assert_eq!(c.stats().occluders, 0, "no last frame");
    for &r in &front {
        let rec = skel.reps[r as usize];
        c.drawn(r, (&rec, None), &payload(r), index.node_box(rec.node));
    }
    c.end_frame(&skel, &index, &front);
    // Frame 2 at the same tolerance: its front's reps that were visible.
    c.begin_frame(&view);
    let coarse: Vec<u32> = vec![1, 3, 5, 8];
    let (mut front, mut hidden) = (coarse.clone(), Vec::new());
    c.cull(&view, &skel, &index, 1.0, &mut front, &mut hidden);
    assert_eq!(c.stats().occluders, 1, "rep 8 only");
    // At another tolerance: every rep visible in frame 1.
    let (mut front, mut hidden) = (coarse.clone(), Vec::new());
    c.cull(&view, &skel, &index, 1.25, &mut front, &mut hidden);
    assert_eq!(c.stats().occluders, 4);
    // Occluders in the front stay in it; the others are not added to it.
    assert!(front.contains(&8));
    assert!(front.iter().chain(&hidden).all(|r| coarse.contains(r)));
}
