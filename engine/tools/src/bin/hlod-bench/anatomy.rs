//! `--anatomy`: where a front's triangles go (issue 45's diagnosis). For
//! each tolerance, the front of every frame of the path (the view's own
//! frustum, as P_R draws it) is counted: reps, triangles, resident bytes,
//! the share in HLODs and the depth in the hierarchy where refinement
//! stopped. Every `every`-th frame is also rasterised on the CPU at the
//! view's resolution (one sample per pixel centre, the front's own depth
//! buffer): a triangle that owns a pixel at the end is visible, one that
//! covered samples but owns none is hidden, one that covers no pixel centre
//! is unsampled, and its area says whether it is smaller than a pixel. Its
//! rep's error is "set by a thin member" when what the simplification step
//! dropped lies more than twice as far from the rep as the rep lies from
//! the step's input (a member that collapsed away whole: the case the
//! builder's measured deviation exists for).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::rc::Rc;

use anyhow::{Context, Result};
use glam::Vec3;

use engine::camera::Pose;
use engine::front::FrontIndex;
use engine::records::RepKind;
use engine::runtime::RuntimeParams;
use engine::skeleton::{RepId, Skeleton};
use engine::{FormatError, SceneFile};
use hlod_builder::mesh::Mesh;

use crate::raster::{IdBuffer, NONE};

const MIB: f64 = 1048576.0;
/// Decoded geometry kept between frames, at most.
const CACHE_BYTES: usize = 1 << 30;
/// A step's dropped geometry this many times farther than its rep's own
/// distance marks the rep as set by a thin member.
const THIN_RATIO: f32 = 2.0;

/// What the diagnosis reads.
pub struct Setup<'a> {
    pub skeleton: &'a Skeleton,
    pub scene: &'a SceneFile<std::sync::Arc<dyn engine::ByteSource>>,
    pub poses: &'a [Pose],
    pub params: RuntimeParams,
    /// Rasterise every this many frames.
    pub every: usize,
    /// The footprint base (`Skeleton::in_core_bytes`).
    pub data_bytes: u64,
}

/// One frame's counts (triangle counts of rasterised frames only where
/// `sampled`).
#[derive(Clone, Copy, Debug, Default)]
struct FrameRow {
    reps: u64,
    tris: u64,
    bytes: u64,
    hlod_tris: u64,
    /// Triangles of LOD reps at the finest level, one above it, two, three or more.
    by_level: [u64; 4],
    sampled: bool,
    visible: u64,
    hidden: u64,
    unsampled: u64,
    off_screen: u64,
    sub_pixel: u64,
    thin: u64,
    covered_px: u64,
    /// Triangles of paged reps (trees, MTs): counted, not rasterised.
    paged: u64,
    /// Reps, triangles and resident bytes of the reps that own a pixel
    /// (paged reps counted as owning one): the front a perfect occlusion
    /// culler at rep granularity would leave.
    seen_reps: u64,
    seen_tris: u64,
    seen_bytes: u64,
    /// Triangles of the reps that own no pixel: some triangle covers a
    /// pixel centre (the rep is hidden), or none does (it is too small or
    /// thin to be sampled).
    hidden_rep_tris: u64,
    unsampled_rep_tris: u64,
    /// Triangles of the reps whose box is hidden behind the front's own
    /// depth buffer, as the engine's culler tests a box: the node's box per
    /// pixel, per 4 x 4 tile (the culler's tiles), and the rep's own box
    /// per pixel. What an occlusion culler testing boxes could leave out at
    /// best, with every drawn triangle as an occluder.
    box_px_tris: u64,
    box_tile_tris: u64,
    rep_box_px_tris: u64,
}

struct Geo {
    pos: Vec<Vec3>,
    idx: Vec<u32>,
}

/// Decoded reps and thin-member verdicts, by rep.
struct Reps<'a> {
    skel: &'a Skeleton,
    scene: &'a SceneFile<std::sync::Arc<dyn engine::ByteSource>>,
    geo: HashMap<RepId, Rc<Geo>>,
    geo_bytes: usize,
    thin: HashMap<RepId, bool>,
}

