//! Section planes and hidden elements in the runtime: what a section
//! removes, or the user hides, leaves P_R's front and every front P_I plans
//! from, so it is neither drawn nor read.

use std::sync::{Arc, Mutex};

use glam::Vec3;

use super::tests::{check_frames, params, pose, start, wide};
use super::*;
use crate::format::RepRecord;
use crate::io::ByteSource;
use crate::section::Section;

/// A source that logs the byte ranges read.
struct Logged {
    inner: Arc<dyn ByteSource>,
    reads: Mutex<Vec<(u64, u64)>>,
}

impl ByteSource for Logged {
    fn len(&self) -> u64 {
        self.inner.len()
    }
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        if let Ok(mut r) = self.reads.lock() {
            r.push((offset, offset + buf.len() as u64));
        }
        self.inner.read_at(offset, buf)
    }
}

/// Records the reps drawn.
#[derive(Default)]
struct Drawn(Vec<RepId>);

impl Renderer for Drawn {
    fn begin_frame(&mut self, _view: &View) {}
    fn draw(&mut self, rep: RepId, _rec: &RepRecord, _payload: &Arc<[u8]>, _s: DrawStyle) {
        self.0.push(rep);
    }
    fn end_frame(&mut self) {}
    fn name(&self) -> &'static str {
        "drawn"
    }
}

/// The reps of nodes wholly on the removed side of `section`.
fn removed(skel: &Skeleton, section: &Section) -> Vec<RepId> {
    (0..skel.reps.len() as RepId)
        .filter(|&r| {
            let n = &skel.nodes[skel.reps[r as usize].node as usize];
            !section.keeps_box(Vec3::from(n.bbox_min), Vec3::from(n.bbox_max))
        })
        .collect()
}

/// Along the row of leaves and back, looking at it.
fn along() -> Vec<Pose> {
    (0..=128)
        .chain((0..=128).rev())
        .map(|i| pose(i as f32 * 0.5, 0.5, 3.0, 0.0))
        .collect()
}

/// Walks `poses` with `section` (from the first frame, or from `from`);
/// the reps drawn from then on and the byte ranges read.
fn walk(mode: Mode, section: Section, from: usize) -> (Vec<RepId>, Vec<(u64, u64)>, u64) {
    let (skel, src) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    let budget = total / 3;
    let logged = Arc::new(Logged {
        inner: src,
        reads: Mutex::new(Vec::new()),
    });
    let p = RuntimeParams {
        // Reads never run through a gap between wanted reps.
        coalesce_max_gap: 0,
        ..params(mode, budget)
    };
    let mut w = start(skel, logged.clone(), p).unwrap();
    let mut drawn = Drawn::default();
    let mut reads_from = 0;
    for (i, ps) in along().iter().enumerate() {
        if i == from {
            w.set_section(section);
            drawn.0.clear();
            reads_from = logged.reads.lock().unwrap().len();
        }
        let f = w.frame(ps, &mut drawn).unwrap();
        check_frames(std::slice::from_ref(&f), budget);
    }
    drop(w);
    let reads = logged.reads.lock().unwrap()[reads_from..].to_vec();
    (drawn.0, reads, budget)
}

fn read_any(skel: &Skeleton, reps: &[RepId], reads: &[(u64, u64)]) -> Vec<RepId> {
    reps.iter()
        .copied()
        .filter(|&r| {
            let rec = &skel.reps[r as usize];
            let (a, b) = (rec.offset, rec.offset + u64::from(rec.len));
            reads.iter().any(|&(x, y)| x < b && a < y)
        })
        .collect()
}

