//! Multi-Triangulations end to end: built MTs validate, every cut is
//! crack-free, partitions respect θ, the file round-trips, the run-time cut
//! matches a cut computed from scratch, the footprint holds in every mode,
//! and corrupt partitions only keep their region at its level.

use std::sync::Arc;

use engine::camera::{Pose, View};
use engine::io::{ByteSource, MemSource};
use engine::mt::cache::CacheMode;
use engine::mt::cut::{MtCriterion, MtCut};
use engine::mt::file::{MtFile, encode, file_ids};
use engine::mt::store::MtStore;
use engine::mt::{Mt, partition};
use glam::Vec3;
use hlod_builder::mt::{MtBuildError, MtParams, build_mt};
use hlod_builder::scenegen::rock::rock;
use proptest::prelude::*;

fn rock_mt(tris: usize, seed: u64) -> Mt {
    let (p, n, i) = rock(tris, seed);
    build_mt(&p, &n, &i, &MtParams::default()).expect("builds")
}

/// A bumpy open sheet with a hole: borders outside and inside.
fn sheet(k: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>) {
    let mut p = Vec::new();
    for y in 0..=k {
        for x in 0..=k {
            let (fx, fy) = (x as f32 / k as f32, y as f32 / k as f32);
            p.push([fx, fy, 0.05 * (fx * 9.0).sin() * (fy * 7.0).cos()]);
        }
    }
    let mut idx = Vec::new();
    let r = (k + 1) as u32;
    for y in 0..k {
        for x in 0..k {
            let c = (x as f32 - k as f32 / 2.0).abs() < k as f32 / 10.0
                && (y as f32 - k as f32 / 2.0).abs() < k as f32 / 10.0;
            if c {
                continue;
            }
            let i = y as u32 * r + x as u32;
            idx.extend_from_slice(&[i, i + 1, i + r + 1, i, i + r + 1, i + r]);
        }
    }
    let n = vec![[0.0, 0.0, 1.0]; p.len()];
    (p, n, idx)
}

fn view(eye: Vec3, at: Vec3) -> View {
    View {
        pose: Pose::look_at(eye, at, 60.0),
        width_px: 640,
        height_px: 360,
        near: 1e-3,
        far: 1e3,
        section: engine::section::Section::NONE,
    }
}

#[test]
fn built_mts_validate_and_their_patches_are_reduced() {
    for mt in [rock_mt(40_000, 1), rock_mt(20_000, 7)] {
        mt.validate().expect("valid");
        assert!(mt.layers() >= 5, "{} layers", mt.layers());
        assert!(mt.mean_patch() >= 10.0, "mean patch {}", mt.mean_patch());
        assert!(mt.nodes.len() > 100);
    }
    let (p, n, i) = sheet(120);
    let mt = build_mt(&p, &n, &i, &MtParams::default()).unwrap();
    mt.validate().expect("open sheet with a hole");
}

#[test]
fn building_is_deterministic() {
    let a = rock_mt(20_000, 3);
    let b = rock_mt(20_000, 3);
    assert_eq!(a, b);
    let pa = partition(&a, 20).unwrap();
    assert_eq!(
        encode(&a, &pa).unwrap(),
        encode(&b, &partition(&b, 20).unwrap()).unwrap()
    );
}

#[test]
fn bad_input_is_refused_or_degrades() {
    let p = vec![
        [0.0f32; 3],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [f32::NAN, 0.0, 0.0],
    ];
    let n = vec![[0.0f32; 3]; 4];
    let d = MtParams::default();
    assert_eq!(
        build_mt(&p[..3], &n[..3], &[], &d),
        Err(MtBuildError::Empty)
    );
    assert_eq!(
        build_mt(&p[..3], &n[..3], &[0, 0, 1], &d),
        Err(MtBuildError::Empty)
    );
    assert_eq!(
        build_mt(&p, &n, &[0, 1, 3], &d),
        Err(MtBuildError::NotFinite(3))
    );
    assert_eq!(
        build_mt(&p[..3], &n[..3], &[0, 1, 7], &d),
        Err(MtBuildError::Index(0, 3))
    );
    let bad = MtParams {
        cluster_tris: 3,
        ..d
    };
    assert_eq!(
        build_mt(&p[..3], &n[..3], &[0, 1, 2], &bad),
        Err(MtBuildError::ClusterSize(3))
    );
    // Nothing to simplify: one node holding the input.
    let one = build_mt(&p[..3], &n[..3], &[0, 1, 2], &d).unwrap();
    one.validate().unwrap();
    assert_eq!(one.nodes.len(), 1);
    // Non-manifold: three triangles on one edge, and a duplicate.
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let n = vec![[0.0; 3]; 5];
    let nm = build_mt(&p, &n, &[0, 1, 2, 1, 0, 3, 0, 1, 4, 0, 1, 4], &d).unwrap();
    nm.validate().unwrap();
    assert_eq!(nm.input_triangles, 4);
    assert!(partition(&nm, 0).is_err());
    assert!(partition(&nm, engine::mt::partition::MAX_THETA + 1).is_err());
}

