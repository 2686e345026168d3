//! Making nodes: a set of leaves (their LOD chains, trees and runs), then
//! interior nodes (HLODs from their children's coarsest reps), written to
//! the scene as they are made. Which nodes and in what groups is the
//! caller's choice (cell by cell); a node's reps depend only on its own
//! subtree, so the output does not.

use std::io::{Seek, Write};

use engine::FormatError;
use engine::format::objects::Run;
use engine::format::{NodeRecord, RepKind, RepMesh, RepRecord, SceneWriter};
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::leaf::{Item, item_object, leaf_levels, runs_of};
use super::source::{CellGeometry, SceneSource};
use super::{BuildParams, BuildStats, Report};
use crate::cluster::TreeNode;
use crate::lod::{Level, hlod, strictly_above};
use crate::mesh::{Aabb, Mesh};

/// A finished node's coarsest rep, kept for its parent's HLOD.
pub(super) struct Coarse {
    pub mesh: Mesh,
    pub error: f32,
}

/// What a leaf has besides its chain: its tree or MT, and its runs.
type LeafExtras = (Option<crate::vdt::TreeRep>, Option<Vec<Run>>);

/// LOD chains of meshes placed by several single-instance leaves, by mesh.
pub(super) type Chains = Vec<(usize, Vec<Level>)>;

/// Repeated leaves ([`super::groups`]): how each places its group's chain,
/// and each group's chain with its instances' triangle counts (the runs of
/// a merged leaf's finest level; empty for a single instance).
#[derive(Default)]
pub(super) struct Groups {
    pub places: std::collections::BTreeMap<usize, super::groups::LeafPlace>,
    /// Each group's owning node ([`super::groups::GroupPlan::owner`]).
    pub owners: Vec<u32>,
    pub chains: Vec<(Vec<Level>, Vec<u32>)>,
}

/// The scene being assembled: records so far, coarse reps awaiting their
/// parents, and the writer.
pub(super) struct Assembly<'a, W: Write + Seek> {
    pub writer: SceneWriter<W>,
    pub tree: &'a [TreeNode],
    pub items: &'a [Item],
    pub params: &'a BuildParams,
    pub chains: &'a Chains,
    pub groups: &'a Groups,
    pub nodes: Vec<NodeRecord>,
    pub node_reps: Vec<Vec<RepRecord>>,
    pub coarse: Vec<Option<Coarse>>,
    pub leaf_runs: Vec<(u32, Vec<Run>)>,
    pub stats: &'a mut BuildStats,
    pub bar: ProgressBar,
    pub report: Report<'a>,
    pub done: u64,
    /// Leaves made at once (in parallel, their results held until written).
    pub batch: usize,
    /// The groups' chains written so far ([`super::placed`]), by group.
    pub written: std::collections::BTreeMap<usize, super::placed::Written>,
    /// The placements made so far, by node.
    pub pending: Vec<super::placed::Pending>,
}

/// A leaf as made in the parallel part.
enum Made {
    Own(Encoded, LeafExtras),
    Placed(super::placed::PlacedLeaf),
}

fn chain_of(chains: &Chains, m: usize) -> Option<&Vec<Level>> {
    chains
        .binary_search_by_key(&m, |(k, _)| *k)
        .ok()
        .map(|k| &chains[k].1)
}