#[test]
fn what_a_section_removes_is_neither_drawn_nor_read() {
    let (skel, _) = wide(64);
    // Everything beyond x = 32.5 is cut away (leaves 33..63).
    let cut = Section::from_planes(&[(Vec3::new(32.5, 0.0, 0.0), Vec3::X)]).unwrap();
    let gone = removed(&skel, &cut);
    assert!(gone.len() > skel.reps.len() / 3, "{} reps", gone.len());
    for mode in [Mode::NoPre, Mode::Pre] {
        let (drawn, reads, _) = walk(mode, cut, 0);
        let bad: Vec<_> = drawn.iter().filter(|r| gone.contains(r)).collect();
        assert!(bad.is_empty(), "{mode:?}: drawn {bad:?}");
        assert!(!drawn.is_empty());
        let bad = read_any(&skel, &gone, &reads);
        assert!(bad.is_empty(), "{mode:?}: read {bad:?}");
        // The control: without the section the same walk draws and reads them.
        let (drawn, reads, _) = walk(mode, Section::NONE, 0);
        assert!(drawn.iter().any(|r| gone.contains(r)), "{mode:?}");
        assert!(!read_any(&skel, &gone, &reads).is_empty(), "{mode:?}");
    }
}

#[test]
fn a_section_set_mid_walk_takes_effect_at_the_next_frame() {
    let (skel, _) = wide(64);
    // A box around leaves 8..16: the rest of the row leaves.
    let bx = Section::boxed(Vec3::new(8.2, -1.0, -1.0), Vec3::new(15.8, 2.0, 2.0)).unwrap();
    let gone = removed(&skel, &bx);
    let (drawn, _, _) = walk(Mode::Pre, bx, 100);
    assert!(!drawn.is_empty());
    let bad: Vec<_> = drawn.iter().filter(|r| gone.contains(r)).collect();
    assert!(bad.is_empty(), "drawn after the section was set: {bad:?}");
}

#[test]
fn hidden_elements_are_neither_drawn_nor_read() {
    use crate::format::objects::ObjectTable;
    use crate::hide::Hiding;
    // The same row, its leaves naming objects 0..63; objects 33.. hidden.
    let infos: Vec<String> = (0..64).map(|k| format!("{{\"name\":\"o{k}\"}}")).collect();
    let (shape, kids) = super::tests::wide_shape(64);
    let (bytes, _) =
        crate::testutil::build_with(&shape, &kids, [0.0; 3], &ObjectTable::encode(&infos, &[]));
    let file =
        crate::format::SceneFile::from_source(crate::io::MemSource::new(bytes.clone())).unwrap();
    let skel = Arc::new(file.skeleton().clone());
    let table = file.read_objects().unwrap();
    let hiding = Hiding::new(&skel, &table, |k| k >= 33);
    let gone: Vec<RepId> = (0..skel.reps.len() as RepId)
        .filter(|&r| {
            let n = skel.reps[r as usize].node as usize;
            hiding.nodes()[n] == crate::hide::NodeVis::Hidden
        })
        .collect();
    assert!(gone.len() > skel.reps.len() / 3, "{} reps", gone.len());
    for (mode, hide) in [(Mode::Pre, true), (Mode::NoPre, true), (Mode::Pre, false)] {
        let logged = Arc::new(Logged {
            inner: Arc::new(crate::io::MemSource::new(bytes.clone())),
            reads: Mutex::new(Vec::new()),
        });
        let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
        let p = RuntimeParams {
            coalesce_max_gap: 0,
            ..params(mode, total / 3)
        };
        let mut w = start(skel.clone(), logged.clone(), p).unwrap();
        let reads0 = logged.reads.lock().unwrap().len();
        if hide {
            w.set_hiding(&hiding);
        }
        let mut drawn = Drawn::default();
        for ps in along() {
            let f = w.frame(&ps, &mut drawn).unwrap();
            check_frames(std::slice::from_ref(&f), total / 3);
        }
        drop(w);
        let reads = logged.reads.lock().unwrap()[reads0..].to_vec();
        let drew = drawn.0.iter().any(|r| gone.contains(r));
        let read = !read_any(&skel, &gone, &reads).is_empty();
        assert_eq!((drew, read), (!hide, !hide), "{mode:?}, hidden {hide}");
    }
}