impl Reps<'_> {
    fn geo(&mut self, r: RepId) -> Result<Rc<Geo>, FormatError> {
        if let Some(g) = self.geo.get(&r) {
            return Ok(g.clone());
        }
        let m = self.scene.read_rep(r)?;
        let g = Rc::new(Geo {
            pos: m
                .vertices
                .iter()
                .map(|v| Vec3::from(m.position(v)))
                .collect(),
            idx: m.indices,
        });
        let bytes = g.pos.len() * 12 + g.idx.len() * 4;
        if self.geo_bytes + bytes > CACHE_BYTES {
            self.geo.clear();
            self.geo_bytes = 0;
        }
        self.geo_bytes += bytes;
        self.geo.insert(r, g.clone());
        Ok(g)
    }

    fn mesh(&mut self, reps: &[RepId]) -> Result<Mesh, FormatError> {
        let mut m = Mesh::default();
        for &r in reps {
            let g = self.geo(r)?;
            let base = m.positions.len() as u32;
            m.positions.extend(g.pos.iter().map(|p| p.to_array()));
            m.indices.extend(g.idx.iter().map(|i| i + base));
        }
        Ok(m)
    }

    /// Whether rep `r`'s error is set by a thin member: the step that made
    /// it (from the next finer level of its node, or from its children's
    /// coarsest reps for an HLOD) dropped geometry that lies more than
    /// [`THIN_RATIO`] times farther from it than it lies from that input.
    fn thin(&mut self, r: RepId) -> Result<bool, FormatError> {
        if let Some(&t) = self.thin.get(&r) {
            return Ok(t);
        }
        let rec = self.skel.reps[r as usize];
        let node = &self.skel.nodes[rec.node as usize];
        let input: Vec<RepId> = match rec.rep_kind() {
            Some(RepKind::Lod) if u32::from(rec.index) + 1 < node.rep_count => vec![r + 1],
            Some(RepKind::Hlod) => (node.first_child..node.first_child + node.child_count)
                .filter_map(|c| {
                    let n = &self.skel.nodes[c as usize];
                    (n.rep_count > 0).then_some(n.first_rep)
                })
                .collect(),
            _ => Vec::new(),
        };
        let t = if input.is_empty() || self.skel.reps[input[0] as usize].is_paged() {
            false
        } else {
            let rep = self.mesh(&[r])?;
            let from = self.mesh(&input)?;
            let kept = hlod_builder::deviation::distance_from(&rep, &from);
            let dropped = hlod_builder::deviation::distance_from(&from, &rep);
            dropped > THIN_RATIO * kept && dropped > 0.0
        };
        self.thin.insert(r, t);
        Ok(t)
    }
}

/// The anatomy table (markdown) and the per-frame CSV.
pub fn run(s: &Setup, tolerances: &[f32]) -> Result<(String, String)> {
    let index = FrontIndex::new(s.skeleton);
    let mut reps = Reps {
        skel: s.skeleton,
        scene: s.scene,
        geo: HashMap::new(),
        geo_bytes: 0,
        thin: HashMap::new(),
    };
    let height = s.skeleton.nodes.iter().map(|n| n.depth).max().unwrap_or(0);
    let mut table = String::from(
        "| ε px | reps median / max | triangles median / max | MiB median / max | % of rep data | tris per covered px | visible | hidden | unsampled | off-screen | smaller than a pixel | thin member | in HLODs | LOD tris at the finest level / 1 / 2 / ≥3 above | depth where refinement stops (median, p10–p90 of tris) | reps owning a pixel: reps / triangles / MiB (median) | their % of rep data | tris in reps owning none: hidden / unsampled | tris in reps whose box is hidden: node box per px / per 4×4 tile, rep box per px |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---:|---:|---:|\n",
    );
    let mut csv = String::from(
        "tolerance_px,frame,reps,tris,bytes,hlod_tris,sampled,visible,hidden,unsampled,off_screen,sub_pixel,thin,covered_px,paged,seen_reps,seen_tris,seen_bytes,hidden_rep_tris,unsampled_rep_tris,box_px_tris,box_tile_tris,rep_box_px_tris\n",
    );
    for &tol in tolerances {
        let mut rows = Vec::with_capacity(s.poses.len());
        let mut depth_tris = vec![0u64; height as usize + 1];
        let mut front = Vec::new();
        for (f, pose) in s.poses.iter().enumerate() {
            let view = s.params.view(pose);
            index.compute(&view, &view.frustum(0.0), tol, &mut front);
            let mut row = FrameRow::default();
            for &r in &front {
                let rec = &s.skeleton.reps[r as usize];
                let t = u64::from(rec.tri_count);
                row.reps += 1;
                row.tris += t;
                row.bytes += rec.resident_len();
                if rec.rep_kind() == Some(RepKind::Hlod) {
                    row.hlod_tris += t;
                } else {
                    let n = &s.skeleton.nodes[rec.node as usize];
                    let above = n.rep_count.saturating_sub(1 + u32::from(rec.index));
                    row.by_level[above.min(3) as usize] += t;
                }
                depth_tris[s.skeleton.nodes[rec.node as usize].depth as usize] += t;
            }
            if f % s.every.max(1) == 0 {
                rasterise(&mut reps, &view, &front, &mut row)
                    .with_context(|| format!("frame {f} at ε {tol} px"))?;
            }
            let _ = writeln!(
                csv,
                "{tol},{f},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                row.reps,
                row.tris,
                row.bytes,
                row.hlod_tris,
                u8::from(row.sampled),
                row.visible,
                row.hidden,
                row.unsampled,
                row.off_screen,
                row.sub_pixel,
                row.thin,
                row.covered_px,
                row.paged,
                row.seen_reps,
                row.seen_tris,
                row.seen_bytes,
                row.hidden_rep_tris,
                row.unsampled_rep_tris,
                row.box_px_tris,
                row.box_tile_tris,
                row.rep_box_px_tris
            );
            rows.push(row);
        }
        table.push_str(&table_row(s, tol, &rows, &depth_tris));
    }
    let _ = writeln!(
        table,
        "\nShares are of the rasterised frames' front triangles (every {}th frame; the hierarchy is {height} levels deep below the root). \
         Hidden: covers pixel centres, owns none in the front's own depth buffer. Unsampled: covers no pixel centre. \
         Thin member: the rep's simplification step dropped geometry more than {THIN_RATIO}× farther from the rep than the rep lies from its input. \
         Reps owning a pixel: the front a perfect occlusion culler at rep granularity would leave (median over the rasterised frames). \
         Box hidden: every pixel centre (or 4×4 tile) of the box's screen rectangle is nearer in the front's own depth buffer than the box's nearest corner, the engine culler's test with every drawn triangle as an occluder.",
        s.every.max(1)
    );
    Ok((table, csv))
}

