use glam::{Vec2, Vec3};

use super::*;
use crate::io::{ByteSource, MemSource};

const DT: f32 = 1.0 / 60.0;

fn grid() -> SpanGrid {
    SpanGrid::new(Grid {
        cell: 0.1,
        quantum: 0.02,
        y_base: -1.0,
    })
}

/// A 20 × 20 m floor slab, its top at 0.
fn floor() -> SpanGrid {
    let mut g = grid();
    g.insert_box(Vec3::new(-10.0, -0.3, -10.0), Vec3::new(10.0, 0.0, 10.0));
    g
}

/// Walks at 1.4 m/s towards `dir` for `secs` seconds.
fn walk(w: &mut Walker, map: &mut impl SolidMap, dir: Vec2, secs: f32) -> Moved {
    let mut all = Moved::default();
    for _ in 0..(secs / DT) as usize {
        let m = w.step(map, dir.normalize() * 1.4 * DT, DT).unwrap();
        all.blocked |= m.blocked;
        all.fell += m.fell;
    }
    all
}

fn standing(map: &mut impl SolidMap, x: f32, z: f32, y: f32) -> Walker {
    Walker::from_eye(Body::default(), map, Vec3::new(x, y + 1.6, z)).unwrap()
}

#[test]
fn a_wall_stops_the_walker_and_it_slides_along() {
    let mut g = floor();
    g.insert_box(Vec3::new(2.0, 0.0, -10.0), Vec3::new(2.2, 2.7, 10.0));
    let mut w = standing(&mut g, 0.0, 0.0, 0.0);
    assert!(w.grounded());
    assert!((w.eye().y - 1.6).abs() < 1e-3, "eye at 1.6 m over the slab");
    let m = walk(&mut w, &mut g, Vec2::X, 3.0);
    assert!(m.blocked);
    assert!(
        w.feet().x < 2.0 - 0.15 && w.feet().x > 1.6,
        "stopped at the wall: {}",
        w.feet()
    );
    // Along the wall, diagonally: the x part is refused, the z part taken.
    let z0 = w.feet().z;
    walk(&mut w, &mut g, Vec2::new(1.0, 1.0), 2.0);
    assert!(
        w.feet().x < 2.0 - 0.15 && w.feet().z > z0 + 1.5,
        "slid: {}",
        w.feet()
    );
    assert_eq!(w.feet().y, 0.0);
}

#[test]
fn a_corridor_is_walked_and_a_door_passed_but_not_a_slit() {
    let mut g = floor();
    // A corridor along z, 1.2 m wide, closed by a wall with a 0.9 m door
    // at z = 5 and a wall with a 0.3 m slit at z = 8.
    g.insert_box(Vec3::new(-0.8, 0.0, -10.0), Vec3::new(-0.6, 2.7, 10.0));
    g.insert_box(Vec3::new(0.6, 0.0, -10.0), Vec3::new(0.8, 2.7, 10.0));
    g.insert_box(Vec3::new(-0.6, 0.0, 5.0), Vec3::new(-0.45, 2.7, 5.1));
    g.insert_box(Vec3::new(0.45, 0.0, 5.0), Vec3::new(0.6, 2.7, 5.1));
    g.insert_box(Vec3::new(-0.6, 2.1, 5.0), Vec3::new(0.6, 2.7, 5.1));
    g.insert_box(Vec3::new(-0.6, 0.0, 8.0), Vec3::new(-0.15, 2.7, 8.1));
    g.insert_box(Vec3::new(0.15, 0.0, 8.0), Vec3::new(0.6, 2.7, 8.1));
    let mut w = standing(&mut g, 0.0, -5.0, 0.0);
    walk(&mut w, &mut g, Vec2::Y, 12.0);
    let z = w.feet().z;
    assert!(
        z > 5.1 && z < 8.0 - 0.15,
        "through the door, stopped at the slit: {z}"
    );
    assert!(w.feet().x.abs() < 0.4, "stayed in the corridor");
}

