//! Small synthetic scenes for unit tests.
#![allow(clippy::needless_range_loop)] // index loops mirror the breadth-first layout

use std::io::Cursor;

use crate::format::{NONE, NodeRecord, RepKind, RepMesh, RepRecord, SceneMeta, SceneWriter};
use crate::skeleton::Skeleton;

/// A quad (two triangles) spanning `min..max` in x/y at z = min.z.
pub fn quad(min: [f32; 3], max: [f32; 3]) -> RepMesh {
    let p = [
        [min[0], min[1], min[2]],
        [max[0], min[1], min[2]],
        [max[0], max[1], min[2]],
        [min[0], max[1], max[2]],
    ];
    RepMesh::quantize(
        &p,
        &[[0.0, 0.0, 1.0]; 4],
        &[[200, 100, 50, 255]; 4],
        vec![0, 1, 2, 0, 2, 3],
    )
}

/// Builds a scene from a shape: `rep_counts[i]` reps for node `i`, `children[i]`
/// the child count of node `i` (breadth-first). Leaf `k` spans `x in [k, k+1]`.
pub fn build(rep_counts: &[u32], children: &[u32]) -> (Vec<u8>, Skeleton) {
    build_with(rep_counts, children, [0.0; 3], &[])
}

/// [`build`] with the mesh payloads compressed
/// ([`RepMesh::encode_compressed`]).
pub fn build_compressed(rep_counts: &[u32], children: &[u32]) -> (Vec<u8>, Skeleton) {
    build_impl(rep_counts, children, [0.0; 3], &[], true)
}

/// [`build`] with an origin and an object section; when the section is not
/// empty, leaf `k` names object `k`.
pub fn build_with(
    rep_counts: &[u32],
    children: &[u32],
    origin: [f64; 3],
    objects: &[u8],
) -> (Vec<u8>, Skeleton) {
    build_impl(rep_counts, children, origin, objects, false)
}

fn build_impl(
    rep_counts: &[u32],
    children: &[u32],
    origin: [f64; 3],
    objects: &[u8],
    compress: bool,
) -> (Vec<u8>, Skeleton) {
    assert_eq!(rep_counts.len(), children.len());
    let n = rep_counts.len();
    let mut nodes = vec![NodeRecord::default(); n];
    let mut next = 1u32;
    for i in 0..n {
        nodes[i].first_child = if children[i] > 0 { next } else { 0 };
        nodes[i].child_count = children[i];
        nodes[i].parent = NONE;
        nodes[i].object = NONE;
        next += children[i];
    }
    for i in 0..n {
        for c in nodes[i].first_child..nodes[i].first_child + nodes[i].child_count {
            nodes[c as usize].parent = i as u32;
            nodes[c as usize].depth = nodes[i].depth + 1;
        }
    }
    // Boxes bottom-up (children come after parents).
    let mut leaf = 0f32;
    for i in 0..n {
        if nodes[i].child_count == 0 {
            nodes[i].bbox_min = [leaf, 0.0, 0.0];
            nodes[i].bbox_max = [leaf + 1.0, 1.0, 1.0];
            if !objects.is_empty() {
                nodes[i].object = leaf as u32;
            }
            leaf += 1.0;
        }
    }
    for i in (0..n).rev() {
        if nodes[i].child_count > 0 {
            let (f, c) = (nodes[i].first_child as usize, nodes[i].child_count as usize);
            let mut min = [f32::INFINITY; 3];
            let mut max = [f32::NEG_INFINITY; 3];
            for ch in &nodes[f..f + c] {
                for a in 0..3 {
                    min[a] = min[a].min(ch.bbox_min[a]);
                    max[a] = max[a].max(ch.bbox_max[a]);
                }
            }
            nodes[i].bbox_min = min;
            nodes[i].bbox_max = max;
        }
    }
    // Errors halve per rep and per level (at most 4 reps a node): strictly decreasing.
    let mut writer = SceneWriter::new(Cursor::new(Vec::new())).unwrap();
    let mut reps = Vec::new();
    for i in 0..n {
        nodes[i].first_rep = reps.len() as u32;
        nodes[i].rep_count = rep_counts[i];
        for r in 0..rep_counts[i] {
            let mesh = quad(nodes[i].bbox_min, nodes[i].bbox_max);
            let payload = if compress {
                mesh.encode_compressed(i as u32, r)
            } else {
                mesh.encode(i as u32, r)
            };
            let loc = writer.write_rep(&payload).unwrap();
            let kind = if nodes[i].child_count == 0 {
                RepKind::Lod
            } else {
                RepKind::Hlod
            };
            reps.push(RepRecord {
                bbox_min: nodes[i].bbox_min,
                bbox_max: nodes[i].bbox_max,
                node: i as u32,
                index: r as u16,
                kind: kind as u16,
                error: 10.0 * 0.5f32.powi((nodes[i].depth * 4 + r) as i32),
                checksum: loc.checksum,
                offset: loc.offset,
                len: loc.len,
                tri_count: mesh.tri_count() as u32,
                vertex_count: mesh.vertices.len() as u32,
                aux: 0,
            });
        }
    }
    let skeleton = Skeleton {
        nodes,
        reps,
        ..Skeleton::default()
    };
    let meta = SceneMeta {
        object_count: leaf as u32,
        input_triangles: 2 * leaf as u64,
        origin,
        source_key: [0; 16],
        drawn_triangles: 2 * leaf as u64,
        hidden_triangles: 0,
    };
    let bytes = writer
        .finish_with_objects(&skeleton, &meta, objects)
        .unwrap()
        .into_inner();
    (bytes, skeleton)
}

