//! Export of a scene file as an OGC 3D Tiles 1.1 tileset.
//!
//! # The mapping
//!
//! - **A chain of tiles per skeleton node**, one per static rep `N[0..k]`
//!   (coarsest first), each the only child of the one before, with
//!   `REPLACE` refinement. A tile's `geometricError` is its rep's
//!   object-space error, so a 3D Tiles viewer that refines while
//!   `geometricError · H / (2 d tan(fov/2))` exceeds its target draws what
//!   our front draws at ε equal to that target (`d`: the distance to the
//!   tile's box, which is the node's box for every tile of the chain, as in
//!   [`engine::front`]). The children of a node's last tile are its child
//!   nodes' first tiles. A node with no rep is one tile with no content and
//!   its parent's error (it is always refined, as our front always descends
//!   through it).
//! - **Content**: one `.glb` per rep with triangles ([`glb`]): quantised
//!   positions as stored, meshopt-compressed streams, element identity.
//! - **Axes**: glTF content is y-up and a viewer turns it z-up (a rotation
//!   of +90° about x), so boxes are written z-up: `(x, y, z) -> (x, -z, y)`.
//!   The scene's origin (survey coordinates) is the root's translation.
//! - **JSON size**: a subtree that would take a file over
//!   [`ExportOptions::max_tiles_per_json`] tiles is written as an external
//!   tileset (`tileset-NODE.json`), its largest subtrees first.
//! - **Bundles** (`ExportOptions::bundle_bytes`, off by default): a small
//!   subtree becomes one chain of tiles whose contents merge cuts of its
//!   reps ([`bundle`]), for viewers that pay per tile.
//! - **Not exported**: view-dependence trees and Multi-Triangulations (the
//!   finest reps of large objects when built with them); the chain ends at
//!   the node's finest static rep, whose error it keeps, and the count is
//!   reported.

pub mod bundle;
pub mod glb;

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use engine::format::objects::ObjectTable;
use engine::format::{FormatError, NONE, NodeRecord, RepKind, SceneFile};
use engine::skeleton::Skeleton;
use rayon::prelude::*;
use serde_json::{Value, json};

use glb::{Element, Features};

/// What can go wrong in an export.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("{path}: {source}")]
    Scene {
        path: PathBuf,
        #[source]
        source: FormatError,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Refused(String),
}

fn io_at(path: &Path) -> impl FnOnce(std::io::Error) -> ExportError + '_ {
    move |source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Export parameters.
#[derive(Clone, Copy, Debug)]
pub struct ExportOptions {
    /// Most tiles one JSON file holds (about 200 bytes each).
    pub max_tiles_per_json: usize,
    /// Subtrees storing at most this many bytes of reps are exported as
    /// bundles ([`bundle`]); 0: one tile per rep.
    pub bundle_bytes: u64,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            max_tiles_per_json: 10_000,
            bundle_bytes: 0,
        }
    }
}

/// Parses `--bundle`: 0, or a size of at least 1 KiB.
pub fn parse_bundle(s: &str) -> Result<u64, String> {
    if s.trim() == "0" {
        return Ok(0);
    }
    let v = crate::build::memory::parse_size(s)?;
    if v < 1024 {
        return Err(format!("{s:?}: a bundle of at least 1K (or 0 for none)"));
    }
    Ok(v)
}

/// What an export wrote.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ExportReport {
    pub tiles: u64,
    /// Tiles with a `.glb`.
    pub contents: u64,
    pub content_bytes: u64,
    /// Tiles whose content names its elements.
    pub contents_with_elements: u64,
    pub json_files: u64,
    pub json_bytes: u64,
    pub largest_json_bytes: u64,
    /// View-dependence trees and MTs left out.
    pub paged_reps_skipped: u64,
    /// Bundles written, and the reps their contents merge.
    pub bundles: u64,
    pub bundled_reps: u64,
}