/// A straight flight of 16 risers of 0.18 m and treads of 0.28 m from z = 0
/// up to an upper floor at 2.88 m with a stairwell, and a lower floor.
fn two_storeys() -> SpanGrid {
    let mut g = floor();
    for k in 0..16 {
        let z = k as f32 * 0.28;
        let top = (k + 1) as f32 * 0.18;
        g.insert_box(Vec3::new(-0.5, top - 0.2, z), Vec3::new(0.5, top, z + 0.28));
    }
    let (y0, y1) = (16.0 * 0.18 - 0.25, 16.0 * 0.18);
    g.insert_box(Vec3::new(-10.0, y0, 16.0 * 0.28), Vec3::new(10.0, y1, 10.0));
    g.insert_box(
        Vec3::new(-10.0, y0, -10.0),
        Vec3::new(-0.6, y1, 16.0 * 0.28),
    );
    g.insert_box(Vec3::new(0.6, y0, -10.0), Vec3::new(10.0, y1, 16.0 * 0.28));
    g
}

#[test]
fn a_stair_is_climbed_and_walked_down_but_a_high_ledge_is_not() {
    let mut g = two_storeys();
    let mut w = standing(&mut g, 0.0, -1.0, 0.0);
    let m = walk(&mut w, &mut g, Vec2::Y, 6.0);
    assert!((w.feet().y - 2.88).abs() < 0.03, "climbed: {}", w.feet());
    assert!(w.feet().z > 16.0 * 0.28, "on the upper floor");
    assert!(m.fell < 0.05, "no fall on the way up");
    let m = walk(&mut w, &mut g, -Vec2::Y, 7.0);
    assert!(w.feet().y.abs() < 0.03, "walked down: {}", w.feet());
    assert!(m.fell < 0.3, "stepped down, not fell: {}", m.fell);
    // A 0.5 m ledge is a wall.
    let mut g = floor();
    g.insert_box(Vec3::new(1.0, 0.0, -10.0), Vec3::new(5.0, 0.5, 10.0));
    let mut w = standing(&mut g, 0.0, 0.0, 0.0);
    walk(&mut w, &mut g, Vec2::X, 3.0);
    assert!(w.feet().x < 1.0 && w.feet().y == 0.0, "{}", w.feet());
}

#[test]
fn walking_off_a_slab_edge_falls_to_the_floor_below() {
    let mut g = two_storeys();
    // On the upper floor beside the stairwell, walking into it sideways.
    let mut w = standing(&mut g, 2.0, 2.0, 2.88);
    assert!(w.grounded());
    let m = walk(&mut w, &mut g, -Vec2::X, 2.5);
    assert!(w.grounded(), "landed");
    assert!(w.feet().y < 2.5, "fell: {}", w.feet());
    assert!(m.fell > 0.5, "a fall, not steps: {}", m.fell);
    // It lands on the flight (on a tread) or the floor, never inside it.
    let top = ((2.0f32 / 0.28).floor() + 1.0) * 0.18;
    assert!(
        w.feet().y >= -0.001 && w.feet().y <= top + 0.2,
        "{}",
        w.feet()
    );
}

#[test]
fn a_fast_fall_never_passes_a_thin_slab() {
    let mut g = grid();
    g.insert_box(Vec3::new(-5.0, 0.0, -5.0), Vec3::new(5.0, 0.02, 5.0));
    let mut w = standing(&mut g, 0.0, 0.0, 200.0);
    assert!(!w.grounded());
    for _ in 0..600 {
        w.step(&mut g, Vec2::ZERO, 0.25).unwrap();
    }
    assert!(
        w.grounded() && (w.feet().y - 0.02).abs() < 0.021,
        "{}",
        w.feet()
    );
}

#[test]
fn a_low_ceiling_stops_the_walker() {
    let mut g = floor();
    g.insert_box(Vec3::new(1.0, 1.5, -10.0), Vec3::new(5.0, 1.7, 10.0));
    let mut w = standing(&mut g, 0.0, 0.0, 0.0);
    walk(&mut w, &mut g, Vec2::X, 3.0);
    assert!(w.feet().x < 1.0, "{}", w.feet());
}

#[test]
fn triangles_fill_the_cells_they_touch_with_their_heights() {
    let mut g = grid();
    // A sloped triangle over x, z in [0, 1]: y = x.
    g.insert_triangle(
        Layer::Solid,
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ],
    );
    let gr = g.grid();
    let col = g.column(5, 2).unwrap().solid.to_vec();
    assert_eq!(col.len(), 1);
    let (lo, hi) = (gr.height(col[0].lo), gr.height(col[0].hi));
    assert!(
        (0.47..=0.5 + 1e-4).contains(&lo) && (0.6 - 1e-4..0.63).contains(&hi),
        "{lo} {hi}"
    );
    assert!(
        g.column(9, 9).unwrap().solid.is_empty(),
        "beyond the hypotenuse"
    );
    // A vertical wall triangle marks the cells along its foot.
    g.insert_triangle(
        Layer::Solid,
        [
            Vec3::new(3.05, 0.0, 0.0),
            Vec3::new(3.05, 0.0, 2.0),
            Vec3::new(3.05, 2.5, 1.0),
        ],
    );
    assert!(!g.column(30, 10).unwrap().solid.is_empty());
    assert!(g.column(31, 10).unwrap().solid.is_empty());
}

