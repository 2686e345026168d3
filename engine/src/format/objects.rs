//! The object section: what a person asks about an element they click.
//!
//! ```text
//! ObjectsHeader (32 B)
//! [u64; object_count + 1]        offsets of each object's JSON text
//! [LeafRuns; leaf_count]         merged leaves, by node id
//! [Run; run_count]               (object, end triangle) runs of those leaves' finest reps
//! text (UTF-8)                   one JSON object per source object
//! ```
//!
//! A leaf made of one object (or a chunk of one) names it in its
//! [`NodeRecord::object`](super::NodeRecord::object); the finest static rep of
//! a merged leaf holds its objects' triangles in contiguous runs, listed here.
//! The section sits after the skeleton and is read only on demand, never by
//! the rendering path.

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

use super::{FormatError, NONE};
use crate::skeleton::Skeleton;

/// Section magic.
pub const OBJECTS_MAGIC: [u8; 8] = *b"OBJECTS\0";

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ObjectsHeader {
    pub magic: [u8; 8],
    pub object_count: u32,
    pub leaf_count: u32,
    pub run_count: u32,
    pub reserved: u32,
    pub text_len: u64,
}
const _: () = assert!(size_of::<ObjectsHeader>() == 32);

/// The runs of one merged leaf.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct LeafRuns {
    pub node: u32,
    pub first_run: u32,
    pub run_count: u32,
    pub reserved: u32,
}
const _: () = assert!(size_of::<LeafRuns>() == 16);

/// Triangles `[previous end, tri_end)` of a leaf's finest rep belong to `object`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct Run {
    pub object: u32,
    pub tri_end: u32,
}
const _: () = assert!(size_of::<Run>() == 8);

/// A decoded, validated object section.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjectTable {
    offsets: Vec<u64>,
    leaves: Vec<LeafRuns>,
    runs: Vec<Run>,
    text: Vec<u8>,
}

impl ObjectTable {
    /// Encodes the section: `infos[k]` is object `k`'s JSON text, `leaves`
    /// each merged leaf's node and runs (any order; sorted here).
    pub fn encode(infos: &[String], leaves: &[(u32, Vec<Run>)]) -> Vec<u8> {
        let mut sorted: Vec<&(u32, Vec<Run>)> = leaves.iter().collect();
        sorted.sort_by_key(|(n, _)| *n);
        let mut offsets = Vec::with_capacity(infos.len() + 1);
        let mut text = Vec::new();
        for s in infos {
            offsets.push(text.len() as u64);
            text.extend_from_slice(s.as_bytes());
        }
        offsets.push(text.len() as u64);
        let mut recs = Vec::new();
        let mut runs = Vec::new();
        for (node, r) in sorted {
            recs.push(LeafRuns {
                node: *node,
                first_run: runs.len() as u32,
                run_count: r.len() as u32,
                reserved: 0,
            });
            runs.extend_from_slice(r);
        }
        let header = ObjectsHeader {
            magic: OBJECTS_MAGIC,
            object_count: infos.len() as u32,
            leaf_count: recs.len() as u32,
            run_count: runs.len() as u32,
            reserved: 0,
            text_len: text.len() as u64,
        };
        let mut out = bytemuck::bytes_of(&header).to_vec();
        out.extend_from_slice(bytemuck::cast_slice(&offsets));
        out.extend_from_slice(bytemuck::cast_slice(&recs));
        out.extend_from_slice(bytemuck::cast_slice(&runs));
        out.extend_from_slice(&text);
        out
    }

