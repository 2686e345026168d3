//! Per-frame refinement of a view-dependence forest (El-Sana & Chiang
//! §3.3.1, §3.3.5), independent of where the tree lives.
//!
//! The *active nodes* are a cut of the forest; since leaves are numbered
//! depth-first they partition the leaf range, kept in `cut` (first leaf →
//! node). The *active triangles* are the permanent ones plus the adjacent
//! triangles of every node above the cut; each knows its three leaves and
//! its three active corners, and each active node its incident triangles.
//!
//! Once per frame every active node is visited (youngest first):
//! - **split** when its projected switch value exceeds the tolerance (it is
//!   visible and too coarse), its id is larger than every active
//!   neighbour's (implicit dependency; older neighbours are split first,
//!   recursively), and the store has its children and adjacent triangles;
//!   corners of its triangles go to the child whose leaf interval holds
//!   them, its adjacent triangles come back;
//! - **collapse** with its sibling when the parent's projected switch value
//!   is within tolerance (or the parent is outside the view), the sibling is
//!   active, and every active neighbour's parent is younger than the parent.
//!
//! The metric is evaluated on the node's bounding sphere (distance to the
//! sphere, and out-of-frustum spheres want no detail), which is monotone up
//! the tree, so a node never splits and collapses back on the same view.
//! A wanted switch the store cannot serve yet is a *miss*; the frame keeps
//! the level it has.

use std::collections::{BTreeMap, HashMap};

use glam::Vec3;

use super::file::VdtError;
use super::{NONE, VdNode};
use crate::camera::{Frustum, View};

/// A node with its position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placed {
    pub id: u32,
    pub node: VdNode,
    pub pos: Vec3,
}

/// Triangles as `(triangle id, leaf corners)`.
pub type TriList = Vec<(u32, [u32; 3])>;

/// Where the tree's nodes come from (in core, paged, or meta-node buffers).
/// `None` answers are misses: the store may start fetching what was asked.
pub trait NodeStore {
    /// The roots with their positions (the coarsest cut).
    fn roots(&mut self) -> Result<Vec<Placed>, VdtError>;
    /// The triangles no collapse removes: `(id, leaves)`.
    fn permanent(&mut self) -> Result<TriList, VdtError>;
    /// The children of `v` (for a split), with their positions.
    fn children(&mut self, v: &Placed) -> Result<Option<[Placed; 2]>, VdtError>;
    /// The parent record of `v` (for a collapse).
    fn parent(&mut self, v: &Placed) -> Result<Option<(u32, VdNode)>, VdtError>;
    /// The triangles `v`'s split adds (and its children's collapse removes).
    fn adjacent(&mut self, v: u32) -> Result<Option<TriList>, VdtError>;
    /// `v` joined or left the active nodes.
    fn activated(&mut self, v: u32);
    fn deactivated(&mut self, v: u32);
}

/// What one refinement pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PassStats {
    pub splits: u32,
    pub collapses: u32,
    pub misses: u32,
    /// Switches the implicit dependencies refused this pass.
    pub refused: u32,
}

impl PassStats {
    /// Splits plus collapses (the paper's *Adapt*).
    pub fn adapt(&self) -> u32 {
        self.splits + self.collapses
    }
}

#[derive(Clone, Debug)]
struct Active {
    node: VdNode,
    pos: Vec3,
    incident: Vec<u32>,
    /// The parent's record once known (from the split that made this node,
    /// or fetched once for a collapse test): the per-frame collapse tests
    /// then need no store access.
    parent: Option<VdNode>,
}

#[derive(Clone, Copy, Debug)]
struct Tri {
    leaves: [u32; 3],
    nodes: [u32; 3],
}

/// How deep a chain of forced splits may go.
const MAX_FORCED: u32 = 64;

/// The screen-space criterion: a node wants more detail when its sphere
/// is in the frustum and its switch value projects above `tolerance_px`.
#[derive(Clone, Copy, Debug)]
pub struct Criterion {
    pub view: View,
    pub frustum: Frustum,
    pub tolerance_px: f32,
}

