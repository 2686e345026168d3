use super::*;

/// An `n × n` grid of quads in the XZ plane, slightly bumped in Y.
fn grid(n: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut p = Vec::new();
    for z in 0..=n {
        for x in 0..=n {
            let h = ((x * 7 + z * 13) % 5) as f32 * 0.01;
            p.push([x as f32, h, z as f32]);
        }
    }
    let mut idx = Vec::new();
    let w = n + 1;
    for z in 0..n {
        for x in 0..n {
            let a = z * w + x;
            idx.extend_from_slice(&[a, a + w, a + 1, a + 1, a + w, a + w + 1]);
        }
    }
    (p, idx)
}

/// Triangles as position triples (bit patterns), canonically rotated and
/// sorted: leaf ids are renumbered depth-first, positions are not.
fn sorted_tris(t: impl IntoIterator<Item = [u32; 3]>, pos: &[[f32; 3]]) -> Vec<[[u32; 3]; 3]> {
    let mut v: Vec<[[u32; 3]; 3]> = t
        .into_iter()
        .map(|c| c.map(|i| pos[i as usize].map(f32::to_bits)))
        .map(|mut c| {
            // Canonical rotation keeps the winding.
            let k = (0..3).min_by_key(|&i| c[i]).unwrap();
            c.rotate_left(k);
            c
        })
        .collect();
    v.sort_unstable();
    v
}

#[test]
fn grid_builds_a_valid_tree_and_full_refinement_is_the_input() {
    let (p, idx) = grid(12);
    for metric in [Metric::Quadric, Metric::EdgeLength] {
        let t = build_tree(
            &p,
            &idx,
            &VdtParams {
                metric,
                max_switch: None,
            },
        );
        t.validate().unwrap();
        assert_eq!(t.leaf_count(), p.len());
        assert!(t.roots.len() < 10, "{metric:?}: {} roots", t.roots.len());
        // ids increase toward the roots; each new id is one more than the last.
        assert!(t.nodes.len() > p.len());
        let leaves: Vec<bool> = (0..t.nodes.len()).map(|i| i < t.leaf_count()).collect();
        let full = sorted_tris(t.cut_triangles(&leaves), &t.positions);
        assert_eq!(
            full,
            sorted_tris(idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]), &p)
        );
        let mut roots = vec![false; t.nodes.len()];
        for &r in &t.roots {
            roots[r as usize] = true;
        }
        assert!(t.cut_triangles(&roots).len() <= t.permanent.len() + 2);
    }
}

#[test]
fn every_prefix_of_the_collapse_sequence_has_no_fold_over() {
    // Undoing collapses newest-first from the roots walks back through the
    // construction's meshes; each must keep every triangle facing up.
    let (p, idx) = grid(10);
    let t = build_tree(&p, &idx, &VdtParams::default());
    let mut active = vec![false; t.nodes.len()];
    for &r in &t.roots {
        active[r as usize] = true;
    }
    for i in (t.leaf_count()..t.nodes.len()).rev() {
        let nd = t.nodes[i];
        active[i] = false;
        active[nd.left as usize] = true;
        active[nd.right as usize] = true;
        for c in t.cut_triangles(&active) {
            let q = c.map(|v| glam::Vec3::from(t.positions[t.nodes[v as usize].leaf as usize]));
            let n = (q[1] - q[0]).cross(q[2] - q[0]);
            assert!(
                n.y > 0.0,
                "triangle {c:?} flipped after undoing {i}: n = {n:?}, q = {q:?}"
            );
        }
    }
}

#[test]
fn duplicates_degenerates_and_non_manifold_fans_are_handled() {
    // Two triangles over the same edge with duplicated vertices, a zero-area
    // triangle, a repeated-corner triangle, and an index out of range.
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0], // duplicate of 1
        [0.0, 0.0, 1.0], // duplicate of 2
        [1.0, 0.0, 1.0],
        [2.0, 0.0, 0.0], // collinear with 0 and 1
    ];
    let idx = vec![0, 2, 1, 3, 4, 5, 0, 1, 6, 0, 0, 1, 0, 1, 99];
    let t = build_tree(&p, &idx, &VdtParams::default());
    t.validate().unwrap();
    assert_eq!(t.leaf_count(), 5, "duplicates welded");
    assert_eq!(
        t.triangles.len(),
        2,
        "degenerate and broken triangles dropped"
    );
    // A fan of three triangles on one edge (non-manifold).
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.5, 1.0, 0.0],
        [0.5, -1.0, 0.3],
        [0.5, 0.2, 1.0],
    ];
    let idx = vec![0, 1, 2, 1, 0, 3, 0, 1, 4];
    let t = build_tree(&p, &idx, &VdtParams::default());
    t.validate().unwrap();
    let leaves: Vec<bool> = (0..t.nodes.len()).map(|i| i < 5).collect();
    assert_eq!(t.cut_triangles(&leaves).len(), 3);
    // No triangles at all: every vertex is its own root.
    let t = build_tree(&p, &[], &VdtParams::default());
    t.validate().unwrap();
    assert_eq!(t.roots.len(), 5);
}

#[test]
fn separate_parts_make_a_forest_and_construction_is_deterministic() {
    let (mut p, mut idx) = grid(4);
    let (p2, idx2) = grid(4);
    let off = p.len() as u32;
    p.extend(p2.iter().map(|q| [q[0] + 10.0, q[1], q[2]]));
    idx.extend(idx2.iter().map(|i| i + off));
    let a = build_tree(&p, &idx, &VdtParams::default());
    let b = build_tree(&p, &idx, &VdtParams::default());
    a.validate().unwrap();
    assert_eq!(a, b);
    assert!(
        a.roots.len() >= 2,
        "two parts cannot merge along real edges"
    );
}

#[test]
fn meta_nodes_block_the_tree_and_round_trip() {
    use super::meta::{block, decode, encode, levels_for_block};
    let (p, idx) = grid(16);
    let t = build_tree(&p, &idx, &VdtParams::default());
    let l4k = levels_for_block(4096);
    assert!((4..=8).contains(&l4k), "L for 4 KiB blocks: {l4k}");
    for levels in [2, 3, l4k] {
        let m = block(&t, levels);
        m.validate(&t).unwrap();
        assert!(!m.roots.is_empty() && m.roots.len() <= t.roots.len());
        let files = encode(&t, &m);
        assert_eq!(files.mnt.len(), m.metas.len());
        for (i, rec) in files.mnt.iter().enumerate() {
            let bytes =
                &files.data[rec.offset as usize..(rec.offset + u64::from(rec.len)) as usize];
            let d = decode(bytes, rec).unwrap();
            let mm = &m.metas[i];
            assert_eq!(d.nodes.iter().map(|r| r.id).collect::<Vec<_>>(), mm.nodes);
            for r in &d.nodes {
                assert_eq!(r.node, t.nodes[r.id as usize]);
            }
            let tris: Vec<(u32, [u32; 3])> = mm
                .triangles
                .iter()
                .map(|&x| (x, t.triangles[x as usize]))
                .collect();
            assert_eq!(d.triangles, tris);
            for (id, xyz) in &d.leaves {
                assert_eq!(*xyz, t.positions[*id as usize]);
            }
            // A flipped byte or a cut payload is refused.
            let mut bad = bytes.to_vec();
            bad[bytes.len() / 2] ^= 0x40;
            assert!(decode(&bad, rec).is_err());
            assert!(decode(&bytes[..bytes.len() - 4], rec).is_err());
        }
    }
    // Deeper blocks mean fewer, larger meta-nodes.
    assert!(block(&t, 5).metas.len() < block(&t, 2).metas.len());
}
