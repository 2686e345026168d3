//! The node hierarchy walked in `f64`: world transforms, `EXT_mesh_gpu_instancing`
//! instances, cycles, and transforms that leave the representable range.

use std::sync::Arc;

use glam::{DMat4, DQuat, DVec3};

use super::access::{self, Buffers};
use super::doc::{Doc, Node};
use crate::mesh::Aabb;

/// Coordinates beyond this (in scene units) are taken as a broken
/// transform: no real model reaches a million kilometres.
pub const MAX_COORD: f64 = 1e9;
/// Most glTF nodes above an object that its description names.
pub const MAX_PARENTS: usize = 32;
/// Most placements (objects) one file may make.
pub const MAX_PLACEMENTS: usize = 20_000_000;

/// One placement of a mesh.
#[derive(Clone, Debug)]
pub struct Placement {
    pub mesh: usize,
    pub world: DMat4,
    /// The glTF node that places it, `None` when the file has no nodes.
    pub node: Option<usize>,
    /// Its index among the node's `EXT_mesh_gpu_instancing` instances.
    pub instance: Option<u32>,
    /// The nodes above `node` on the path the walk took, outermost first
    /// (shared by the placements under one parent).
    pub parents: Arc<[usize]>,
}

/// The local transform of a node (matrix, or T * R * S).
fn local(n: &Node) -> DMat4 {
    if let Some(m) = n.matrix {
        return DMat4::from_cols_array(&m);
    }
    let t = n.translation.map_or(DVec3::ZERO, DVec3::from);
    let s = n.scale.map_or(DVec3::ONE, DVec3::from);
    let r = n.rotation.map_or(DQuat::IDENTITY, |q| {
        let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
        if q.length_squared() > 0.0 {
            q.normalize()
        } else {
            DQuat::IDENTITY
        }
    });
    DMat4::from_scale_rotation_translation(s, r, t)
}

/// The per-instance transforms of `EXT_mesh_gpu_instancing` on node `i`.
fn instances(bufs: &Buffers, i: usize, n: &Node) -> Result<Option<Vec<DMat4>>, String> {
    let Some(ext) = &n.extensions.instancing else {
        return Ok(None);
    };
    let what = |e: String| format!("nodes[{i}].extensions.EXT_mesh_gpu_instancing: {e}");
    let get = |name: &str| ext.attributes.get(name).copied();
    let t = get("TRANSLATION")
        .map(|a| access::read_f32::<3>(bufs, a))
        .transpose()
        .map_err(what)?;
    let r = get("ROTATION")
        .map(|a| access::read_f32::<4>(bufs, a))
        .transpose()
        .map_err(what)?;
    let s = get("SCALE")
        .map(|a| access::read_f32::<3>(bufs, a))
        .transpose()
        .map_err(what)?;
    let counts: Vec<usize> = [t.as_ref().map(Vec::len), r.as_ref().map(Vec::len)]
        .into_iter()
        .chain([s.as_ref().map(Vec::len)])
        .flatten()
        .collect();
    let Some(&count) = counts.first() else {
        return Err(what("no TRANSLATION, ROTATION or SCALE attribute".into()));
    };
    if counts.iter().any(|&c| c != count) {
        return Err(what(format!("attributes of different counts {counts:?}")));
    }
    let v3 = |a: [f32; 3]| DVec3::new(a[0].into(), a[1].into(), a[2].into());
    Ok(Some(
        (0..count)
            .map(|k| {
                let tk = t.as_ref().map_or(DVec3::ZERO, |t| v3(t[k]));
                let sk = s.as_ref().map_or(DVec3::ONE, |s| v3(s[k]));
                let rk = r.as_ref().map_or(DQuat::IDENTITY, |r| {
                    let q = r[k].map(f64::from);
                    let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
                    if q.length_squared() > 0.0 {
                        q.normalize()
                    } else {
                        DQuat::IDENTITY
                    }
                });
                DMat4::from_scale_rotation_translation(sk, rk, tk)
            })
            .collect(),
    ))
}

/// Whether `world` places a mesh with local box `b` within range.
fn in_range(world: &DMat4, b: &Aabb) -> bool {
    if !world.is_finite() {
        return false;
    }
    b.corners().iter().all(|c| {
        let w = world.transform_point3(c.as_dvec3());
        w.is_finite() && w.abs().max_element() <= MAX_COORD
    })
}