impl Criterion {
    pub fn new(view: View, tolerance_px: f32) -> Self {
        Self {
            view,
            frustum: view.frustum(0.0),
            tolerance_px,
        }
    }

    /// Whether `node` at `pos` is too coarse for this view.
    pub fn wants_detail(&self, node: &VdNode, pos: Vec3) -> bool {
        let r = Vec3::splat(node.radius);
        if !self.frustum.intersects(pos - r, pos + r) {
            return false;
        }
        let d = (pos.distance(self.view.pose.position) - node.radius).max(self.view.near);
        self.view.projected(node.switch, d) > self.tolerance_px
    }
}

/// Active nodes and triangles of one forest.
#[derive(Debug, Default)]
pub struct Refiner {
    active: BTreeMap<u32, Active>,
    cut: BTreeMap<u32, u32>,
    tris: HashMap<u32, Tri>,
}

impl Refiner {
    /// Starts at the roots (the coarsest level).
    pub fn new(store: &mut dyn NodeStore) -> Result<Self, VdtError> {
        let mut r = Self::default();
        for p in store.roots()? {
            r.insert(p, Vec::new(), None);
            store.activated(p.id);
        }
        for (t, leaves) in store.permanent()? {
            r.add_triangle(t, leaves)?;
        }
        Ok(r)
    }

    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Active node ids, ascending.
    pub fn active_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.active.keys().copied()
    }

    /// Active triangles as `(triangle id, leaves, corner positions)`,
    /// sorted by triangle id.
    pub fn triangles(&self) -> Vec<(u32, [u32; 3], [Vec3; 3])> {
        let mut v: Vec<_> = self
            .tris
            .iter()
            .map(|(&t, x)| (t, x.leaves, x.nodes.map(|n| self.active[&n].pos)))
            .collect();
        v.sort_unstable_by_key(|x| x.0);
        v
    }

    /// The cut as an indexed mesh: one vertex per active node (ascending
    /// id), triangles sorted by triangle id — shared corners stay shared.
    pub fn indexed_mesh(&self) -> (Vec<Vec3>, Vec<u32>) {
        let ids: Vec<u32> = self.active.keys().copied().collect();
        let positions = self.active.values().map(|a| a.pos).collect();
        let mut tris: Vec<(u32, [u32; 3])> = self.tris.iter().map(|(&t, x)| (t, x.nodes)).collect();
        tris.sort_unstable_by_key(|x| x.0);
        let slot = |n: u32| ids.binary_search(&n).map_or(0, |i| i as u32);
        let indices = tris.iter().flat_map(|(_, c)| c.map(slot)).collect();
        (positions, indices)
    }

    /// One pass over the active nodes.
    pub fn pass(
        &mut self,
        store: &mut dyn NodeStore,
        c: &Criterion,
    ) -> Result<PassStats, VdtError> {
        let mut st = PassStats::default();
        // Youngest first: a split needs the node to be younger than its
        // neighbours, so splitting them in this order lets a refinement
        // cascade within one pass.
        let ids: Vec<u32> = self.active.keys().rev().copied().collect();
        for id in ids {
            let Some(a) = self.active.get(&id) else {
                continue; // collapsed with its sibling earlier in this pass
            };
            let v = Placed {
                id,
                node: a.node,
                pos: a.pos,
            };
            if v.node.left != NONE && c.wants_detail(&v.node, v.pos) {
                self.try_split(store, &v, &mut st, 0)?;
            } else if v.node.parent != NONE && !c.wants_detail(&v.node, v.pos) {
                self.try_collapse(store, c, &v, &mut st)?;
            }
        }
        Ok(st)
    }

    /// Passes until nothing changes (or `max_passes`): the settled cut.
    pub fn settle(
        &mut self,
        store: &mut dyn NodeStore,
        c: &Criterion,
        max_passes: usize,
    ) -> Result<PassStats, VdtError> {
        let mut total = PassStats::default();
        for _ in 0..max_passes {
            let s = self.pass(store, c)?;
            total.splits += s.splits;
            total.collapses += s.collapses;
            total.misses += s.misses;
            total.refused += s.refused;
            if s.adapt() == 0 {
                break;
            }
        }
        Ok(total)
    }

    fn neighbours(&self, v: u32) -> impl Iterator<Item = u32> + '_ {
        self.active[&v]
            .incident
            .iter()
            .flat_map(move |t| self.tris[t].nodes)
            .filter(move |&n| n != v)
    }

    fn try_split(
        &mut self,
        store: &mut dyn NodeStore,
        v: &Placed,
        st: &mut PassStats,
        depth: u32,
    ) -> Result<bool, VdtError> {
        // Implicit dependency: v is younger than all its active neighbours.
        // An older neighbour is split first (a forced split, as in Hoppe's
        // view-dependent meshes), else v would wait for it forever when that
        // neighbour itself is fine for the view.
        while let Some(u) = self.neighbours(v.id).filter(|&n| n > v.id).max() {
            let a = &self.active[&u];
            let pu = Placed {
                id: u,
                node: a.node,
                pos: a.pos,
            };
            if depth >= MAX_FORCED || !self.try_split(store, &pu, st, depth + 1)? {
                st.refused += 1;
                return Ok(false);
            }
        }
        let Some([l, r]) = store.children(v)? else {
            st.misses += 1;
            return Ok(false);
        };
        let Some(adj) = store.adjacent(v.id)? else {
            st.misses += 1;
            return Ok(false);
        };
        if l.node.leaf != v.node.leaf || r.node.leaf != l.node.leaf_end {
            return Err(VdtError::Corrupt(format!(
                "node {}: children's leaf intervals",
                v.id
            )));
        }
        // Children first, so v's meta-node never looks unused in between.
        store.activated(l.id);
        store.activated(r.id);
        store.deactivated(v.id);
        let a = self.remove(v.id);
        self.insert(l, Vec::new(), Some(v.node));
        self.insert(r, Vec::new(), Some(v.node));
        for t in a.incident {
            let tri = self.tris.get_mut(&t).expect("incident triangle is active");
            let k = (0..3).find(|&k| tri.nodes[k] == v.id).expect("corner");
            let to = if tri.leaves[k] >= r.node.leaf {
                r.id
            } else {
                l.id
            };
            tri.nodes[k] = to;
            self.active.get_mut(&to).expect("child").incident.push(t);
        }
        for (t, leaves) in adj {
            self.add_triangle(t, leaves)?;
        }
        st.splits += 1;
        Ok(true)
    }

    fn try_collapse(
        &mut self,
        store: &mut dyn NodeStore,
        c: &Criterion,
        v: &Placed,
        st: &mut PassStats,
    ) -> Result<(), VdtError> {
        let pid = v.node.parent;
        let p = match self.active[&v.id].parent {
            Some(p) => p,
            None => {
                let Some((_, p)) = store.parent(v)? else {
                    st.misses += 1;
                    return Ok(());
                };
                self.active.get_mut(&v.id).expect("active").parent = Some(p);
                p
            }
        };
        let sib = if p.left == v.id { p.right } else { p.left };
        let Some(left) = self.active.get(&p.left) else {
            return Ok(()); // the sibling's subtree is refined further
        };
        let ppos = left.pos;
        if !self.active.contains_key(&sib) || c.wants_detail(&p, ppos) {
            return Ok(());
        }
        // Implicit dependency: every active neighbour's parent is younger.
        let blocked = [p.left, p.right].iter().any(|&x| {
            self.neighbours(x)
                .filter(|&n| n != p.left && n != p.right)
                .any(|n| self.active[&n].node.parent <= pid)
        });
        if blocked {
            st.refused += 1;
            return Ok(());
        }
        let Some(adj) = store.adjacent(pid)? else {
            st.misses += 1;
            return Ok(());
        };
        for (t, _) in &adj {
            if let Some(tri) = self.tris.remove(t) {
                for n in tri.nodes {
                    if let Some(a) = self.active.get_mut(&n) {
                        a.incident.retain(|x| x != t);
                    }
                }
            }
        }
        store.activated(pid);
        store.deactivated(p.left);
        store.deactivated(p.right);
        let a = self.remove(p.left);
        let b = self.remove(p.right);
        let mut incident = a.incident;
        incident.extend(b.incident);
        for &t in &incident {
            let tri = self.tris.get_mut(&t).expect("incident triangle is active");
            for n in &mut tri.nodes {
                if *n == p.left || *n == p.right {
                    *n = pid;
                }
            }
        }
        self.insert(
            Placed {
                id: pid,
                node: p,
                pos: ppos,
            },
            incident,
            None,
        );
        st.collapses += 1;
        Ok(())
    }

    fn insert(&mut self, p: Placed, incident: Vec<u32>, parent: Option<VdNode>) {
        self.cut.insert(p.node.leaf, p.id);
        self.active.insert(
            p.id,
            Active {
                node: p.node,
                pos: p.pos,
                incident,
                parent,
            },
        );
    }

    fn remove(&mut self, id: u32) -> Active {
        let a = self.active.remove(&id).expect("active node");
        self.cut.remove(&a.node.leaf);
        a
    }

    /// The active node whose leaf interval holds `leaf`.
    fn owner(&self, leaf: u32) -> Option<u32> {
        let (_, &n) = self.cut.range(..=leaf).next_back()?;
        (leaf < self.active[&n].node.leaf_end).then_some(n)
    }

    fn add_triangle(&mut self, t: u32, leaves: [u32; 3]) -> Result<(), VdtError> {
        let mut nodes = [NONE; 3];
        for k in 0..3 {
            nodes[k] = self.owner(leaves[k]).ok_or_else(|| {
                VdtError::Corrupt(format!("triangle {t}: leaf {} not covered", leaves[k]))
            })?;
        }
        if nodes[0] == nodes[1] || nodes[1] == nodes[2] || nodes[0] == nodes[2] {
            return Err(VdtError::Corrupt(format!(
                "triangle {t} degenerate when added"
            )));
        }
        for n in nodes {
            self.active.get_mut(&n).expect("owner").incident.push(t);
        }
        self.tris.insert(t, Tri { leaves, nodes });
        Ok(())
    }
}

