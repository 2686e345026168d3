//! Run-time refinement of view-dependence trees: in core, external memory
//! (meta-node buffers) and the virtual-memory baseline, on the shipped bunny.

use std::collections::BTreeSet;
use std::sync::{Arc, OnceLock};

use engine::camera::{Pose, View};
use engine::io::MemSource;
use engine::vdt::VdTree;
use engine::vdt::ext::ExtStore;
use engine::vdt::file::{VdtFile, encode};
use engine::vdt::refine::{Criterion, NodeStore, Refiner};
use engine::vdt::virt::VirtStore;
use glam::Vec3;
use hlod_builder::vdt::{VdtParams, build_tree};

fn bunny() -> &'static (VdTree, Vec<u8>) {
    static T: OnceLock<(VdTree, Vec<u8>)> = OnceLock::new();
    T.get_or_init(|| {
        let imp = hlod_builder::import::load(&e2e_tests::data_dir().join("bunny.glb")).unwrap();
        let m = imp.meshes.iter().flatten().next().unwrap();
        let t = build_tree(&m.positions, &m.indices, &VdtParams::default());
        t.validate().unwrap();
        let bytes = encode(&t, engine::vdt::meta::levels_for_block(4096));
        (t, bytes)
    })
}

fn open(bytes: &[u8]) -> Arc<VdtFile> {
    Arc::new(VdtFile::open(Arc::new(MemSource::new(bytes.to_vec()))).unwrap())
}

fn bounds(t: &VdTree) -> (Vec3, Vec3) {
    t.positions
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(a, b), p| {
            (a.min(Vec3::from(*p)), b.max(Vec3::from(*p)))
        })
}

fn view(eye: Vec3, target: Vec3) -> View {
    View {
        pose: Pose::look_at(eye, target, 60.0),
        width_px: 640,
        height_px: 480,
        near: 1e-4,
        far: 1e4,
        section: engine::section::Section::NONE,
    }
}

/// A seeded orbit with random radius and height changes.
fn random_path(t: &VdTree, frames: usize, seed: u64) -> Vec<View> {
    let (lo, hi) = bounds(t);
    let (c, r) = ((lo + hi) * 0.5, (hi - lo).length());
    let mut s = seed;
    let mut rnd = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 33) as f64 / (1u64 << 31) as f64) as f32
    };
    let (mut a, mut d, mut y) = (0.0f32, 1.5f32, 0.0f32);
    (0..frames)
        .map(|_| {
            a += 0.05 + 0.2 * rnd();
            d = (d + 0.3 * (rnd() - 0.5)).clamp(0.35, 3.0);
            y = (y + 0.3 * (rnd() - 0.5)).clamp(-0.8, 0.8);
            let eye = c + r * d * Vec3::new(a.cos(), y, a.sin());
            view(eye, c + (rnd() - 0.5) * 0.2 * r)
        })
        .collect()
}

/// Active triangles whose shown normal points against their
/// full-resolution normal.
fn flips(t: &VdTree, r: &Refiner) -> usize {
    r.triangles()
        .iter()
        .filter(|(_, leaves, q)| {
            let o = leaves.map(|l| Vec3::from(t.positions[l as usize]));
            let n0 = (o[1] - o[0]).cross(o[2] - o[0]);
            let n1 = (q[1] - q[0]).cross(q[2] - q[0]);
            n0.dot(n1) < 0.0
        })
        .count()
}

/// A refiner from the roots, run until quiet (see `refine_until_quiet`).
fn run_until_quiet<S: NodeStore>(
    store: &mut S,
    c: &Criterion,
    poll: impl FnMut(&mut S),
) -> Refiner {
    let mut r = Refiner::new(store).unwrap();
    refine_until_quiet(&mut r, store, c, poll);
    r
}

/// Passes (polling the store's I/O) until four quiet passes in a row.
fn refine_until_quiet<S: NodeStore>(
    r: &mut Refiner,
    store: &mut S,
    c: &Criterion,
    mut poll: impl FnMut(&mut S),
) {
    let mut quiet = 0;
    for _ in 0..4000 {
        poll(store);
        let s = r.pass(store, c).unwrap();
        if s.adapt() == 0 && s.misses == 0 {
            quiet += 1;
            if quiet > 3 {
                break;
            }
        } else {
            quiet = 0;
        }
        if s.misses > 0 {
            std::thread::sleep(std::time::Duration::from_micros(300));
        }
    }
}

fn ext_poll(e: &mut ExtStore) {
    e.poll().unwrap();
    e.validate().unwrap();
}

#[test]
fn refining_every_node_gives_back_the_input_in_all_three_stores() {
    let (t, bytes) = bunny();
    let (lo, hi) = bounds(t);
    let centre = (lo + hi) * 0.5;
    let c = Criterion::new(
        view(centre + Vec3::Z * (hi - lo).length() * 2.0, centre),
        0.0,
    );
    let all: BTreeSet<u32> = (0..t.triangles.len() as u32).collect();
    let file = open(bytes);
    let size = bytes.len() as u64;
    let results = [
        ("incore", run_until_quiet(&mut t.clone(), &c, |_| {})),
        (
            "ext",
            run_until_quiet(
                &mut ExtStore::start(file.clone(), 2 * size).unwrap(),
                &c,
                ext_poll,
            ),
        ),
        (
            "virt",
            run_until_quiet(&mut VirtStore::start(file, 2 * size).unwrap(), &c, |_| {}),
        ),
    ];
    for (name, r) in &results {
        let shown = r.triangles();
        let ids: BTreeSet<u32> = shown.iter().map(|x| x.0).collect();
        assert!(
            ids == all,
            "{name}: {} of {} triangles",
            ids.len(),
            all.len()
        );
        assert_eq!(r.active_count(), t.leaf_count(), "{name}");
        for (_, leaves, q) in &shown {
            assert_eq!(
                leaves.map(|l| Vec3::from(t.positions[l as usize])),
                *q,
                "{name}"
            );
        }
    }
}