/// The reps of node `n` that become tiles: its static meshes, in order.
fn chain(s: &Skeleton, n: &NodeRecord) -> Vec<u32> {
    (n.first_rep..n.first_rep + n.rep_count)
        .filter(|&r| {
            matches!(
                s.reps[r as usize].rep_kind(),
                Some(RepKind::Lod | RepKind::Hlod)
            )
        })
        .collect()
}

/// Whether rep `r` gets a `.glb` (a static mesh with triangles): the export
/// writes every such rep or fails.
fn has_content(s: &Skeleton, r: u32) -> bool {
    let rec = &s.reps[r as usize];
    !rec.is_paged() && rec.tri_count > 0
}

/// A node's content path, relative to the tileset's folder.
pub fn content_uri(rep: u32) -> String {
    format!("content/{}/{rep}.glb", rep / 1000)
}

/// An external tileset's file name.
pub fn external_name(node: u32) -> String {
    format!("tileset-{node}.json")
}

/// A node's box as a z-up 3D Tiles `box`.
fn bounding_box(n: &NodeRecord) -> Value {
    let (a, b) = (n.bbox_min, n.bbox_max);
    let c = [0, 1, 2].map(|k| 0.5 * (f64::from(a[k]) + f64::from(b[k])));
    let h = [0, 1, 2].map(|k| (0.5 * (f64::from(b[k]) - f64::from(a[k]))).max(1e-6));
    json!({"box": [c[0], -c[2], c[1], h[0], 0.0, 0.0, 0.0, h[2], 0.0, 0.0, 0.0, h[1]]})
}

/// Where each node's subtree is written: inline in its parent's file, or in
/// a file of its own.
struct Split {
    external: Vec<bool>,
}

impl Split {
    /// Greedy, bottom-up: a node's file holds its chain and its children's
    /// inline subtrees; while that exceeds `limit`, the largest child goes
    /// to a file of its own (leaving a one-tile stub).
    fn new(s: &Skeleton, chains: &[u32], limit: usize, bundles: &bundle::Bundles) -> Self {
        let n = s.nodes.len();
        let mut inline = vec![0usize; n];
        let mut external = vec![false; n];
        for i in (0..n).rev() {
            let node = &s.nodes[i];
            if bundles.is_root(i as u32) {
                // A bundle is its chain: its nodes have no tiles of their own.
                inline[i] = chains[i] as usize;
                continue;
            }
            let kids = node.first_child as usize..(node.first_child + node.child_count) as usize;
            let mut total = chains[i] as usize + kids.clone().map(|c| inline[c]).sum::<usize>();
            if total > limit {
                let mut order: Vec<usize> = kids.collect();
                order.sort_by_key(|&c| (std::cmp::Reverse(inline[c]), c));
                for c in order {
                    if total <= limit || inline[c] <= 1 {
                        break;
                    }
                    external[c] = true;
                    total -= inline[c] - 1;
                }
            }
            inline[i] = total;
        }
        Self { external }
    }
}

/// Writes the tileset JSON files, from the root down.
struct Tileset<'a> {
    s: &'a Skeleton,
    split: Split,
    bundles: &'a bundle::Bundles,
    /// Each bundle's tiles, coarsest first: error and content path.
    bundle_tiles: HashMap<u32, Vec<(f64, Option<String>)>>,
    origin: [f64; 3],
    dir: &'a Path,
    report: ExportReport,
}