/// Every placement of a usable mesh (`boxes[m]` is `Some` for those), in
/// scene order; a skipped node is a warning, a cycle an error.
pub fn place(
    doc: &Doc,
    bufs: &Buffers,
    boxes: &[Option<Aabb>],
    warnings: &mut Vec<String>,
) -> Result<Vec<Placement>, String> {
    let mut out = Vec::new();
    if doc.nodes.is_empty() {
        if !doc.meshes.is_empty() {
            warnings.push(format!(
                "the file has no nodes: each of its {} meshes placed once, untransformed",
                doc.meshes.len()
            ));
        }
        for (m, b) in boxes.iter().enumerate() {
            if b.is_some() {
                out.push(Placement {
                    mesh: m,
                    world: DMat4::IDENTITY,
                    node: None,
                    instance: None,
                    parents: Arc::from([]),
                });
            }
        }
        return Ok(out);
    }
    let n = doc.nodes.len();
    for (i, node) in doc.nodes.iter().enumerate() {
        if let Some(&c) = node.children.iter().find(|&&c| c >= n) {
            return Err(format!(
                "nodes[{i}].children: node {c} does not exist ({n} nodes)"
            ));
        }
        if let Some(m) = node.mesh.filter(|&m| m >= doc.meshes.len()) {
            return Err(format!(
                "nodes[{i}].mesh: mesh {m} does not exist ({} meshes)",
                doc.meshes.len()
            ));
        }
    }
    let roots = roots(doc, warnings)?;
    // A node with several parents is placed under each: count what the
    // walk would visit before walking (a DAG of 60 levels of two edges to
    // the next visits 2^60 nodes).
    let visits_needed = expansion(doc, &roots)?;
    if visits_needed > MAX_PLACEMENTS as u64 {
        return Err(format!(
            "the node hierarchy places nodes more than {MAX_PLACEMENTS} times (nodes shared \
             by several parents expand to {} placements)",
            if visits_needed == u64::MAX {
                "more than 2^64".to_string()
            } else {
                visits_needed.to_string()
            }
        ));
    }
    // Depth-first, with the nodes on the current path marked: a child on
    // the path is a cycle. A node with two parents is placed under each.
    enum Step {
        Enter(usize, DMat4, Arc<[usize]>),
        Leave(usize),
    }
    let mut on_path = vec![false; n];
    let mut stack: Vec<Step> = roots
        .iter()
        .rev()
        .map(|&r| Step::Enter(r, DMat4::IDENTITY, Arc::from([])))
        .collect();
    let mut visits = 0usize;
    while let Some(step) = stack.pop() {
        let (i, parent, parents) = match step {
            Step::Leave(i) => {
                on_path[i] = false;
                continue;
            }
            Step::Enter(i, p, up) => (i, p, up),
        };
        if on_path[i] {
            return Err(format!(
                "nodes[{i}] is its own ancestor: the node hierarchy has a cycle"
            ));
        }
        visits += 1;
        if visits > MAX_PLACEMENTS {
            return Err(format!(
                "the node hierarchy places more than {MAX_PLACEMENTS} nodes"
            ));
        }
        let node = &doc.nodes[i];
        let world = parent * local(node);
        if let Some(m) = node.mesh
            && let Some(b) = &boxes[m]
            && !degenerate(i, &world, warnings)
        {
            match instances(bufs, i, node)? {
                None => {
                    if in_range(&world, b) {
                        out.push(Placement {
                            mesh: m,
                            world,
                            node: Some(i),
                            instance: None,
                            parents: parents.clone(),
                        });
                    } else {
                        warnings.push(out_of_range(i, None, &world));
                    }
                }
                Some(list) => {
                    for (k, t) in list.iter().enumerate() {
                        let w = world * *t;
                        if in_range(&w, b) {
                            out.push(Placement {
                                mesh: m,
                                world: w,
                                node: Some(i),
                                instance: Some(k as u32),
                                parents: parents.clone(),
                            });
                        } else {
                            warnings.push(out_of_range(i, Some(k), &w));
                        }
                    }
                }
            }
            if out.len() > MAX_PLACEMENTS {
                return Err(format!("more than {MAX_PLACEMENTS} objects"));
            }
        }
        on_path[i] = true;
        stack.push(Step::Leave(i));
        if !node.children.is_empty() {
            // The outermost MAX_PARENTS are kept: a chain of a million
            // nodes must not write a million names per object.
            let below: Arc<[usize]> = if parents.len() < MAX_PARENTS {
                parents.iter().copied().chain([i]).collect()
            } else {
                parents.clone()
            };
            for &c in node.children.iter().rev() {
                stack.push(Step::Enter(c, world, below.clone()));
            }
        }
    }
    Ok(out)
}