#[test]
fn the_union_does_not_depend_on_the_order_of_the_triangles() {
    let tris: Vec<[Vec3; 3]> = (0..200)
        .map(|k| {
            let f = k as f32;
            [
                Vec3::new((f * 0.37) % 7.0, (f * 0.11) % 3.0, (f * 0.53) % 7.0),
                Vec3::new((f * 0.71) % 7.0, (f * 0.29) % 3.0, (f * 0.13) % 7.0),
                Vec3::new((f * 0.19) % 7.0, (f * 0.07) % 3.0, (f * 0.91) % 7.0),
            ]
        })
        .collect();
    let mut a = grid();
    let mut b = grid();
    for t in &tris {
        a.insert_triangle(Layer::Solid, *t);
    }
    for t in tris.iter().rev() {
        b.insert_triangle(Layer::Solid, *t);
    }
    assert_eq!(a.encode(), b.encode());
}

/// A source that fails every read after `ok` reads.
struct Failing(MemSource, std::sync::atomic::AtomicU32);
impl ByteSource for Failing {
    fn len(&self) -> u64 {
        self.0.len()
    }
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        if self.1.fetch_sub(1, std::sync::atomic::Ordering::Relaxed) == 0 {
            return Err(std::io::Error::other("disk gone"));
        }
        self.0.read_at(offset, buf)
    }
}

#[test]
fn the_paged_map_walks_as_the_memory_one_within_its_cap() {
    let mut g = two_storeys();
    // Walls in many chunks, so that the walk crosses them.
    for k in -2..3 {
        g.insert_box(
            Vec3::new(k as f32 * 3.3, 0.0, -9.0),
            Vec3::new(k as f32 * 3.3 + 0.1, 1.0, -8.0),
        );
    }
    let section = g.encode();
    let index = crate::format::walk::WalkIndex::decode(&section, section.len() as u64).unwrap();
    let one_chunk = 40 * 1024;
    let mut paged = WalkMap::new(MemSource::new(section.clone()), 0, index.clone(), one_chunk);
    let (mut a, mut b) = (
        standing(&mut g, -9.0, -9.5, 0.0),
        standing(&mut paged, -9.0, -9.5, 0.0),
    );
    for (dir, secs) in [(Vec2::X, 12.0), (Vec2::Y, 4.0), (Vec2::new(0.6, 1.0), 10.0)] {
        walk(&mut a, &mut g, dir, secs);
        walk(&mut b, &mut paged, dir, secs);
        assert_eq!(a.feet(), b.feet());
        assert!(paged.resident_bytes() <= paged.index_bytes() + one_chunk.max(20_000));
    }
    assert!(paged.reads >= 6, "chunks were paged: {} reads", paged.reads);
    // A read error mid-walk is an error, not a panic.
    let failing = Failing(MemSource::new(section), 2.into());
    let mut broken = WalkMap::new(failing, 0, index, 0);
    let mut w = standing(&mut broken, -9.0, -9.5, 0.0);
    let mut err = None;
    for _ in 0..2000 {
        if let Err(e) = w.step(&mut broken, Vec2::X * 0.05, DT) {
            err = Some(e);
            break;
        }
    }
    assert!(err.expect("fails").to_string().contains("disk gone"));
}

