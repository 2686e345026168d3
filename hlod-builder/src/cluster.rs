//! Scene-graph topology by spatial clustering.
//!
//! A binary BVH over the leaf items' boxes (obvhs, PLOC) is regrouped into a
//! tree of the requested branching factor: each node takes its BVH children and
//! keeps opening the heaviest (by triangles) inner one until it has `branching`
//! children. A BVH subtree with at most `leaf_tris` triangles becomes one leaf
//! that merges its items (many tiny objects make one drawable leaf).

use std::collections::VecDeque;
use std::time::Duration;

use glam::Vec3A;
use obvhs::{BvhBuildParams, aabb::Aabb as BvhAabb, bvh2::builder::build_bvh2};

use crate::mesh::Aabb;

/// A leaf candidate: an object or a chunk of one.
#[derive(Clone, Copy, Debug)]
pub struct ClusterItem {
    pub bounds: Aabb,
    pub tris: usize,
}

/// A scene-graph node, in breadth-first order (root first).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TreeNode {
    pub parent: Option<u32>,
    pub depth: u32,
    pub children: Vec<u32>,
    /// Items of a leaf (empty for interior nodes).
    pub items: Vec<u32>,
}

enum Proto {
    Leaf(Vec<u32>),
    Inner(Vec<Proto>),
}

/// Builds the scene-graph topology over `items`.
pub fn cluster(items: &[ClusterItem], branching: usize, leaf_tris: usize) -> Vec<TreeNode> {
    assert!(!items.is_empty(), "cluster needs at least one item");
    let boxes: Vec<BvhAabb> = items
        .iter()
        .map(|it| BvhAabb::new(Vec3A::from(it.bounds.min), Vec3A::from(it.bounds.max)))
        .collect();
    let mut params = BvhBuildParams::fastest_build();
    params.max_prims_per_leaf = 1;
    let mut build_time = Duration::ZERO;
    let bvh = build_bvh2(&boxes, params, &mut build_time);
    // Post-order triangle sums per BVH node.
    let n = bvh.nodes.len();
    let mut tris = vec![0usize; n];
    let mut order = Vec::with_capacity(n);
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        order.push(i);
        let node = &bvh.nodes[i];
        if !node.is_leaf() {
            stack.push(node.first_index as usize);
            stack.push(node.first_index as usize + 1);
        }
    }
    for &i in order.iter().rev() {
        let node = &bvh.nodes[i];
        tris[i] = if node.is_leaf() {
            prims(&bvh, i).iter().map(|&p| items[p as usize].tris).sum()
        } else {
            tris[node.first_index as usize] + tris[node.first_index as usize + 1]
        };
    }
    let proto = convert(&bvh, 0, &tris, branching.max(2), leaf_tris);
    flatten(proto)
}

fn prims(bvh: &obvhs::bvh2::Bvh2, i: usize) -> Vec<u32> {
    let node = &bvh.nodes[i];
    let f = node.first_index as usize;
    bvh.primitive_indices[f..f + node.prim_count as usize].to_vec()
}

fn all_prims(bvh: &obvhs::bvh2::Bvh2, i: usize, out: &mut Vec<u32>) {
    let node = &bvh.nodes[i];
    if node.is_leaf() {
        out.extend(prims(bvh, i));
    } else {
        all_prims(bvh, node.first_index as usize, out);
        all_prims(bvh, node.first_index as usize + 1, out);
    }
}

fn convert(
    bvh: &obvhs::bvh2::Bvh2,
    i: usize,
    tris: &[usize],
    branching: usize,
    leaf_tris: usize,
) -> Proto {
    let node = &bvh.nodes[i];
    if node.is_leaf() || tris[i] <= leaf_tris {
        let mut p = Vec::new();
        all_prims(bvh, i, &mut p);
        p.sort_unstable();
        return Proto::Leaf(p);
    }
    let opens = |j: usize| !bvh.nodes[j].is_leaf() && tris[j] > leaf_tris;
    let mut frontier = vec![node.first_index as usize, node.first_index as usize + 1];
    while frontier.len() < branching {
        let pick = frontier
            .iter()
            .enumerate()
            .filter(|&(_, &j)| opens(j))
            .max_by(|a, b| tris[*a.1].cmp(&tris[*b.1]).then(b.0.cmp(&a.0)))
            .map(|(k, _)| k);
        let Some(k) = pick else { break };
        let j = frontier.remove(k);
        let f = bvh.nodes[j].first_index as usize;
        frontier.insert(k, f + 1);
        frontier.insert(k, f);
    }
    Proto::Inner(
        frontier
            .into_iter()
            .map(|j| convert(bvh, j, tris, branching, leaf_tris))
            .collect(),
    )
}

fn flatten(root: Proto) -> Vec<TreeNode> {
    let mut out: Vec<TreeNode> = Vec::new();
    let mut queue = VecDeque::from([(root, None::<u32>, 0u32)]);
    while let Some((proto, parent, depth)) = queue.pop_front() {
        let id = out.len() as u32;
        if let Some(p) = parent {
            out[p as usize].children.push(id);
        }
        match proto {
            Proto::Leaf(items) => out.push(TreeNode {
                parent,
                depth,
                children: Vec::new(),
                items,
            }),
            Proto::Inner(kids) => {
                out.push(TreeNode {
                    parent,
                    depth,
                    children: Vec::new(),
                    items: Vec::new(),
                });
                for k in kids {
                    queue.push_back((k, Some(id), depth + 1));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn items(n: usize, tris: usize) -> Vec<ClusterItem> {
        (0..n)
            .map(|i| {
                let p = Vec3::new((i % 10) as f32 * 3.0, (i / 10) as f32 * 3.0, 0.0);
                ClusterItem {
                    bounds: Aabb {
                        min: p,
                        max: p + Vec3::ONE,
                    },
                    tris,
                }
            })
            .collect()
    }

    #[test]
    fn every_item_in_exactly_one_leaf_and_branching_respected() {
        let nodes = cluster(&items(100, 500), 4, 0);
        let mut seen: Vec<u32> = nodes.iter().flat_map(|n| n.items.clone()).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..100).collect::<Vec<_>>());
        for (i, n) in nodes.iter().enumerate() {
            assert!(n.children.len() <= 4);
            assert!(n.children.is_empty() != n.items.is_empty());
            for &c in &n.children {
                assert_eq!(nodes[c as usize].parent, Some(i as u32));
                assert!(c as usize > i);
            }
        }
        // With branching 4, 100 leaves need at least 4 levels below the root.
        assert!(nodes.iter().map(|n| n.depth).max().unwrap() >= 3);
    }

    #[test]
    fn small_items_are_merged_into_leaves() {
        let nodes = cluster(&items(100, 10), 8, 200);
        let leaves: Vec<_> = nodes.iter().filter(|n| !n.items.is_empty()).collect();
        assert!(leaves.len() < 100 && leaves.len() >= 5);
        assert!(leaves.iter().all(|l| l.items.len() * 10 <= 200));
        let single = cluster(&items(1, 10), 8, 0);
        assert_eq!(single.len(), 1);
        assert_eq!(single[0].items, vec![0]);
    }
}