/// A random cut: each node refined with probability `p` if its fathers are.
fn random_cut(mt: &Mt, seed: u64, p: f64) -> Vec<bool> {
    let ins = mt.in_arcs();
    let mut s = seed | 1;
    let mut order: Vec<u32> = (0..mt.nodes.len() as u32).collect();
    order.sort_by_key(|&n| mt.nodes[n as usize].layer);
    let mut refined = vec![false; mt.nodes.len()];
    for n in order {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        let fathers_in = ins[n as usize]
            .iter()
            .all(|&a| refined[mt.arcs[a as usize].father as usize]);
        refined[n as usize] = n == 0 || (fathers_in && (s % 1000) as f64 / 1000.0 < p);
    }
    refined
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn every_cut_is_crack_free(seed in 1u64..u64::MAX, p in 0.3f64..1.0) {
        let mt = rock_mt(8_000, seed % 5);
        let topo = mt.topology(&vec![true; mt.nodes.len()]);
        let cut = random_cut(&mt, seed, p);
        prop_assert!(mt.is_cut(&cut));
        let r = mt.check_cut(&cut, &topo, "random");
        prop_assert!(r.is_ok(), "{:?}", r);
    }

    #[test]
    fn partitions_hold_every_node_once_within_theta(theta in 1u32..64, seed in 0u64..4) {
        let mt = rock_mt(6_000, seed);
        let p = partition(&mt, theta).unwrap();
        p.validate(&mt).unwrap();
        let members = p.members();
        prop_assert_eq!(members.iter().map(Vec::len).sum::<usize>(), mt.nodes.len());
        prop_assert!(members.iter().all(|m| !m.is_empty() && m.len() <= theta as usize));
        if theta == 1 {
            prop_assert_eq!(p.count as usize, mt.nodes.len());
        }
    }
}

fn open(mt: &Mt, theta: u32) -> (Arc<MtFile>, Vec<u32>, u64) {
    let parts = partition(mt, theta).unwrap();
    let bytes = encode(mt, &parts).unwrap();
    let len = bytes.len() as u64;
    let src: Arc<dyn ByteSource> = Arc::new(MemSource::new(bytes));
    (Arc::new(MtFile::open(src).unwrap()), file_ids(&parts), len)
}

/// The cut in the Mt's own node ids.
fn as_mt_cut(cut: &MtCut, ids: &[u32]) -> Vec<bool> {
    ids.iter().map(|&f| cut.refined()[f as usize]).collect()
}

fn path(frames: usize) -> Vec<View> {
    (0..frames)
        .map(|k| {
            let t = k as f32 / frames as f32;
            let a = t * std::f32::consts::TAU;
            let d = 6.0 - 4.6 * t;
            view(Vec3::new(a.sin(), 0.3, a.cos()) * d, Vec3::ZERO)
        })
        .collect()
}

#[test]
fn file_round_trips_every_node() {
    let mt = rock_mt(10_000, 2);
    let (f, ids, _) = open(&mt, 20);
    let nodes = f.read_nodes(0, f.header.node_count).unwrap();
    let tris: u64 = nodes
        .iter()
        .map(|n| {
            let n = n.as_ref().unwrap();
            (0..n.arc_at.len())
                .map(|k| u64::from(n.arc(k).0.tri_count))
                .sum::<u64>()
        })
        .sum();
    assert_eq!(tris, mt.arc_triangles());
    for (old, nd) in mt.nodes.iter().enumerate() {
        let got = nodes[ids[old] as usize].as_ref().unwrap();
        assert_eq!(got.head.layer, nd.layer);
        assert_eq!(got.head.error, nd.error);
        assert_eq!(got.arc_at.len(), mt.out_arcs(old as u32).len());
    }
}