impl<W: Write + Seek> Assembly<'_, W> {
    /// Makes and writes `leaves`, `batch` at a time, loading each batch's
    /// geometry from `src` (and dropping it) as it goes.
    pub fn leaves<S: SceneSource>(&mut self, src: &S, leaves: &[usize]) -> Result<(), FormatError> {
        let total = self.tree.len() as u64;
        for batch in leaves.chunks(self.batch.max(1)) {
            let (tree, items, chains, params) = (self.tree, self.items, self.chains, self.params);
            let geo = CellGeometry::load(
                src,
                batch
                    .iter()
                    .flat_map(|&i| tree[i].items.iter().map(|&k| &items[k as usize])),
                self.params,
            )?;
            let lod = (RepKind::Lod, params.compress_reps);
            let groups = self.groups;
            let made: Vec<Made> = batch
                .par_iter()
                .map(|&i| {
                    if let Some(p) = groups.places.get(&i) {
                        let g = p.group as usize;
                        return Made::Placed(super::placed::PlacedLeaf::new(
                            g,
                            &groups.chains[g].0,
                            p.frame,
                            p.deviation,
                        ));
                    }
                    let (levels, vdt, runs) =
                        leaf_levels(&tree[i].items, items, &geo, params, &|m| {
                            chain_of(chains, m)
                        });
                    Made::Own(encode_chain(i as u32, levels, lod, 0.0), (vdt, runs))
                })
                .collect();
            drop(geo);
            for (&i, made) in batch.iter().zip(made) {
                match made {
                    Made::Own(enc, (vdt, runs)) => self.leaf(i, enc, vdt, runs)?,
                    Made::Placed(p) => self.placed_leaf(i, p)?,
                }
            }
            (self.report)("leaf LODs", self.done, total);
        }
        Ok(())
    }

    /// A leaf placing a shared chain: the chain's payloads written if this
    /// is its first leaf, the leaf's records and placements made.
    fn placed_leaf(&mut self, i: usize, p: super::placed::PlacedLeaf) -> Result<(), FormatError> {
        use super::placed::{Pending, Written};
        let (chain, tris) = &self.groups.chains[p.group];
        if !self.written.contains_key(&p.group) {
            // Written by the first leaf made, in the owner's name.
            let owner = self.groups.owners[p.group];
            let lod = (RepKind::Lod, self.params.compress_reps);
            let enc = encode_chain(owner, chain.clone(), lod, 0.0);
            let (recs, _) = write_chain(&mut self.writer, enc)?;
            self.written.insert(p.group, Written { owner, recs });
        }
        let w = &self.written[&p.group];
        let recs = p.records(i as u32, &w.recs);
        let rows = p.rows();
        for index in 0..recs.len() as u16 {
            self.pending.push(Pending {
                node: i as u32,
                index,
                owner: w.owner,
                rows,
            });
        }
        // A merged leaf: its own objects' runs, in the chain's order.
        let runs = (!tris.is_empty()).then(|| {
            let order = &self.groups.places[&i].order;
            runs_of(
                (order.iter().zip(tris)).map(|(&k, &t)| (item_object(&self.items[k as usize]), t)),
            )
        });
        let coarse = Coarse {
            mesh: p.coarse,
            error: recs[0].error,
        };
        self.finish_leaf(i, recs, coarse, runs);
        Ok(())
    }

    /// A leaf's node: its objects, flags and runs, box and colour, its
    /// records and its coarsest level kept for its parent.
    fn finish_leaf(&mut self, i: usize, recs: Vec<RepRecord>, c: Coarse, runs: Option<Vec<Run>>) {
        if let Some(r) = runs {
            self.leaf_runs.push((i as u32, r));
        }
        let items = &self.tree[i].items;
        let n = &mut self.nodes[i];
        n.object_count = items.len() as u32;
        if let [k] = items.as_slice() {
            n.object = item_object(&self.items[*k as usize]);
            if matches!(self.items[*k as usize], Item::Chunk { .. }) {
                n.flags |= NodeRecord::FLAG_CHUNK;
            }
        } else {
            n.flags |= NodeRecord::FLAG_MERGED;
        }
        finish_node(&mut self.nodes[i], &recs, &c.mesh, &[]);
        self.node_reps[i] = recs;
        self.coarse[i] = Some(c);
        self.bar.inc(1);
        self.done += 1;
    }

    fn leaf(
        &mut self,
        i: usize,
        enc: Encoded,
        vdt: Option<crate::vdt::TreeRep>,
        runs: Option<Vec<Run>>,
    ) -> Result<(), FormatError> {
        let (mut recs, c) = write_chain(&mut self.writer, enc)?;
        if let Some(t) = vdt {
            if t.kind == RepKind::Mt {
                self.stats.mt_objects += 1;
            } else {
                self.stats.vdt_objects += 1;
            }
            recs.push(crate::vdt::write_rep(
                &mut self.writer,
                i as u32,
                &recs,
                &t,
            )?);
        }
        self.finish_leaf(i, recs, c, runs);
        Ok(())
    }

    /// Makes and writes interior `nodes` (deepest first: every child is
    /// done before its parent), 32 at a time within one depth.
    pub fn interior(&mut self, nodes: &[usize]) -> Result<(), FormatError> {
        let total = self.tree.len() as u64;
        let tree = self.tree;
        for level in nodes.chunk_by(|&a, &b| tree[a].depth == tree[b].depth) {
            for batch in level.chunks(32) {
                let inputs: Vec<(Mesh, f32)> = batch
                    .iter()
                    .map(|&i| {
                        let kids: Vec<&Coarse> = tree[i]
                            .children
                            .iter()
                            .map(|&c| {
                                self.coarse[c as usize]
                                    .as_ref()
                                    .expect("children done first")
                            })
                            .collect();
                        let merged = Mesh::merge(kids.iter().map(|k| &k.mesh));
                        let floor = kids.iter().map(|k| k.error).fold(0.0, f32::max);
                        (merged, floor)
                    })
                    .collect();
                let params = self.params;
                let made: Vec<Encoded> = inputs
                    .into_par_iter()
                    .zip(batch)
                    .map(|((merged, floor), &i)| {
                        let budget = ((merged.tri_count() as f32 * params.hlod_ratio) as usize)
                            .clamp(
                                params.lod.min_tris.min(merged.tri_count()),
                                params.hlod_tris,
                            );
                        let (mesh, e) = hlod(&merged, budget);
                        let level = Level {
                            mesh,
                            error: floor + e,
                        };
                        encode_chain(
                            i as u32,
                            vec![level],
                            (RepKind::Hlod, params.compress_reps),
                            floor,
                        )
                    })
                    .collect();
                for (&i, enc) in batch.iter().zip(made) {
                    self.hlod_node(i, enc)?;
                }
                (self.report)("HLODs", self.done, total);
            }
        }
        Ok(())
    }

    fn hlod_node(&mut self, i: usize, enc: Encoded) -> Result<(), FormatError> {
        let (recs, c) = write_chain(&mut self.writer, enc)?;
        let children = &self.tree[i].children;
        let child_boxes: Vec<([f32; 3], [f32; 3])> = children
            .iter()
            .map(|&ch| {
                (
                    self.nodes[ch as usize].bbox_min,
                    self.nodes[ch as usize].bbox_max,
                )
            })
            .collect();
        self.nodes[i].object_count = children
            .iter()
            .map(|&ch| self.nodes[ch as usize].object_count)
            .sum();
        finish_node(&mut self.nodes[i], &recs, &c.mesh, &child_boxes);
        self.node_reps[i] = recs;
        self.coarse[i] = Some(c);
        for &ch in children {
            self.coarse[ch as usize] = None;
        }
        self.bar.inc(1);
        self.done += 1;
        Ok(())
    }
}

