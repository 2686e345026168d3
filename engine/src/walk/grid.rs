//! Solid space in memory: what the builder rasterises triangles into and
//! encodes as a walk section, and what tests build rooms in.

use std::collections::BTreeMap;

use glam::Vec3;

use super::{Grid, SolidMap, Span};
use crate::format::FormatError;
use crate::format::walk::{
    CHUNK_AREA, CHUNK_CELLS, Chunk, Column, LAYERS, MAX_SPANS, WalkIndex, locate,
};

/// What a span stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    Solid = 0,
    /// A door's leaf: passed with the doors open.
    Door = 1,
}

/// One chunk's spans as `(cell, span)` (door cells after the solid ones),
/// appended, and sorted and merged when they have doubled since the last
/// time.
#[derive(Clone, Debug, Default)]
struct Pending {
    spans: Vec<(u16, Span)>,
    merged: usize,
    /// Cell `c`'s merged spans, after [`Pending::columns`].
    columns: Option<Vec<Vec<Span>>>,
}

impl Pending {
    fn push(&mut self, cell: u16, s: Span) {
        self.columns = None;
        // The triangles of one element mostly add to the cells just added
        // to: a span that overlaps or touches the last one unsorted joins it.
        if self.spans.len() > self.merged
            && let Some((lc, l)) = self.spans.last_mut()
            && *lc == cell
            && u32::from(s.lo) <= u32::from(l.hi) + 1
            && u32::from(l.lo) <= u32::from(s.hi) + 1
        {
            (l.lo, l.hi) = (l.lo.min(s.lo), l.hi.max(s.hi));
            return;
        }
        self.spans.push((cell, s));
        if self.spans.len() >= 2 * self.merged + 64 {
            self.compact();
        }
    }

    /// Sorts, and merges the spans of a cell that overlap or touch (the
    /// union, whatever the order they came in). The spans merged last time
    /// are still sorted: only those added since are sorted, then the two
    /// runs are merged.
    fn compact(&mut self) {
        // The order of `(cell, lo, hi)`, compared as one integer.
        self.spans[self.merged..].sort_unstable_by_key(|&(c, s)| {
            (u64::from(c) << 32) | (u64::from(s.lo) << 16) | u64::from(s.hi)
        });
        let (a, b) = self.spans.split_at(self.merged);
        let mut out: Vec<(u16, Span)> = Vec::with_capacity(self.spans.len());
        let (mut i, mut j) = (0, 0);
        while i < a.len() || j < b.len() {
            let (c, s) = if j == b.len() || (i < a.len() && a[i] <= b[j]) {
                i += 1;
                a[i - 1]
            } else {
                j += 1;
                b[j - 1]
            };
            match out.last_mut() {
                Some((lc, l)) if *lc == c && u32::from(s.lo) <= u32::from(l.hi) + 1 => {
                    l.hi = l.hi.max(s.hi);
                }
                _ => out.push((c, s)),
            }
        }
        self.merged = out.len();
        self.spans = out;
    }

    /// Every cell's merged spans (both layers), cached for lookups.
    fn columns(&mut self) -> &[Vec<Span>] {
        if self.columns.is_none() {
            self.columns = Some(self.build_columns());
        }
        self.columns.as_deref().expect("made above")
    }

    /// Every cell's merged spans, not cached.
    fn build_columns(&mut self) -> Vec<Vec<Span>> {
        self.compact();
        let mut cols = vec![Vec::new(); LAYERS * CHUNK_AREA];
        for &(c, s) in &self.spans {
            cols[usize::from(c)].push(s);
        }
        for col in &mut cols {
            cap_spans(col);
        }
        cols
    }
}

/// `s` less `v` (none, one or two spans).
fn subtract(s: Span, v: Span) -> Vec<Span> {
    if v.hi < s.lo || v.lo > s.hi {
        return vec![s];
    }
    let mut out = Vec::new();
    if s.lo < v.lo {
        out.push(Span {
            lo: s.lo,
            hi: v.lo - 1,
        });
    }
    if s.hi > v.hi {
        out.push(Span {
            lo: v.hi + 1,
            hi: s.hi,
        });
    }
    out
}