#[test]
fn the_incremental_cut_is_the_cut_from_scratch() {
    let mt = rock_mt(20_000, 4);
    let (f, ids, len) = open(&mt, 20);
    let topo = mt.topology(&vec![true; mt.nodes.len()]);
    for mode in CacheMode::ALL {
        let mut store = MtStore::new(f.clone(), mode, 4 * len).unwrap();
        let mut cut = MtCut::start(&mut store).unwrap();
        for (k, v) in path(90).iter().enumerate() {
            let c = MtCriterion::new(*v, 1.0);
            let st = cut.adapt(&c, &mut store);
            assert_eq!(st.misses, 0);
            cut.end_frame(k as i64, &mut store);
            let mut fresh_store = MtStore::new(f.clone(), CacheMode::NpNc, 4 * len).unwrap();
            let mut fresh = MtCut::start(&mut fresh_store).unwrap();
            fresh.adapt(&c, &mut fresh_store);
            assert_eq!(cut.refined(), fresh.refined(), "{mode:?} frame {k}");
            mt.check_cut(&as_mt_cut(&cut, &ids), &topo, "run time")
                .unwrap();
            assert_eq!(
                cut.triangle_count(),
                mt.cut_triangles(&as_mt_cut(&cut, &ids)).len() as u64
            );
        }
    }
}

#[test]
fn the_footprint_holds_in_every_mode_and_frame() {
    let mt = rock_mt(20_000, 5);
    let (f, ids, len) = open(&mt, 20);
    let topo = mt.topology(&vec![true; mt.nodes.len()]);
    for mode in CacheMode::ALL {
        for budget in [len / 8, len / 3, len] {
            let mut store = MtStore::new(f.clone(), mode, budget).unwrap();
            let mut cut = MtCut::start(&mut store).unwrap();
            let mut missed = 0;
            for (k, v) in path(120).iter().enumerate() {
                missed += cut.adapt(&MtCriterion::new(*v, 0.5), &mut store).misses;
                cut.end_frame(k as i64, &mut store);
                let peak = store.take_peak();
                assert!(peak <= budget, "{mode:?} {budget}: {peak} held");
                assert!(store.resident_bytes() <= budget);
                mt.check_cut(&as_mt_cut(&cut, &ids), &topo, "under budget")
                    .unwrap();
            }
            if budget == len / 8 {
                assert!(missed > 0, "{mode:?}: a tight footprint refuses some nodes");
            }
        }
    }
    assert!(MtStore::new(f.clone(), CacheMode::PC, 100).is_err());
}

#[test]
fn a_corrupt_partition_keeps_its_region_and_the_run_goes_on() {
    let mt = rock_mt(20_000, 6);
    let parts = partition(&mt, 20).unwrap();
    let mut bytes = encode(&mt, &parts).unwrap();
    let clean = MtFile::open(Arc::new(MemSource::new(bytes.clone()))).unwrap();
    // Flip a byte in the middle of every fifth partition past the first.
    let mut hit = 0;
    for p in clean.parts.iter().skip(1).step_by(5) {
        let d = clean.dir[p.first as usize];
        let at = (clean.header.data_offset + d.offset + u64::from(d.len) / 2) as usize;
        bytes[at] ^= 0x5a;
        hit += 1;
    }
    let f = Arc::new(MtFile::open(Arc::new(MemSource::new(bytes))).unwrap());
    let ids = file_ids(&parts);
    let topo = mt.topology(&vec![true; mt.nodes.len()]);
    for mode in CacheMode::ALL {
        let mut store = MtStore::new(f.clone(), mode, u64::MAX).unwrap();
        let mut cut = MtCut::start(&mut store).unwrap();
        for (k, v) in path(60).iter().enumerate() {
            cut.adapt(&MtCriterion::new(*v, 0.5), &mut store);
            cut.end_frame(k as i64, &mut store);
            mt.check_cut(&as_mt_cut(&cut, &ids), &topo, "corrupt")
                .unwrap();
        }
        assert!(
            store.stats.corrupt > 0 && store.stats.corrupt <= hit * 20,
            "{:?}",
            store.stats
        );
    }
}

#[test]
fn a_damaged_file_is_refused_with_the_part_named() {
    let mt = rock_mt(4_000, 1);
    let bytes = encode(&mt, &partition(&mt, 20).unwrap()).unwrap();
    let open = |b: Vec<u8>| {
        MtFile::open(Arc::new(MemSource::new(b)))
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    let mut b = bytes.clone();
    b[0] ^= 1;
    assert!(open(b).contains("magic"));
    let mut b = bytes.clone();
    b[20] ^= 1;
    assert!(open(b).contains("header"));
    let mut b = bytes.clone();
    b[140] ^= 1;
    assert!(open(b).contains("directory"));
    assert!(open(bytes[..bytes.len() - 1].to_vec()).contains("header"));
    assert!(open(bytes[..50].to_vec()).contains("no header"));
}