#[test]
fn implicit_dependencies_prevent_fold_overs_on_random_paths() {
    let (t, _) = bunny();
    let mut worst = 0;
    let mut frames = 0;
    for seed in [1, 2, 3] {
        let mut store = t.clone();
        let mut r = Refiner::new(&mut store).unwrap();
        for v in random_path(t, 150, seed) {
            let c = Criterion::new(v, 0.3);
            r.pass(&mut store, &c).unwrap();
            worst = worst.max(flips(t, &r));
            frames += 1;
        }
        assert!(r.triangle_count() > 1000, "the paths do refine");
    }
    assert_eq!(worst, 0, "fold-overs in some of {frames} frames");
}

#[test]
fn paged_stores_follow_the_in_core_refinement_and_keep_the_footprint() {
    let (t, bytes) = bunny();
    let file = open(bytes);
    let path = random_path(t, 120, 7);
    // In core, one pass per frame: the reference.
    let mut mem = t.clone();
    let mut reference = Refiner::new(&mut mem).unwrap();
    let mut ref_active = Vec::new();
    for v in &path {
        reference.pass(&mut mem, &Criterion::new(*v, 0.3)).unwrap();
        ref_active.push(reference.active_ids().collect::<Vec<_>>());
    }
    // The baseline waits on every fault: it makes the same choices, under
    // a footprint of the in-core part and 256 KiB.
    let budget = file.core_bytes() + 256 * 1024;
    let mut virt = VirtStore::start(file.clone(), budget).unwrap();
    let mut r = Refiner::new(&mut virt).unwrap();
    for (k, v) in path.iter().enumerate() {
        r.pass(&mut virt, &Criterion::new(*v, 0.3)).unwrap();
        assert!(virt.resident_bytes() <= budget);
        assert_eq!(
            r.active_ids().collect::<Vec<_>>(),
            ref_active[k],
            "virt frame {k}"
        );
    }
    assert!(
        virt.pager.stats.faults > budget / 4096,
        "pages were replaced"
    );
    // External memory at the same footprint: misses allowed, the budget
    // and the bookkeeping hold every frame; with room for the whole tree it
    // catches up with the in-core cut at the end.
    let last = Criterion::new(*path.last().unwrap(), 0.3);
    let mut settled = t.clone();
    let mut want = Refiner::new(&mut settled).unwrap();
    want.settle(&mut settled, &last, 200).unwrap();
    let want: Vec<u32> = want.active_ids().collect();
    for budget in [budget, file.core_bytes() + file.header.data_len] {
        let mut ext = ExtStore::start(file.clone(), budget).unwrap();
        let mut r = Refiner::new(&mut ext).unwrap();
        let mut misses = 0;
        for v in &path {
            ext.poll().unwrap();
            misses += r.pass(&mut ext, &Criterion::new(*v, 0.3)).unwrap().misses;
            assert!(ext.resident_bytes() <= budget);
            ext.validate().unwrap();
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        eprintln!(
            "ext at {budget} B: {misses} misses over {} frames, {:?}",
            path.len(),
            ext.stats
        );
        if budget > file.header.data_len {
            refine_until_quiet(&mut r, &mut ext, &last, |e| e.poll().unwrap());
            assert!(
                r.active_ids().eq(want.iter().copied()),
                "ext did not catch up"
            );
        } else {
            assert!(
                misses > 0 && ext.stats.give_ups > 0,
                "the tight footprint binds"
            );
        }
    }
}

#[test]
fn bad_files_are_refused_and_a_corrupt_meta_node_keeps_its_part_coarse() {
    let (t, bytes) = bunny();
    let src = |b: Vec<u8>| VdtFile::open(Arc::new(MemSource::new(b)));
    assert!(src(bytes[..100].to_vec()).is_err(), "truncated header");
    assert!(
        src(bytes[..bytes.len() - 1].to_vec()).is_err(),
        "truncated file"
    );
    let mut b = bytes.clone();
    b[0] ^= 1;
    assert!(src(b).is_err(), "magic");
    let mut b = bytes.clone();
    b[120] ^= 1;
    assert!(src(b).is_err(), "MNT checksum");
    // Flip one byte in every meta-node below the roots' children: those
    // reads fail their checksum; the run goes on at the level it has.
    let file = open(bytes);
    let roots = file.header.root_count as usize;
    let mut b = bytes.clone();
    for r in &file.mnt[roots..] {
        if r.parent as usize >= roots {
            b[(file.header.data_offset + r.offset + 20) as usize] ^= 0x10;
        }
    }
    let bad = Arc::new(src(b).unwrap());
    let mut ext = ExtStore::start(bad, bytes.len() as u64).unwrap();
    let (lo, hi) = bounds(t);
    let centre = (lo + hi) * 0.5;
    let c = Criterion::new(view(centre + Vec3::Z * (hi - lo).length(), centre), 0.5);
    let r = run_until_quiet(&mut ext, &c, |e| e.poll().unwrap());
    assert!(ext.stats.failed > 0);
    assert!(r.triangle_count() > 0 && r.triangle_count() < t.triangles.len());
}