/// Cells of a chunk's columns holding solid or doors.
fn occupied(cols: &[Vec<Span>]) -> usize {
    (0..CHUNK_AREA)
        .filter(|&k| !cols[k].is_empty() || !cols[k + CHUNK_AREA].is_empty())
        .count()
}

/// Keeps at most [`MAX_SPANS`] spans by filling the smallest gaps (solid
/// grows: nothing is walked through that was not).
fn cap_spans(col: &mut Vec<Span>) {
    while col.len() > MAX_SPANS {
        let k = (1..col.len())
            .min_by_key(|&k| (col[k].lo - col[k - 1].hi, k))
            .expect("more than one span");
        col[k - 1].hi = col[k].hi;
        col.remove(k);
    }
}

/// A chunk's `(x, z)` and its encoded payload.
pub type Payload = ((i32, i32), Vec<u8>);

/// Solid columns held in memory, by chunk of [`CHUNK_CELLS`]² cells.
#[derive(Clone, Debug)]
pub struct SpanGrid {
    grid: Grid,
    chunks: BTreeMap<(i32, i32), Pending>,
    /// Only chunk rows (z) in this range are kept (a band of a large scene
    /// rasterised a band at a time).
    rows: Option<(i32, i32)>,
}

impl SpanGrid {
    pub fn new(grid: Grid) -> Self {
        Self {
            grid,
            chunks: BTreeMap::new(),
            rows: None,
        }
    }

    /// A grid that keeps only chunk rows `z0..z1` (chunk units along z).
    pub fn band(grid: Grid, z0: i32, z1: i32) -> Self {
        Self {
            rows: Some((z0, z1)),
            ..Self::new(grid)
        }
    }

    /// The chunk row holding coordinate `z`.
    pub fn chunk_row(&self, z: f32) -> i32 {
        let r = self.grid.cell_of(z).div_euclid(CHUNK_CELLS as i64);
        r.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
    }

    /// Adds `s` to cell `(x, z)` of `layer` (cells beyond the `i32` chunk
    /// range are dropped).
    pub fn insert(&mut self, layer: Layer, x: i64, z: i64, s: Span) {
        let Some(((cx, cz), c)) = locate(x, z) else {
            return;
        };
        if self.rows.is_some_and(|(z0, z1)| cz < z0 || cz >= z1) {
            return;
        }
        let cell = c + layer as usize * CHUNK_AREA;
        self.chunks
            .entry((cx, cz))
            .or_default()
            .push(cell as u16, s);
    }

    /// Adds a solid box.
    pub fn insert_box(&mut self, min: Vec3, max: Vec3) {
        self.insert_box_in(Layer::Solid, min, max);
    }

    /// Adds a box to `layer`.
    pub fn insert_box_in(&mut self, layer: Layer, min: Vec3, max: Vec3) {
        let g = self.grid;
        let s = g.span(min.y, max.y);
        let last = |v: f32| (v / g.cell).ceil() as i64 - 1;
        for z in g.cell_of(min.z)..=last(max.z).max(g.cell_of(min.z)) {
            for x in g.cell_of(min.x)..=last(max.x).max(g.cell_of(min.x)) {
                self.insert(layer, x, z, s);
            }
        }
    }