/// A node's levels encoded (coarsest first) and not yet written: the work
/// of [`write_chain`] that needs no writer, done in the parallel part.
pub(super) struct Encoded {
    /// Records with everything but where the payload lies (offset, length,
    /// checksum: filled in when written).
    recs: Vec<RepRecord>,
    payloads: Vec<Vec<u8>>,
    coarse: Coarse,
}

/// Encodes a node's levels (coarsest first), compressed or not; `floor` is
/// an error every rep must exceed (the children's for an HLOD).
pub(super) fn encode_chain(
    node: u32,
    levels: Vec<Level>,
    (kind, compress): (RepKind, bool),
    floor: f32,
) -> Encoded {
    let n = levels.len();
    let mut recs = vec![RepRecord::default(); n];
    let mut payloads = vec![Vec::new(); n];
    let mut below = if kind == RepKind::Hlod {
        Some(floor)
    } else {
        None
    };
    // Finest first, so each coarser error is made strictly larger.
    for (i, level) in levels.iter().enumerate().rev() {
        let m = &level.mesh;
        let packed = RepMesh::quantize(&m.positions, &m.normals, &m.colors, m.indices.clone());
        let raw = level.error + packed.quantization_error();
        let error = match below {
            Some(b) => strictly_above(b, raw),
            None => raw,
        };
        below = Some(error);
        payloads[i] = if compress {
            packed.encode_compressed(node, i as u32)
        } else {
            packed.encode(node, i as u32)
        };
        let (bbox_min, bbox_max) = m.bounds().to_arrays();
        recs[i] = RepRecord {
            bbox_min,
            bbox_max,
            node,
            index: i as u16,
            kind: kind as u16,
            error,
            tri_count: m.tri_count() as u32,
            vertex_count: m.vertex_count() as u32,
            ..RepRecord::default()
        };
    }
    let first = levels.into_iter().next().expect("at least one level");
    let error = recs[0].error;
    Encoded {
        recs,
        payloads,
        coarse: Coarse {
            mesh: first.mesh,
            error,
        },
    }
}

/// Writes an encoded chain, finest first (as it was encoded); returns the
/// records (coarsest first) and the coarsest level.
fn write_chain<W: Write + Seek>(
    writer: &mut SceneWriter<W>,
    enc: Encoded,
) -> Result<(Vec<RepRecord>, Coarse), FormatError> {
    let Encoded {
        mut recs,
        payloads,
        coarse,
    } = enc;
    for (rec, payload) in recs.iter_mut().zip(&payloads).rev() {
        let loc = writer.write_rep(payload)?;
        rec.checksum = loc.checksum;
        rec.offset = loc.offset;
        rec.len = loc.len;
    }
    Ok((recs, coarse))
}

/// Box and colour of a node from its reps and children.
fn finish_node(
    n: &mut NodeRecord,
    reps: &[RepRecord],
    color_mesh: &Mesh,
    child_boxes: &[([f32; 3], [f32; 3])],
) {
    let mut b = Aabb::EMPTY;
    for r in reps {
        b.add(r.bbox_min.into());
        b.add(r.bbox_max.into());
    }
    for (mn, mx) in child_boxes {
        b.add((*mn).into());
        b.add((*mx).into());
    }
    (n.bbox_min, n.bbox_max) = b.to_arrays();
    n.color = u32::from_le_bytes(color_mesh.dominant_color());
}
