//! Bundles: cuts, merged contents and the bundled tileset.

use std::collections::{BTreeMap, BTreeSet};

use engine::format::SceneFile;
use engine::skeleton::Skeleton;

use super::bundle::{self, Bundles};
use super::glb::{self, Element, Features};
use super::tests::{decode, files, plant_scene, tiles};
use super::*;

/// The leaves under node `i`.
fn leaves(s: &Skeleton, i: u32, out: &mut Vec<u32>) {
    let n = &s.nodes[i as usize];
    if n.child_count == 0 {
        out.push(i);
    }
    for c in n.first_child..n.first_child + n.child_count {
        leaves(s, c, out);
    }
}

/// The finest static rep of each of `leaves`.
fn finest_of(s: &Skeleton, leaves: &[u32]) -> Vec<u32> {
    leaves
        .iter()
        .filter_map(|&l| chain(s, &s.nodes[l as usize]).last().copied())
        .collect()
}

/// Whether node `a` is `b` or above it.
fn above(s: &Skeleton, a: u32, mut b: u32) -> bool {
    loop {
        if a == b {
            return true;
        }
        match s.nodes[b as usize].parent {
            p if p == engine::format::NONE => return false,
            p => b = p,
        }
    }
}

#[test]
fn each_cut_covers_every_leaf_once_and_the_chain_refines_to_the_finest() {
    let dir = tempfile::tempdir().unwrap();
    let scene = plant_scene(dir.path(), 60);
    let file = SceneFile::open(&scene).unwrap();
    let s = file.skeleton();
    let b = Bundles::new(s, 64 << 10);
    assert!(!b.roots.is_empty());
    for &root in &b.roots {
        let mut ls = Vec::new();
        leaves(s, root, &mut ls);
        let cuts = bundle::cuts(s, root);
        let mut prev = f64::INFINITY;
        for (k, (reps, max)) in cuts.iter().enumerate() {
            assert!(*max <= prev, "errors never grow along the chain");
            prev = *max;
            // A front: every leaf lies under exactly one rep's node.
            for &l in &ls {
                let n = reps
                    .iter()
                    .filter(|&&r| above(s, s.reps[r as usize].node, l))
                    .count();
                assert_eq!(n, 1, "bundle {root}, cut {k}, leaf {l}");
            }
            let worst = reps.iter().map(|&r| f64::from(s.reps[r as usize].error));
            assert_eq!(worst.fold(0.0, f64::max), *max);
        }
        // The last cut is every leaf's finest static rep.
        let last: BTreeSet<u32> = cuts.last().unwrap().0.iter().copied().collect();
        let finest: BTreeSet<u32> = finest_of(s, &ls).into_iter().collect();
        assert_eq!(last, finest);
        // No two equal cuts.
        for w in cuts.windows(2) {
            assert_ne!(w[0].0, w[1].0);
        }
    }
    // Every node under a root is inside; no root lies inside another.
    for &root in &b.roots {
        let p = s.nodes[root as usize].parent;
        assert!(p == engine::format::NONE || !b.is_inside(p));
    }
}

#[test]
fn a_merged_content_keeps_every_triangle_and_names_elements_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let scene = plant_scene(dir.path(), 20);
    let file = SceneFile::open(&scene).unwrap();
    let s = file.skeleton();
    let reps: Vec<u32> = (0..s.reps.len() as u32)
        .filter(|&r| has_content(s, r))
        .take(3)
        .collect();
    let meshes: Vec<_> = reps.iter().map(|&r| file.read_rep(r).unwrap()).collect();
    let el = |object: u32| Element {
        object,
        name: format!("e{object}"),
        ..Element::default()
    };
    let tris = |m: &engine::format::RepMesh| m.indices.len() / 3;
    let one = |m: &engine::format::RepMesh| Features {
        triangle: vec![0; tris(m)],
        elements: vec![el(7)],
    };
    let (f0, f2) = (one(&meshes[0]), one(&meshes[2]));
    let parts = vec![
        (&meshes[0], Some(&f0)),
        (&meshes[1], None),
        (&meshes[2], Some(&f2)),
    ];
    let (m, f) = bundle::merge(&parts);
    let n: usize = meshes.iter().map(tris).sum();
    assert_eq!(m.indices.len() / 3, n);
    let f = f.unwrap();
    assert_eq!(f.elements.len(), 1, "one element, named once");
    let nulls = f.triangle.iter().filter(|&&k| k == 1).count();
    assert_eq!(nulls, tris(&meshes[1]), "the rep without elements is null");
    // Positions move by at most the new quantisation.
    let q = m.quantization_error()
        + meshes
            .iter()
            .map(|m| m.quantization_error())
            .fold(0.0, f32::max);
    let mut at = 0usize;
    for src in &meshes {
        for (t, tri) in src.indices.chunks(3).enumerate() {
            for (k, &i) in tri.iter().enumerate() {
                let a = src.position(&src.vertices[i as usize]);
                let b = m.position(&m.vertices[m.indices[3 * (at + t) + k] as usize]);
                let d = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt();
                assert!(d <= q * 1.01 + 1e-6, "moved {d} > {q}");
            }
        }
        at += tris(src);
    }
    // The GLB says which id is null, and decodes to the same triangles.
    let (doc, _, indices, ids) = decode(&glb::encode(&m, Some(&f)));
    let fid =
        &doc["meshes"][0]["primitives"][0]["extensions"]["EXT_mesh_features"]["featureIds"][0];
    assert_eq!(fid["nullFeatureId"], 1);
    assert_eq!(fid["featureCount"], 1);
    assert_eq!(indices.len(), m.indices.len());
    assert!(ids.iter().all(|&i| i == 0.0 || i == 1.0));
}