    /// Adds triangle `t` to `layer`: every cell whose square it touches
    /// gets the heights it spans over that square (clipped exactly, rounded
    /// outwards).
    pub fn insert_triangle(&mut self, layer: Layer, t: [Vec3; 3]) {
        if !t.iter().all(|p| p.is_finite()) {
            return;
        }
        let g = self.grid;
        let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        let (x0, x1, z0, z1) = (
            g.cell_of(lo.x),
            g.cell_of(hi.x),
            g.cell_of(lo.z),
            g.cell_of(hi.z),
        );
        if x0 == x1 && z0 == z1 {
            self.insert(layer, x0, z0, g.span(lo.y, hi.y));
            return;
        }
        // Only the rows of the band kept.
        let (z0, z1) = match self.rows {
            Some((r0, r1)) => {
                let n = CHUNK_CELLS as i64;
                (z0.max(i64::from(r0) * n), z1.min(i64::from(r1) * n - 1))
            }
            None => (z0, z1),
        };
        let c = g.cell;
        let tri = Poly::of(&t);
        let rows = self.rows;
        // The chunk last added to: most of a triangle's cells share one.
        let mut current: Option<((i32, i32), &mut Pending)> = None;
        for z in z0..=z1 {
            let row = tri
                .clip(2, z as f32 * c, true)
                .clip(2, (z + 1) as f32 * c, false);
            if row.n == 0 {
                continue;
            }
            let (rx0, rx1) = row.points().iter().fold((i64::MAX, i64::MIN), |(a, b), p| {
                (a.min(g.cell_of(p.x)), b.max(g.cell_of(p.x)))
            });
            for x in rx0.max(x0)..=rx1.min(x1) {
                let cell = row
                    .clip(0, x as f32 * c, true)
                    .clip(0, (x + 1) as f32 * c, false);
                if let Some((a, b)) = cell.points().iter().fold(None, |r: Option<(f32, f32)>, p| {
                    Some(r.map_or((p.y, p.y), |(a, b)| (a.min(p.y), b.max(p.y))))
                }) {
                    let Some((key, cell)) = locate(x, z) else {
                        continue;
                    };
                    if rows.is_some_and(|(z0, z1)| key.1 < z0 || key.1 >= z1) {
                        continue;
                    }
                    if current.as_ref().map(|(k, _)| *k) != Some(key) {
                        current = Some((key, self.chunks.entry(key).or_default()));
                    }
                    if let Some((_, p)) = current.as_mut() {
                        p.push((cell + layer as usize * CHUNK_AREA) as u16, g.span(a, b));
                    }
                }
            }
        }
    }

    /// Adds every span of `other` (same grid): the union.
    pub fn absorb(&mut self, other: SpanGrid) {
        for (k, p) in other.chunks {
            let mine = self.chunks.entry(k).or_default();
            for (c, s) in p.spans {
                mine.push(c, s);
            }
        }
    }

    /// Each cell holding anything, with its solid layer's spans (any order).
    pub fn solid_columns(&mut self) -> Vec<(i64, i64, Vec<Span>)> {
        let n = CHUNK_CELLS as i64;
        let mut out = Vec::new();
        for (&(cx, cz), p) in &mut self.chunks {
            for (c, col) in p.build_columns().into_iter().take(CHUNK_AREA).enumerate() {
                if !col.is_empty() {
                    let (i, j) = ((c % CHUNK_CELLS) as i64, (c / CHUNK_CELLS) as i64);
                    out.push((i64::from(cx) * n + i, i64::from(cz) * n + j, col));
                }
            }
        }
        out
    }

    /// Removes `[s.lo, s.hi]` from the solid layer of each cell `(x, z)`
    /// listed (an opening's void cut out of the wall around it).
    pub fn carve(&mut self, cuts: &[(i64, i64, Span)]) {
        let mut by_chunk: BTreeMap<(i32, i32), Vec<(u16, Span)>> = BTreeMap::new();
        for &(x, z, s) in cuts {
            if let Some((k, c)) = locate(x, z) {
                by_chunk.entry(k).or_default().push((c as u16, s));
            }
        }
        for (k, mut cut) in by_chunk {
            let Some(p) = self.chunks.get_mut(&k) else {
                continue;
            };
            cut.sort_unstable();
            p.compact();
            p.columns = None;
            let mut out = Vec::with_capacity(p.spans.len());
            for &(c, s) in &p.spans {
                let mut left = vec![s];
                let at = cut.partition_point(|x| x.0 < c);
                for &(_, v) in cut[at..].iter().take_while(|x| x.0 == c) {
                    left = left.into_iter().flat_map(|s| subtract(s, v)).collect();
                }
                out.extend(left.into_iter().map(|s| (c, s)));
            }
            p.spans = out;
            p.merged = p.spans.len();
        }
    }