impl Tileset<'_> {
    /// The tile of node `i` (its whole chain), with `parent_error` the
    /// error of the tile above; the external subtrees met are pushed on
    /// `pending` (node, its first tile's error bound).
    fn node_tile(&mut self, i: u32, parent_error: f64, pending: &mut Vec<(u32, f64)>) -> Value {
        let n = self.s.nodes[i as usize];
        let reps = chain(self.s, &n);
        let bv = bounding_box(&n);
        let mut errors: Vec<f64> = Vec::with_capacity(reps.len().max(1));
        let mut bound = parent_error;
        for &r in &reps {
            bound = bound.min(f64::from(self.s.reps[r as usize].error));
            errors.push(bound);
        }
        if reps.is_empty() {
            errors.push(parent_error);
        }
        let last = *errors.last().expect("at least one tile");
        let mut children = Vec::new();
        for c in n.first_child..n.first_child + n.child_count {
            if self.split.external[c as usize] {
                let first = self.first_error(c, last);
                children.push(json!({
                    "boundingVolume": bounding_box(&self.s.nodes[c as usize]),
                    "geometricError": first as f32,
                    "content": {"uri": external_name(c)},
                }));
                pending.push((c, last));
                self.report.tiles += 1;
            } else {
                children.push(self.subtree_tile(c, last, pending));
            }
        }
        let uris: Vec<Option<String>> = (0..errors.len())
            .map(|k| {
                let r = reps.get(k).filter(|&&r| has_content(self.s, r));
                r.map(|&r| content_uri(r))
            })
            .collect();
        self.chain_tiles(&bv, &errors, &uris, children)
    }

    /// A chain of tiles with box `bv`, tile `k` of error `errors[k]` and
    /// content `uris[k]`, each the only child of the one before; `children`
    /// hang under the last.
    fn chain_tiles(
        &mut self,
        bv: &Value,
        errors: &[f64],
        uris: &[Option<String>],
        mut children: Vec<Value>,
    ) -> Value {
        // From the finest tile up.
        let mut tile: Option<Value> = None;
        for k in (0..errors.len()).rev() {
            let mut t = json!({"boundingVolume": bv.clone(), "geometricError": errors[k] as f32});
            if let Some(Some(uri)) = uris.get(k) {
                t["content"] = json!({"uri": uri});
            }
            let kids = match tile.take() {
                Some(below) => vec![below],
                None => std::mem::take(&mut children),
            };
            if !kids.is_empty() {
                t["children"] = Value::Array(kids);
            }
            self.report.tiles += 1;
            tile = Some(t);
        }
        tile.expect("at least one tile")
    }

    /// Node `i`'s subtree as tiles: a bundle's chain, or the node's own.
    fn subtree_tile(&mut self, i: u32, bound: f64, pending: &mut Vec<(u32, f64)>) -> Value {
        if self.bundles.is_root(i) {
            self.bundle_tile(i, bound)
        } else {
            self.node_tile(i, bound, pending)
        }
    }

    /// The chain of bundle `i` under a parent of error `bound` (written
    /// once: its tiles are taken).
    fn bundle_tile(&mut self, i: u32, bound: f64) -> Value {
        let bv = bounding_box(&self.s.nodes[i as usize]);
        let (mut errors, uris): (Vec<f64>, Vec<Option<String>>) = self
            .bundle_tiles
            .remove(&i)
            .unwrap_or_default()
            .into_iter()
            .unzip();
        let mut b = bound;
        for e in &mut errors {
            b = b.min(*e);
            *e = b;
        }
        if errors.is_empty() {
            errors.push(bound);
        }
        self.chain_tiles(&bv, &errors, &uris, Vec::new())
    }

    /// The error of node `c`'s first tile under a parent of error `bound`.
    fn first_error(&self, c: u32, bound: f64) -> f64 {
        if let Some((e, _)) = self.bundle_tiles.get(&c).and_then(|t| t.first()) {
            return bound.min(*e);
        }
        let n = self.s.nodes[c as usize];
        chain(self.s, &n).first().map_or(bound, |&r| {
            bound.min(f64::from(self.s.reps[r as usize].error))
        })
    }

    fn write_file(&mut self, name: &str, root: Value) -> Result<(), ExportError> {
        let error = root["geometricError"].clone();
        let doc = json!({
            "asset": {"version": "1.1", "generator": "hlod-build export-3dtiles"},
            "geometricError": error,
            "root": root,
        });
        let bytes = serde_json::to_vec(&doc).expect("a JSON value serialises");
        let path = self.dir.join(name);
        fs::write(&path, &bytes).map_err(io_at(&path))?;
        self.report.json_files += 1;
        self.report.json_bytes += bytes.len() as u64;
        self.report.largest_json_bytes = self.report.largest_json_bytes.max(bytes.len() as u64);
        Ok(())
    }

    fn write_all(&mut self) -> Result<(), ExportError> {
        let root = self.s.nodes[0];
        let diag: f64 = (0..3)
            .map(|k| f64::from(root.bbox_max[k] - root.bbox_min[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        // Above every rep's error: a root with no rep is always refined.
        let top = (diag * 1e3).max(1.0);
        let mut pending = Vec::new();
        let mut tile = self.subtree_tile(0, top, &mut pending);
        tile["refine"] = json!("REPLACE");
        let o = self.origin;
        if o != [0.0; 3] {
            tile["transform"] = json!([
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, o[0], -o[2], o[1], 1.0
            ]);
        }
        self.write_file("tileset.json", tile)?;
        while let Some((c, bound)) = pending.pop() {
            let mut tile = self.subtree_tile(c, bound, &mut pending);
            tile["refine"] = json!("REPLACE");
            self.write_file(&external_name(c), tile)?;
        }
        Ok(())
    }
}

/// Pulls the IFC type and GlobalId out of an object's description
/// ([`engine::tree::Described`]: `extras` keys, IfcOpenShell's
/// `type`/`GlobalId` and common spellings, else an IFC-style name
/// `IfcClass:Name:GlobalId`).
pub fn element(object: u32, info: &str) -> Element {
    let v: Value = serde_json::from_str(info).unwrap_or(Value::Null);
    let d = engine::tree::Described::of(&v);
    let described = !v.is_null();
    Element {
        object,
        mesh_name: d.mesh_name,
        name: d.name,
        ifc_type: d.ifc_type,
        global_id: d.global_id,
        info: if described {
            info.to_string()
        } else {
            String::new()
        },
    }
}

/// The elements of rep `r`'s triangles: every triangle of a one-object
/// leaf's reps, and of a merged leaf's finest static rep (by the object
/// section's runs). Other reps (HLODs, a merged leaf's coarser levels) mix
/// objects without a record of which triangle is whose: none.
fn features(s: &Skeleton, objects: &ObjectTable, r: u32, finest: bool) -> Option<Features> {
    if objects.is_empty() {
        return None;
    }
    let rec = &s.reps[r as usize];
    let node = &s.nodes[rec.node as usize];
    if !node.is_leaf() {
        return None;
    }
    let info = |k: u32| element(k, objects.info(k).unwrap_or_default());
    if node.object != NONE {
        return Some(Features {
            triangle: vec![0; rec.tri_count as usize],
            elements: vec![info(node.object)],
        });
    }
    if !finest {
        return None;
    }
    let mut local: Vec<u32> = Vec::new();
    let mut triangle = Vec::with_capacity(rec.tri_count as usize);
    for t in 0..rec.tri_count {
        let k = objects.object_at(s, rec.node, t)?;
        let i = match local.iter().position(|&o| o == k) {
            Some(i) => i,
            None => {
                local.push(k);
                local.len() - 1
            }
        };
        triangle.push(i as u32);
    }
    Some(Features {
        triangle,
        elements: local.into_iter().map(info).collect(),
    })
}

/// Refuses an output folder that is neither absent, empty, nor an earlier
/// export, or that holds the scene.
fn check_output(scene: &Path, out: &Path) -> Result<(), ExportError> {
    if !out.exists() {
        return Ok(());
    }
    if !out.is_dir() {
        return Err(ExportError::Refused(format!(
            "{}: exists and is not a folder",
            out.display()
        )));
    }
    let empty = fs::read_dir(out).map_err(io_at(out))?.next().is_none();
    if !empty && !out.join("tileset.json").is_file() {
        return Err(ExportError::Refused(format!(
            "{}: a folder that is not an earlier export (no tileset.json); give a new or empty one",
            out.display()
        )));
    }
    let (s, o) = (scene.canonicalize(), out.canonicalize());
    if let (Ok(s), Ok(o)) = (s, o)
        && s.starts_with(&o)
    {
        return Err(ExportError::Refused(format!(
            "{}: the scene is inside the output folder {}, which the export replaces",
            scene.display(),
            out.display()
        )));
    }
    Ok(())
}

/// Exports `scene` as a tileset in folder `out`, atomically: everything is
/// written to a temporary folder beside it, which replaces `out` (absent,
/// empty or an earlier export) only once complete. Memory: the skeleton,
/// the object section and a batch of reps.
pub fn export(scene: &Path, out: &Path, opts: ExportOptions) -> Result<ExportReport, ExportError> {
    if opts.max_tiles_per_json < 16 {
        return Err(ExportError::Refused(format!(
            "at least 16 tiles per JSON file (asked for {})",
            opts.max_tiles_per_json
        )));
    }
    let at = |source| ExportError::Scene {
        path: scene.to_path_buf(),
        source,
    };
    let file = SceneFile::open(scene).map_err(at)?;
    check_output(scene, out)?;
    let objects = file.read_objects().map_err(at)?;
    let s = file.skeleton();
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    fs::create_dir_all(&parent).map_err(io_at(&parent))?;
    let tmp = tempfile::Builder::new()
        .prefix(".export-3dtiles-")
        .tempdir_in(&parent)
        .map_err(io_at(&parent))?;
    let mut report = ExportReport::default();
    let mut chains = vec![0u32; s.nodes.len()];
    let mut finest = vec![false; s.reps.len()];
    for (i, n) in s.nodes.iter().enumerate() {
        let c = chain(s, n);
        chains[i] = c.len().max(1) as u32;
        if let Some(&r) = c.last() {
            finest[r as usize] = true;
        }
        report.paged_reps_skipped += (n.rep_count as usize - c.len()) as u64;
    }
    let bundles = bundle::Bundles::new(s, opts.bundle_bytes);
    let order: Vec<u32> = s
        .reps_in_file_order()
        .into_iter()
        .filter(|&r| has_content(s, r) && !bundles.is_inside(s.reps[r as usize].node))
        .collect();
    for batch in order.chunks(256) {
        let meshes = batch
            .iter()
            .map(|&r| file.read_rep(r).map(|m| (r, m)))
            .collect::<Result<Vec<_>, _>>()
            .map_err(at)?;
        let written = meshes
            .par_iter()
            .map(|(r, mesh)| {
                let f = features(s, &objects, *r, finest[*r as usize]);
                let bytes = glb::encode(mesh, f.as_ref());
                write_content(tmp.path(), &content_uri(*r), &bytes)?;
                Ok((bytes.len() as u64, f.is_some()))
            })
            .collect::<Result<Vec<_>, ExportError>>()?;
        for (len, named) in written {
            report.contents += 1;
            report.content_bytes += len;
            report.contents_with_elements += u64::from(named);
        }
    }
    let mut bundle_tiles = HashMap::new();
    for batch in bundles.roots.chunks(64) {
        let cuts: Vec<Vec<(Vec<u32>, f64)>> = batch.iter().map(|&b| bundle::cuts(s, b)).collect();
        let mut need: Vec<u32> = cuts
            .iter()
            .flatten()
            .flat_map(|(c, _)| c.iter().copied())
            .filter(|&r| has_content(s, r))
            .collect();
        need.sort_by_key(|&r| (s.reps[r as usize].offset, r));
        need.dedup();
        let meshes: HashMap<u32, engine::format::RepMesh> = need
            .iter()
            .map(|&r| file.read_rep(r).map(|m| (r, m)))
            .collect::<Result<_, _>>()
            .map_err(at)?;
        // A rep is in several cuts of its bundle: its elements are found once.
        let named: HashMap<u32, Option<glb::Features>> = need
            .par_iter()
            .map(|&r| (r, features(s, &objects, r, finest[r as usize])))
            .collect();
        let done = batch
            .par_iter()
            .zip(&cuts)
            .map(|(&b, cuts)| {
                let mut tiles = Vec::with_capacity(cuts.len());
                let mut stats = (0u64, 0u64, 0u64, 0u64);
                for (k, (reps, max)) in cuts.iter().enumerate() {
                    let parts: Vec<(&engine::format::RepMesh, Option<&glb::Features>)> = reps
                        .iter()
                        .filter(|&&r| has_content(s, r))
                        .map(|&r| (&meshes[&r], named[&r].as_ref()))
                        .collect();
                    if parts.is_empty() {
                        tiles.push((*max, None));
                        continue;
                    }
                    // One rep keeps its own quantisation; merged reps are
                    // quantised again, which adds to the tile's error.
                    let (bytes, named, err) = if let [(m, f)] = parts.as_slice() {
                        (glb::encode(m, *f), f.is_some(), *max)
                    } else {
                        let (m, f) = bundle::merge(&parts);
                        let q = f64::from(m.quantization_error());
                        (glb::encode(&m, f.as_ref()), f.is_some(), *max + q)
                    };
                    let uri = bundle::content_uri(b, k);
                    write_content(tmp.path(), &uri, &bytes)?;
                    stats.0 += 1;
                    stats.1 += bytes.len() as u64;
                    stats.2 += u64::from(named);
                    tiles.push((err, Some(uri)));
                }
                stats.3 = cuts
                    .iter()
                    .flat_map(|(c, _)| c)
                    .collect::<std::collections::HashSet<_>>()
                    .len() as u64;
                Ok((b, tiles, stats))
            })
            .collect::<Result<Vec<_>, ExportError>>()?;
        for (b, tiles, (n, len, named, reps)) in done {
            report.contents += n;
            report.content_bytes += len;
            report.contents_with_elements += named;
            report.bundles += 1;
            report.bundled_reps += reps;
            bundle_tiles.insert(b, tiles);
        }
    }
    for &b in &bundles.roots {
        chains[b as usize] = bundle_tiles.get(&b).map_or(1, |t| t.len().max(1) as u32);
    }
    let mut ts = Tileset {
        s,
        split: Split::new(s, &chains, opts.max_tiles_per_json, &bundles),
        bundles: &bundles,
        bundle_tiles,
        origin: file.header().origin,
        dir: tmp.path(),
        report,
    };
    ts.write_all()?;
    let report = ts.report;
    replace_dir(tmp, out)?;
    Ok(report)
}

/// Writes a content file at `uri` under `dir`.
fn write_content(dir: &Path, uri: &str, bytes: &[u8]) -> Result<(), ExportError> {
    let path = dir.join(uri);
    let parent = path.parent().expect("content files are in a folder");
    fs::create_dir_all(parent).map_err(io_at(parent))?;
    fs::write(&path, bytes).map_err(io_at(&path))
}

/// Puts the finished folder `tmp` at `out`, replacing what is there.
fn replace_dir(tmp: tempfile::TempDir, out: &Path) -> Result<(), ExportError> {
    let old = out.exists().then(|| {
        let mut name = out.file_name().unwrap_or_default().to_os_string();
        name.push(format!(".old-{}", std::process::id()));
        out.with_file_name(name)
    });
    if let Some(old) = &old {
        fs::rename(out, old).map_err(io_at(out))?;
    }
    let path = tmp.keep();
    if let Err(e) = fs::rename(&path, out) {
        if let Some(old) = &old {
            let _ = fs::rename(old, out);
        }
        let _ = fs::remove_dir_all(&path);
        return Err(io_at(out)(e));
    }
    if let Some(old) = old {
        fs::remove_dir_all(&old).map_err(io_at(&old))?;
    }
    Ok(())
}

#[cfg(test)]
mod bundle_tests;
#[cfg(test)]
mod tests;