    /// Decodes and validates a section against the scene's skeleton. An
    /// empty section (a version-1 file, or none written) is an empty table.
    pub fn decode(bytes: &[u8], skeleton: &Skeleton) -> Result<Self, FormatError> {
        if bytes.is_empty() {
            return Ok(Self::default());
        }
        let bad = |s: String| FormatError::BadHeader(format!("object section: {s}"));
        let hsize = size_of::<ObjectsHeader>();
        let h: ObjectsHeader = bytemuck::pod_read_unaligned(
            bytes
                .get(..hsize)
                .ok_or_else(|| bad("shorter than its header".into()))?,
        );
        if h.magic != OBJECTS_MAGIC {
            return Err(bad("bad magic".into()));
        }
        let n_off = u64::from(h.object_count) + 1;
        let need = [
            n_off * 8,
            u64::from(h.leaf_count) * 16,
            u64::from(h.run_count) * 8,
            h.text_len,
        ]
        .iter()
        .try_fold(hsize as u64, |a, &b| a.checked_add(b));
        if need != Some(bytes.len() as u64) {
            return Err(bad("section length disagrees with its counts".into()));
        }
        let mut at = hsize;
        let mut take = |len: usize| {
            let s = &bytes[at..at + len];
            at += len;
            s
        };
        let offsets: Vec<u64> = bytemuck::pod_collect_to_vec(take(n_off as usize * 8));
        let leaves: Vec<LeafRuns> = bytemuck::pod_collect_to_vec(take(h.leaf_count as usize * 16));
        let runs: Vec<Run> = bytemuck::pod_collect_to_vec(take(h.run_count as usize * 8));
        let text = take(h.text_len as usize).to_vec();
        if offsets.first() != Some(&0)
            || offsets.last() != Some(&h.text_len)
            || offsets.windows(2).any(|w| w[0] > w[1])
        {
            return Err(bad("object offsets are not increasing".into()));
        }
        let nodes = &skeleton.nodes;
        for (i, l) in leaves.iter().enumerate() {
            let ok_node = nodes.get(l.node as usize).is_some_and(|n| n.is_leaf());
            let ordered = i == 0 || leaves[i - 1].node < l.node;
            let in_range = u64::from(l.first_run) + u64::from(l.run_count) <= runs.len() as u64;
            if !(ok_node && ordered && in_range) {
                return Err(bad(format!("leaf entry {i} (node {})", l.node)));
            }
            let rs = &runs[l.first_run as usize..(l.first_run + l.run_count) as usize];
            if rs.iter().any(|r| r.object >= h.object_count)
                || rs.windows(2).any(|w| w[0].tri_end >= w[1].tri_end)
            {
                return Err(bad(format!("runs of node {}", l.node)));
            }
        }
        Ok(Self {
            offsets,
            leaves,
            runs,
            text,
        })
    }

    /// Number of objects described.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Whether no object is described (a version-1 scene).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Object `k`'s JSON text.
    pub fn info(&self, k: u32) -> Option<&str> {
        let k = k as usize;
        let (a, b) = (*self.offsets.get(k)?, *self.offsets.get(k + 1)?);
        std::str::from_utf8(&self.text[a as usize..b as usize]).ok()
    }

    /// The runs of merged leaf `node` (empty for any other node).
    pub fn runs_of(&self, node: u32) -> &[Run] {
        match self.leaves.binary_search_by_key(&node, |l| l.node) {
            Ok(i) => {
                let l = self.leaves[i];
                &self.runs[l.first_run as usize..(l.first_run + l.run_count) as usize]
            }
            Err(_) => &[],
        }
    }

    /// The object that triangle `tri` of leaf `node`'s finest static rep
    /// belongs to.
    pub fn object_at(&self, skeleton: &Skeleton, node: u32, tri: u32) -> Option<u32> {
        let n = skeleton.nodes.get(node as usize)?;
        if n.object != NONE {
            return Some(n.object);
        }
        let l = self
            .leaves
            .binary_search_by_key(&node, |l| l.node)
            .ok()
            .map(|i| self.leaves[i])?;
        let rs = &self.runs[l.first_run as usize..(l.first_run + l.run_count) as usize];
        rs.iter().find(|r| tri < r.tri_end).map(|r| r.object)
    }
}