#[test]
fn the_search_finds_the_stair_and_the_fall_and_its_path_walks() {
    let mut g = two_storeys();
    g.insert_box(Vec3::new(-3.0, 0.0, -3.0), Vec3::new(3.0, 2.6, -2.9));
    let start = standing(&mut g, 0.0, -1.0, 0.0);
    let r = Reach::explore(
        &mut g,
        start,
        Vec2::new(-2.0, -2.8),
        Vec2::new(2.0, 6.0),
        100_000,
    )
    .unwrap();
    let top = (0..r.places.len())
        .max_by(|&a, &b| {
            r.places[a]
                .walker
                .feet()
                .y
                .total_cmp(&r.places[b].walker.feet().y)
        })
        .unwrap();
    assert!(
        (r.places[top].walker.feet().y - 2.88).abs() < 0.03,
        "the upper floor is reached: {} of {} places",
        r.places[top].walker.feet(),
        r.places.len()
    );
    let zmin = r
        .places
        .iter()
        .map(|p| p.walker.feet())
        .filter(|f| f.y < 2.0)
        .fold(f32::MAX, |m, f| m.min(f.z));
    assert!(
        zmin > -2.9 + 0.19,
        "not through the wall (it is 2.6 m high): {zmin}"
    );
    let mut w = start;
    for by in r.path_to(top) {
        w.step(&mut g, by, DT).unwrap();
    }
    assert_eq!(w.feet(), r.places[top].walker.feet(), "the path walks");
    let f = r
        .falls
        .iter()
        .find(|f| r.places[f.from].walker.feet().y > 2.8)
        .expect("a fall off the upper floor");
    let drop = r.places[f.from].walker.feet().y - f.landing.feet().y;
    assert!(f.landing.grounded() && drop > 0.3, "{drop}");
    let deepest = r
        .falls
        .iter()
        .map(|f| r.places[f.from].walker.feet().y - f.landing.feet().y)
        .fold(0.0, f32::max);
    assert!(
        deepest > 2.0,
        "off the slab edge to the floor below: {deepest}"
    );
}

#[test]
fn a_closed_door_is_a_wall_and_an_open_one_is_passed() {
    let mut g = floor();
    g.insert_box(Vec3::new(2.0, 0.0, -10.0), Vec3::new(2.2, 2.7, -0.5));
    g.insert_box(Vec3::new(2.0, 0.0, 0.5), Vec3::new(2.2, 2.7, 10.0));
    g.insert_box(Vec3::new(2.0, 2.1, -0.5), Vec3::new(2.2, 2.7, 0.5));
    g.insert_box_in(
        Layer::Door,
        Vec3::new(2.08, 0.0, -0.45),
        Vec3::new(2.12, 2.05, 0.45),
    );
    let mut closed = standing(&mut g, 0.0, 0.0, 0.0);
    walk(&mut closed, &mut g, Vec2::X, 4.0);
    assert!(closed.feet().x < 2.0, "{}", closed.feet());
    let body = Body {
        doors_open: true,
        ..Body::default()
    };
    let mut open = Walker::from_eye(body, &mut g, Vec3::new(0.0, 1.6, 0.0)).unwrap();
    walk(&mut open, &mut g, Vec2::X, 4.0);
    assert!(open.feet().x > 3.0, "{}", open.feet());
}

#[test]
fn an_opening_carved_out_of_a_wall_is_walked_through() {
    let mut g = floor();
    g.insert_box(Vec3::new(2.0, 0.0, -10.0), Vec3::new(2.2, 2.7, 10.0));
    // The void of a 0.9 m × 2.1 m door opening, as its own grid's columns.
    let mut void = grid();
    void.insert_box(Vec3::new(1.95, 0.0, -0.45), Vec3::new(2.25, 2.1, 0.45));
    let cuts: Vec<(i64, i64, Span)> = void
        .solid_columns()
        .into_iter()
        .map(|(x, z, c)| {
            (
                x,
                z,
                Span {
                    lo: c[0].lo + 1,
                    hi: c[c.len() - 1].hi - 1,
                },
            )
        })
        .collect();
    let mut w = standing(&mut g, 0.0, 0.0, 0.0);
    walk(&mut w, &mut g, Vec2::X, 4.0);
    assert!(w.feet().x < 2.0, "the wall before: {}", w.feet());
    g.carve(&cuts);
    let mut w = standing(&mut g, 0.0, 0.0, 0.0);
    walk(&mut w, &mut g, Vec2::X, 4.0);
    assert!(w.feet().x > 3.0, "through the opening: {}", w.feet());
    // Beside the opening the wall stands, and above it the lintel.
    let mut w = standing(&mut g, 0.0, 2.0, 0.0);
    walk(&mut w, &mut g, Vec2::X, 4.0);
    assert!(w.feet().x < 2.0, "{}", w.feet());
    let lintel = g.column(20, 0).unwrap().solid.to_vec();
    assert!(
        lintel
            .iter()
            .any(|s| g.grid().height(s.hi) > 2.6 && g.grid().height(s.lo) > 2.0),
        "{lintel:?}"
    );
}
