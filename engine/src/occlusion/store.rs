//! P_R's occluder triangles: each drawn rep's largest triangles, kept in
//! least-recently-used order under a byte capacity that comes out of the
//! footprint.

use std::collections::BinaryHeap;
use std::sync::Arc;

use crate::evict::lru::LruMap;
use glam::Vec3;

use crate::format::{PackedVertex, REP_MAGIC, RepHeader};
use crate::skeleton::RepId;

/// Most occluder triangles kept per rep.
pub const MAX_TRIS: usize = 32;
/// A triangle counts as an occluder when its area is at least this share
/// of the square of its rep's box diagonal.
const MIN_AREA_SHARE: f32 = 1e-3;
/// Bytes charged per entry on top of its triangles.
const ENTRY_BYTES: u64 = 64;

type Tris = Arc<[[Vec3; 3]]>;

/// The largest opaque triangles of a raw rep payload, largest first (none
/// from a payload that is not a raw mesh rep; indices out of range and
/// triangles with a translucent corner are skipped).
pub fn occluder_triangles(payload: &[u8]) -> Vec<[Vec3; 3]> {
    let hs = size_of::<RepHeader>();
    if payload.len() < hs {
        return Vec::new();
    }
    let h: RepHeader = bytemuck::pod_read_unaligned(&payload[..hs]);
    let (vc, ic) = (h.vertex_count as usize, h.index_count as usize);
    let vs = size_of::<PackedVertex>();
    let isz = if vc <= 1 << 16 { 2 } else { 4 };
    if h.magic != REP_MAGIC || payload.len() < hs + vc * vs + ic * isz {
        return Vec::new();
    }
    // Every vertex decoded once (a triangle would decode three), with
    // whether it is opaque.
    let pos: Vec<(Vec3, bool)> = payload[hs..hs + vc * vs]
        .chunks_exact(vs)
        .map(|b| {
            let pv: PackedVertex = bytemuck::pod_read_unaligned(b);
            let p = Vec3::from_array(std::array::from_fn(|a| {
                h.quant_min[a] + f32::from(pv.position[a]) * h.quant_scale[a]
            }));
            (p, pv.color[3] == u8::MAX)
        })
        .collect();
    let ib = &payload[hs + vc * vs..];
    let index = |i: usize| -> usize {
        if isz == 2 {
            usize::from(u16::from_le_bytes([ib[2 * i], ib[2 * i + 1]]))
        } else {
            u32::from_le_bytes([ib[4 * i], ib[4 * i + 1], ib[4 * i + 2], ib[4 * i + 3]]) as usize
        }
    };
    let diag = Vec3::from_array(h.quant_scale).length() * 65535.0;
    let min_area = MIN_AREA_SHARE * diag * diag;
    // The best MAX_TRIS by (larger area, earlier in the mesh), a heap whose
    // top is the worst kept: the same triangles, in the same order, as a
    // stable sort of all of them by area.
    let mut best: BinaryHeap<Ranked> = BinaryHeap::with_capacity(MAX_TRIS + 1);
    for t in 0..ic / 3 {
        let v = [index(3 * t), index(3 * t + 1), index(3 * t + 2)];
        if v.iter().any(|&i| i >= vc) {
            continue;
        }
        // A translucent triangle (glass) hides nothing.
        if v.iter().any(|&i| !pos[i].1) {
            continue;
        }
        let p = v.map(|i| pos[i].0);
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        if !(area.is_finite() && area >= min_area) {
            continue;
        }
        let r = Ranked { area, at: t, p };
        if best.len() < MAX_TRIS {
            best.push(r);
        } else if best.peek().is_some_and(|w| r < *w) {
            best.pop();
            best.push(r);
        }
    }
    best.into_sorted_vec().into_iter().map(|r| r.p).collect()
}

/// A candidate occluder, ordered best first: larger area, then earlier in
/// the mesh.
struct Ranked {
    area: f32,
    at: usize,
    p: [Vec3; 3],
}

impl Ord for Ranked {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.area.total_cmp(&self.area).then(self.at.cmp(&o.at))
    }
}

impl PartialOrd for Ranked {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

impl PartialEq for Ranked {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o).is_eq()
    }
}

impl Eq for Ranked {}

/// The occluder triangles of recently drawn reps.
#[derive(Debug)]
pub struct OccluderStore {
    /// Each rep's triangles and the frame it was last used in.
    entries: LruMap<RepId, (Tris, u32)>,
    bytes: u64,
    capacity: u64,
}

impl OccluderStore {
    /// A store of at most `capacity` bytes.
    pub fn new(capacity: u64) -> Self {
        Self {
            entries: LruMap::default(),
            bytes: 0,
            capacity,
        }
    }

    fn cost(t: &Tris) -> u64 {
        ENTRY_BYTES + (t.len() * size_of::<[Vec3; 3]>()) as u64
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Rep `r`'s triangles, if held (marked as used in `frame`).
    pub fn get(&mut self, r: RepId, frame: u32) -> Option<Tris> {
        self.entries.get_mut(r).map(|e| {
            e.1 = frame;
            e.0.clone()
        })
    }

    /// Whether rep `r`'s triangles are held (not marked as used).
    pub fn contains(&self, r: RepId) -> bool {
        self.entries.contains(r)
    }

    /// Keeps rep `r`'s occluders, taken from its raw payload, unless held
    /// (used in `frame`); the least recently used entries make room.
    pub fn insert_from(
        &mut self,
        r: RepId,
        payload: &[u8],
        placement: Option<&crate::records::RepPlacement>,
        frame: u32,
    ) {
        if self.get(r, frame).is_some() {
            return;
        }
        let mut tris = occluder_triangles(payload);
        if let Some(pl) = placement {
            for t in &mut tris {
                *t = t.map(|p| Vec3::from_array(pl.point(p.to_array())));
            }
        }
        let tris: Tris = tris.into();
        let cost = Self::cost(&tris);
        if cost > self.capacity {
            return;
        }
        while self.bytes + cost > self.capacity {
            match self.entries.pop_victim() {
                Some((_, (t, _))) => self.bytes -= Self::cost(&t),
                None => break,
            }
        }
        self.bytes += cost;
        self.entries.put(r, (tris, frame));
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The byte count matches the entries and stays within the capacity.
    pub fn validate(&self) -> Result<(), String> {
        self.entries.validate()?;
        let sum: u64 = self.entries.values().map(|(_, (t, _))| Self::cost(t)).sum();
        if sum != self.bytes {
            return Err(format!(
                "store counts {} bytes, entries hold {sum}",
                self.bytes
            ));
        }
        if self.bytes > self.capacity {
            return Err(format!(
                "store holds {} bytes over {}",
                self.bytes, self.capacity
            ));
        }
        Ok(())
    }
}

const _: () = assert!(size_of::<[Vec3; 3]>() == 36);