fn rasterise(
    reps: &mut Reps,
    view: &engine::camera::View,
    front: &[RepId],
    row: &mut FrameRow,
) -> Result<()> {
    let mut buf = IdBuffer::new(view);
    // Per triangle: its rep's slot in `front`, what it did.
    let mut tri_rep: Vec<u32> = Vec::new();
    let mut drawn = Vec::new();
    for (slot, &r) in front.iter().enumerate() {
        if reps.skel.reps[r as usize].is_paged() {
            row.paged += u64::from(reps.skel.reps[r as usize].tri_count);
            continue;
        }
        let g = reps.geo(r)?;
        for t in g.idx.chunks_exact(3) {
            let id = tri_rep.len() as u32;
            let d = buf.triangle(
                id,
                [
                    g.pos[t[0] as usize],
                    g.pos[t[1] as usize],
                    g.pos[t[2] as usize],
                ],
            );
            tri_rep.push(slot as u32);
            drawn.push(d);
        }
    }
    let mut owns = vec![false; tri_rep.len()];
    let mut owns_pixel: Vec<bool> = front
        .iter()
        .map(|&r| reps.skel.reps[r as usize].is_paged())
        .collect();
    for &o in buf.owners() {
        if o != NONE {
            owns[o as usize] = true;
            owns_pixel[tri_rep[o as usize] as usize] = true;
            row.covered_px += 1;
        }
    }
    let mut thin_slot = vec![None; front.len()];
    let mut sampled = vec![false; front.len()];
    for (k, d) in drawn.iter().enumerate() {
        if !d.on_screen {
            row.off_screen += 1;
        } else if owns[k] {
            row.visible += 1;
        } else if d.samples > 0 {
            row.hidden += 1;
        } else {
            row.unsampled += 1;
        }
        if d.on_screen && d.area < 1.0 {
            row.sub_pixel += 1;
        }
        let slot = tri_rep[k] as usize;
        sampled[slot] |= d.on_screen && d.samples > 0;
        let thin = match thin_slot[slot] {
            Some(t) => t,
            None => {
                let t = reps.thin(front[slot])?;
                thin_slot[slot] = Some(t);
                t
            }
        };
        row.thin += u64::from(thin);
    }
    let (px, tiles) = (buf.depth_tiles(1), buf.depth_tiles(engine::occlusion::TILE));
    for (slot, &owns) in owns_pixel.iter().enumerate() {
        let rec = &reps.skel.reps[front[slot] as usize];
        let t = u64::from(rec.tri_count);
        if !rec.is_paged() {
            let n = &reps.skel.nodes[rec.node as usize];
            let (mn, mx) = (Vec3::from(n.bbox_min), Vec3::from(n.bbox_max));
            row.box_px_tris += u64::from(px.box_hidden(mn, mx)) * t;
            row.box_tile_tris += u64::from(tiles.box_hidden(mn, mx)) * t;
            let (mn, mx) = (Vec3::from(rec.bbox_min), Vec3::from(rec.bbox_max));
            row.rep_box_px_tris += u64::from(px.box_hidden(mn, mx)) * t;
        }
        if owns {
            row.seen_reps += 1;
            row.seen_tris += t;
            row.seen_bytes += rec.resident_len();
        } else if sampled[slot] {
            row.hidden_rep_tris += t;
        } else {
            row.unsampled_rep_tris += t;
        }
    }
    row.sampled = true;
    Ok(())
}

