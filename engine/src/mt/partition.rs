//! Holst & Schumann's greedy partitioning (§4.2): nodes used together in
//! one cut are close in the hierarchy and joined by many arcs, so
//! partitions are grown by merging the connected pair with the most arcs
//! between them while the merged partition stays within `theta` nodes,
//! preferring, among pairs joined by as many arcs, the one whose merged
//! layer span is smallest (so a partition holds few levels of detail).

use std::collections::{BTreeMap, BinaryHeap};

use super::{DRAIN, Mt};

/// Largest `theta` accepted (nodes per partition).
pub const MAX_THETA: u32 = 4096;

/// Nodes grouped into partitions.
#[derive(Clone, Debug, PartialEq)]
pub struct Partitioning {
    /// Partition of each node; partitions are numbered by their first node.
    pub of_node: Vec<u32>,
    pub count: u32,
    pub theta: u32,
}

/// Why a partitioning is not acceptable.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PartitionError {
    #[error("θ = {0} is outside 1..={MAX_THETA} nodes per partition")]
    Theta(u32),
    #[error("partition {0} holds {1} nodes, more than θ = {2}")]
    TooLarge(u32, u32, u32),
    #[error("{0}")]
    Shape(String),
}

#[derive(PartialEq, Eq, PartialOrd, Ord)]
struct Entry {
    arcs: u32,
    /// Negated layer span: a smaller span pops first.
    neg_span: i64,
    /// Reversed ids for a deterministic order (smaller ids first).
    a: std::cmp::Reverse<u32>,
    b: std::cmp::Reverse<u32>,
}

struct Part {
    size: u32,
    lo: u32,
    hi: u32,
    /// Arcs to each connected partition.
    links: BTreeMap<u32, u32>,
}

/// Partitions `mt`'s nodes greedily with at most `theta` nodes each.
pub fn partition(mt: &Mt, theta: u32) -> Result<Partitioning, PartitionError> {
    if !(1..=MAX_THETA).contains(&theta) {
        return Err(PartitionError::Theta(theta));
    }
    let n = mt.nodes.len();
    let mut parts: Vec<Option<Part>> = mt
        .nodes
        .iter()
        .map(|nd| {
            Some(Part {
                size: 1,
                lo: nd.layer,
                hi: nd.layer,
                links: BTreeMap::new(),
            })
        })
        .collect();
    for a in mt.arcs.iter().filter(|a| a.child != DRAIN) {
        let (f, c) = (a.father, a.child);
        for (x, y) in [(f, c), (c, f)] {
            *parts[x as usize]
                .as_mut()
                .expect("fresh")
                .links
                .entry(y)
                .or_default() += 1;
        }
    }
    let entry = |parts: &[Option<Part>], a: u32, b: u32, arcs: u32| -> Option<Entry> {
        let (pa, pb) = (parts[a as usize].as_ref()?, parts[b as usize].as_ref()?);
        (pa.size + pb.size <= theta).then(|| Entry {
            arcs,
            neg_span: -(i64::from(pa.hi.max(pb.hi)) - i64::from(pa.lo.min(pb.lo))),
            a: std::cmp::Reverse(a.min(b)),
            b: std::cmp::Reverse(a.max(b)),
        })
    };
    let mut heap = BinaryHeap::new();
    for a in 0..n as u32 {
        let links: Vec<(u32, u32)> = parts[a as usize]
            .as_ref()
            .expect("fresh")
            .links
            .iter()
            .map(|(&b, &c)| (b, c))
            .collect();
        for (b, c) in links {
            if a < b {
                heap.extend(entry(&parts, a, b, c));
            }
        }
    }
    // Union-find parent: merged partitions point at the survivor.
    let mut into: Vec<u32> = (0..n as u32).collect();
    while let Some(e) = heap.pop() {
        let (a, b) = (e.a.0, e.b.0);
        // Stale: a side was merged away, or its sizes, span or arcs changed.
        let Some(fresh) = entry(&parts, a, b, e.arcs) else {
            continue;
        };
        let linked = parts[a as usize].as_ref().and_then(|p| p.links.get(&b));
        if fresh != e || linked != Some(&e.arcs) {
            continue;
        }
        let pb = parts[b as usize].take().expect("live");
        into[b as usize] = a;
        let mut pa = parts[a as usize].take().expect("live");
        pa.size += pb.size;
        pa.lo = pa.lo.min(pb.lo);
        pa.hi = pa.hi.max(pb.hi);
        pa.links.remove(&b);
        for (&k, &c) in &pb.links {
            if k == a {
                continue;
            }
            *pa.links.entry(k).or_default() += c;
            let pk = parts[k as usize]
                .as_mut()
                .expect("linked partitions are live");
            let moved = pk.links.remove(&b).unwrap_or(0);
            *pk.links.entry(a).or_default() += moved;
        }
        let links: Vec<(u32, u32)> = pa.links.iter().map(|(&k, &c)| (k, c)).collect();
        parts[a as usize] = Some(pa);
        for (k, c) in links {
            heap.extend(entry(&parts, a, k, c));
        }
    }
    let root = |mut x: u32| {
        while into[x as usize] != x {
            x = into[x as usize];
        }
        x
    };
    // Number partitions by their first node.
    let mut number: BTreeMap<u32, u32> = BTreeMap::new();
    let mut of_node = vec![0u32; n];
    for (k, slot) in of_node.iter_mut().enumerate() {
        let r = root(k as u32);
        let next = number.len() as u32;
        *slot = *number.entry(r).or_insert(next);
    }
    let p = Partitioning {
        of_node,
        count: number.len() as u32,
        theta,
    };
    p.validate(mt)?;
    Ok(p)
}

impl Partitioning {
    /// Every node is in one partition, partitions are numbered by first
    /// node, none is empty and none holds more than θ nodes.
    pub fn validate(&self, mt: &Mt) -> Result<(), PartitionError> {
        if !(1..=MAX_THETA).contains(&self.theta) {
            return Err(PartitionError::Theta(self.theta));
        }
        if self.of_node.len() != mt.nodes.len() {
            return Err(PartitionError::Shape(format!(
                "{} nodes but {} partition entries",
                mt.nodes.len(),
                self.of_node.len()
            )));
        }
        let mut size = vec![0u32; self.count as usize];
        let mut next = 0u32;
        for &p in &self.of_node {
            if p > next || p >= self.count {
                return Err(PartitionError::Shape(format!(
                    "partition {p} out of order or range"
                )));
            }
            if p == next {
                next += 1;
            }
            size[p as usize] += 1;
        }
        if next != self.count {
            return Err(PartitionError::Shape("an empty partition".into()));
        }
        if let Some((p, &s)) = size.iter().enumerate().find(|(_, s)| **s > self.theta) {
            return Err(PartitionError::TooLarge(p as u32, s, self.theta));
        }
        Ok(())
    }

    /// The nodes of each partition, ascending.
    pub fn members(&self) -> Vec<Vec<u32>> {
        let mut m = vec![Vec::new(); self.count as usize];
        for (n, &p) in self.of_node.iter().enumerate() {
            m[p as usize].push(n as u32);
        }
        m
    }
}