/// [`build`] with every leaf's levels shared (format version 6): leaf
/// `k`'s rep `r` places the payload of the first leaf's rep `r` (a unit
/// quad in its own coordinates) by a translation of `k` along x, so that
/// it draws what [`build`]'s does.
pub fn build_instanced(rep_counts: &[u32], children: &[u32]) -> (Vec<u8>, Skeleton) {
    let (bytes, plain) = build(rep_counts, children);
    let mut writer = SceneWriter::new(Cursor::new(Vec::new())).unwrap();
    let mut skeleton = plain.clone();
    let file = crate::format::SceneFile::from_source(crate::io::MemSource::new(bytes)).unwrap();
    let mut first_leaf: Option<u32> = None;
    for (i, n) in plain.nodes.iter().enumerate() {
        for r in n.first_rep..n.first_rep + n.rep_count {
            let loc = if !n.is_leaf() {
                writer.write_rep(&file.read_rep_bytes(r).unwrap()).unwrap()
            } else {
                let owner = *first_leaf.get_or_insert(i as u32);
                let index = r - n.first_rep;
                let source = plain.nodes[owner as usize].first_rep + index;
                let loc = if source == r {
                    let mesh = quad([0.0; 3], [1.0; 3]);
                    writer.write_rep(&mesh.encode(i as u32, index)).unwrap()
                } else {
                    let o = skeleton.reps[source as usize];
                    crate::format::RepLocation {
                        offset: o.offset,
                        len: o.len,
                        checksum: o.checksum,
                    }
                };
                let x = n.bbox_min[0];
                skeleton.placements.push(crate::records::RepPlacement {
                    rep: r,
                    source,
                    transform: [
                        [1.0, 0.0, 0.0, x],
                        [0.0, 1.0, 0.0, 0.0],
                        [0.0, 0.0, 1.0, 0.0],
                    ],
                });
                loc
            };
            let rec = &mut skeleton.reps[r as usize];
            (rec.offset, rec.len, rec.checksum) = (loc.offset, loc.len, loc.checksum);
        }
    }
    let meta = file.meta();
    let bytes = writer.finish(&skeleton, &meta).unwrap().into_inner();
    (bytes, skeleton)
}

/// Random tree shapes for [`build`]: (rep counts, child counts), breadth-first,
/// up to `max_nodes` nodes.
pub fn shape_strategy(
    max_nodes: usize,
) -> impl proptest::strategy::Strategy<Value = (Vec<u32>, Vec<u32>)> {
    use proptest::prelude::*;
    prop::collection::vec((0u32..4, 1u32..4), 1..max_nodes).prop_map(|spec| {
        let (mut children, mut reps, mut total) = (Vec::new(), Vec::new(), 1usize);
        for (i, (c, r)) in spec.iter().enumerate() {
            if i >= total {
                break;
            }
            let c = if total + (*c as usize) <= spec.len() {
                *c
            } else {
                0
            };
            total += c as usize;
            children.push(c);
            reps.push(*r);
        }
        while children.len() < total {
            children.push(0);
            reps.push(1);
        }
        (reps, children)
    })
}