#[test]
fn a_bundled_export_has_fewer_tiles_draws_the_finest_triangles_and_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let scene = plant_scene(dir.path(), 60);
    let file = SceneFile::open(&scene).unwrap();
    let s = file.skeleton();
    let plain = export(&scene, &dir.path().join("plain"), ExportOptions::default()).unwrap();
    let opts = ExportOptions {
        bundle_bytes: 64 << 10,
        ..ExportOptions::default()
    };
    let out = dir.path().join("b");
    let r = export(&scene, &out, opts).unwrap();
    assert!(r.bundles > 0);
    assert!(
        r.tiles < plain.tiles,
        "{} tiles against {}",
        r.tiles,
        plain.tiles
    );
    assert!(r.contents < plain.contents);
    // Parents' errors bound their children's (checked by `tiles`); each
    // bundle's last tile holds its leaves' finest triangles.
    let (all, _) = tiles(&out);
    assert_eq!(all.len() as u64, r.tiles);
    let b = Bundles::new(s, opts.bundle_bytes);
    let mut last: BTreeMap<u32, (usize, String)> = BTreeMap::new();
    for (t, _) in &all {
        let Some(u) = t["content"]["uri"].as_str() else {
            continue;
        };
        assert!(out.join(u).is_file(), "{u}");
        if let Some(name) = u.strip_prefix("content/b") {
            let stem = name.rsplit('/').next().unwrap().trim_end_matches(".glb");
            let (root, k) = stem.split_once('-').unwrap();
            let (root, k): (u32, usize) = (root.parse().unwrap(), k.parse().unwrap());
            assert!(b.is_root(root));
            let e = last.entry(root).or_insert((k, u.to_string()));
            if k > e.0 {
                *e = (k, u.to_string());
            }
        } else {
            let rep: u32 = u
                .rsplit('/')
                .next()
                .unwrap()
                .trim_end_matches(".glb")
                .parse()
                .unwrap();
            assert!(
                !b.is_inside(s.reps[rep as usize].node),
                "rep {rep} is in a bundle"
            );
        }
    }
    assert_eq!(last.len(), b.roots.len());
    for (root, (_, u)) in &last {
        let mut ls = Vec::new();
        leaves(s, *root, &mut ls);
        let want: u64 = finest_of(s, &ls)
            .into_iter()
            .map(|r| u64::from(s.reps[r as usize].tri_count))
            .sum();
        let (_, _, indices, _) = decode(&fs::read(out.join(u)).unwrap());
        assert_eq!(indices.len() as u64 / 3, want, "bundle {root}");
    }
    // Deterministic, and split into small files alike.
    let again = dir.path().join("b2");
    export(&scene, &again, opts).unwrap();
    assert_eq!(files(&out), files(&again), "byte-identical");
    let small = dir.path().join("small");
    let r3 = export(
        &scene,
        &small,
        ExportOptions {
            max_tiles_per_json: 16,
            ..opts
        },
    )
    .unwrap();
    assert_eq!(
        (r3.tiles - r3.json_files + 1, r3.contents),
        (r.tiles, r.contents)
    );
}