fn median_max(mut v: Vec<f64>) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() - 1])
}

/// The depth below which `q` of the triangles lie.
fn depth_quantile(depth_tris: &[u64], q: f64) -> usize {
    let total: u64 = depth_tris.iter().sum();
    let mut acc = 0u64;
    for (d, &t) in depth_tris.iter().enumerate() {
        acc += t;
        if acc as f64 >= q * total as f64 {
            return d;
        }
    }
    depth_tris.len().saturating_sub(1)
}

fn table_row(s: &Setup, tol: f32, rows: &[FrameRow], depth_tris: &[u64]) -> String {
    let col = |f: &dyn Fn(&FrameRow) -> f64| median_max(rows.iter().map(f).collect());
    let (reps_med, reps_max) = col(&|r| r.reps as f64);
    let (tris_med, tris_max) = col(&|r| r.tris as f64);
    let (mib_med, mib_max) = col(&|r| r.bytes as f64 / MIB);
    let sampled: Vec<&FrameRow> = rows.iter().filter(|r| r.sampled).collect();
    let sum = |f: &dyn Fn(&FrameRow) -> u64| sampled.iter().map(|r| f(r)).sum::<u64>() as f64;
    let drawn = sum(&|r| r.tris - r.paged).max(1.0);
    let pct = |x: f64| format!("{:.1}%", 100.0 * x / drawn);
    // Triangles per covered pixel, the median over the rasterised frames.
    let (per_px, _) = median_max(
        sampled
            .iter()
            .map(|r| r.tris as f64 / r.covered_px.max(1) as f64)
            .collect(),
    );
    let all_tris: u64 = rows.iter().map(|r| r.tris).sum();
    let hlod: u64 = rows.iter().map(|r| r.hlod_tris).sum();
    let level = |k: usize| {
        let t: u64 = rows.iter().map(|r| r.by_level[k]).sum();
        format!("{:.0}%", 100.0 * t as f64 / all_tris.max(1) as f64)
    };
    let levels = format!("{} / {} / {} / {}", level(0), level(1), level(2), level(3));
    let seen = |f: &dyn Fn(&FrameRow) -> f64| median_max(sampled.iter().map(|r| f(r)).collect()).0;
    let seen_mib = seen(&|r| r.seen_bytes as f64 / MIB);
    let seen_cols = format!(
        "{:.0} / {:.0} / {seen_mib:.1} | {:.2}% | {} / {} | {} / {}, {}",
        seen(&|r| r.seen_reps as f64),
        seen(&|r| r.seen_tris as f64),
        100.0 * seen_mib * MIB / s.data_bytes.max(1) as f64,
        pct(sum(&|r| r.hidden_rep_tris)),
        pct(sum(&|r| r.unsampled_rep_tris)),
        pct(sum(&|r| r.box_px_tris)),
        pct(sum(&|r| r.box_tile_tris)),
        pct(sum(&|r| r.rep_box_px_tris)),
    );
    format!(
        "| {tol} | {reps_med:.0} / {reps_max:.0} | {tris_med:.0} / {tris_max:.0} | {mib_med:.1} / {mib_max:.1} | {:.2}% | {per_px:.2} | {} | {} | {} | {} | {} | {} | {:.1}% | {levels} | {} ({}–{}) | {seen_cols} |\n",
        100.0 * mib_med * MIB / s.data_bytes.max(1) as f64,
        pct(sum(&|r| r.visible)),
        pct(sum(&|r| r.hidden)),
        pct(sum(&|r| r.unsampled)),
        pct(sum(&|r| r.off_screen)),
        pct(sum(&|r| r.sub_pixel)),
        pct(sum(&|r| r.thin)),
        100.0 * hlod as f64 / all_tris.max(1) as f64,
        depth_quantile(depth_tris, 0.5),
        depth_quantile(depth_tris, 0.1),
        depth_quantile(depth_tris, 0.9),
    )
}