/// The whole forest in core: every answer is immediate (the in-core mode,
/// and the reference the paged stores are tested against).
impl NodeStore for super::VdTree {
    fn roots(&mut self) -> Result<Vec<Placed>, VdtError> {
        Ok(self.roots.iter().map(|&r| self.placed(r)).collect())
    }

    fn permanent(&mut self) -> Result<TriList, VdtError> {
        Ok(self
            .permanent
            .iter()
            .map(|&t| (t, self.triangles[t as usize]))
            .collect())
    }

    fn children(&mut self, v: &Placed) -> Result<Option<[Placed; 2]>, VdtError> {
        Ok(Some([self.placed(v.node.left), self.placed(v.node.right)]))
    }

    fn parent(&mut self, v: &Placed) -> Result<Option<(u32, VdNode)>, VdtError> {
        Ok(Some((v.node.parent, self.nodes[v.node.parent as usize])))
    }

    fn adjacent(&mut self, v: u32) -> Result<Option<TriList>, VdtError> {
        let n = self.leaf_count();
        Ok(Some(
            self.adjacent[v as usize - n]
                .iter()
                .map(|&t| (t, self.triangles[t as usize]))
                .collect(),
        ))
    }

    fn activated(&mut self, _: u32) {}
    fn deactivated(&mut self, _: u32) {}
}

impl super::VdTree {
    fn placed(&self, id: u32) -> Placed {
        let node = self.nodes[id as usize];
        Placed {
            id,
            node,
            pos: Vec3::from(self.positions[node.leaf as usize]),
        }
    }
}