    /// Cells holding solid or doors.
    pub fn cells(&mut self) -> usize {
        self.chunks
            .values_mut()
            .map(|p| occupied(&p.build_columns()))
            .sum()
    }

    /// Bytes held (approximately).
    pub fn heap_bytes(&self) -> usize {
        self.chunks
            .values()
            .map(|p| {
                let cols = p.columns.as_ref().map_or(0, |c| {
                    c.len() * 24 + c.iter().map(|v| v.capacity() * 4).sum::<usize>()
                });
                p.spans.capacity() * 6 + cols + 96
            })
            .sum()
    }

    /// The walk section of these columns.
    pub fn encode(&mut self) -> Vec<u8> {
        let g = self.grid;
        let (chunks, _) = self.clone().into_chunks();
        WalkIndex::encode(g.cell, g.quantum, g.y_base, &chunks)
    }

    /// Each chunk's payload, by `(x, z)` (for [`WalkIndex::encode`]), and
    /// the cells holding anything; each chunk's spans are dropped once it is
    /// encoded.
    pub fn into_chunks(self) -> (Vec<Payload>, usize) {
        let mut cells = 0;
        let chunks = self
            .chunks
            .into_iter()
            .map(|(k, mut p)| {
                let cols = p.build_columns();
                drop(p);
                cells += occupied(&cols);
                (k, Chunk::encode(&cols))
            })
            .collect();
        (chunks, cells)
    }
}

/// A convex polygon of at most 8 corners, on the stack: a triangle
/// clipped by the four sides of a cell has at most 7.
#[derive(Clone, Copy, Debug)]
struct Poly {
    p: [Vec3; 8],
    n: usize,
}

impl Poly {
    fn of(t: &[Vec3; 3]) -> Self {
        let mut p = [Vec3::ZERO; 8];
        p[..3].copy_from_slice(t);
        Self { p, n: 3 }
    }

    fn points(&self) -> &[Vec3] {
        &self.p[..self.n]
    }

    /// Sutherland–Hodgman: the part with coordinate `axis` (0: x, 2: z)
    /// at least (`keep_above`) or at most `at`.
    fn clip(&self, axis: usize, at: f32, keep_above: bool) -> Self {
        let inside = |p: &Vec3| {
            if keep_above {
                p[axis] >= at
            } else {
                p[axis] <= at
            }
        };
        let mut out = Self {
            p: [Vec3::ZERO; 8],
            n: 0,
        };
        let n = self.n;
        for k in 0..n {
            let (a, b) = (self.p[k], self.p[(k + 1) % n]);
            let (ia, ib) = (inside(&a), inside(&b));
            if ia && out.n < 8 {
                out.p[out.n] = a;
                out.n += 1;
            }
            if ia != ib && out.n < 8 {
                let t = (at - a[axis]) / (b[axis] - a[axis]);
                let mut p = a + (b - a) * t;
                p[axis] = at;
                out.p[out.n] = p;
                out.n += 1;
            }
        }
        out
    }
}

impl SolidMap for SpanGrid {
    fn grid(&self) -> Grid {
        self.grid
    }

    fn column(&mut self, x: i64, z: i64) -> Result<Column<'_>, FormatError> {
        let Some((k, c)) = locate(x, z) else {
            return Ok(Column::default());
        };
        Ok(match self.chunks.get_mut(&k) {
            Some(p) => {
                let cols = p.columns();
                Column {
                    solid: &cols[c],
                    doors: &cols[c + CHUNK_AREA],
                }
            }
            None => Column::default(),
        })
    }
}