/// Whether node `i`'s world transform collapses its mesh (a zero scale, a
/// zero or singular matrix: every triangle would land on a point, a line
/// or a plane); said as a warning naming the node, and the mesh skipped.
fn degenerate(i: usize, world: &DMat4, warnings: &mut Vec<String>) -> bool {
    let det = world.determinant();
    let scale = [world.x_axis, world.y_axis, world.z_axis]
        .map(|a| a.truncate().length())
        .into_iter()
        .fold(0.0f64, f64::max);
    // Relative to the largest axis: a tiny but uniform scale is fine.
    // A non-finite transform is refused elsewhere; only a finite one is judged here.
    let flat = world.is_finite() && (scale == 0.0 || det.abs() <= 1e-12 * scale.powi(3));
    if flat {
        warnings.push(format!(
            "nodes[{i}]: its transform is degenerate (determinant {det:.3e}: a zero scale or a \
             singular matrix collapses the mesh), skipped"
        ));
    }
    flat
}

/// How many node visits the walk from `roots` makes (a node shared by
/// several parents counts under each), saturating; a cycle is an error.
fn expansion(doc: &Doc, roots: &[usize]) -> Result<u64, String> {
    const UNSEEN: u64 = u64::MAX - 1;
    const OPEN: u64 = u64::MAX - 2;
    let n = doc.nodes.len();
    let mut count = vec![UNSEEN; n];
    let mut stack: Vec<(usize, usize)> = Vec::new();
    let mut total = 0u64;
    for &r in roots {
        if count[r] == UNSEEN {
            count[r] = OPEN;
            stack.push((r, 0));
        }
        while let Some(top) = stack.last_mut() {
            let i = top.0;
            let children = &doc.nodes[i].children;
            if let Some(&c) = children.get(top.1) {
                top.1 += 1;
                match count[c] {
                    OPEN => {
                        return Err(format!(
                            "nodes[{c}] is its own ancestor: the node hierarchy has a cycle"
                        ));
                    }
                    UNSEEN => {
                        count[c] = OPEN;
                        stack.push((c, 0));
                    }
                    _ => {}
                }
                continue;
            }
            stack.pop();
            count[i] = children
                .iter()
                .fold(1u64, |s, &c| s.saturating_add(count[c]))
                .min(u64::MAX - 3);
        }
        total = total.saturating_add(count[r]);
    }
    Ok(total)
}

fn out_of_range(node: usize, instance: Option<usize>, world: &DMat4) -> String {
    let at = match instance {
        Some(k) => format!("nodes[{node}] instance {k}"),
        None => format!("nodes[{node}]"),
    };
    let scale = world
        .x_axis
        .truncate()
        .length()
        .max(world.y_axis.truncate().length());
    if world.is_finite() {
        format!(
            "{at}: its transform (scale {scale:.3e}, translation {:.3e}) places the mesh beyond \
             {MAX_COORD:.0e} units, skipped",
            world.w_axis.truncate().abs().max_element()
        )
    } else {
        format!("{at}: non-finite transform, skipped")
    }
}

/// The root nodes: the default scene's (or the first scene's); all
/// parentless nodes when there is no scene or it lists none.
fn roots(doc: &Doc, warnings: &mut Vec<String>) -> Result<Vec<usize>, String> {
    let n = doc.nodes.len();
    let chosen = doc.scene.or((!doc.scenes.is_empty()).then_some(0));
    if let Some(s) = chosen {
        let scene = doc.scenes.get(s).ok_or_else(|| {
            format!(
                "scene: scenes[{s}] does not exist ({} scenes)",
                doc.scenes.len()
            )
        })?;
        if let Some(&r) = scene.nodes.iter().find(|&&r| r >= n) {
            return Err(format!(
                "scenes[{s}].nodes: node {r} does not exist ({n} nodes)"
            ));
        }
        if !scene.nodes.is_empty() {
            return Ok(scene.nodes.clone());
        }
        warnings.push(format!(
            "scenes[{s}] lists no nodes: every node without a parent is used"
        ));
    }
    let mut is_child = vec![false; n];
    for node in &doc.nodes {
        for &c in &node.children {
            is_child[c] = true;
        }
    }
    Ok((0..n).filter(|&i| !is_child[i]).collect())
}
