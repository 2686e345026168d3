//! Meta-node trees (El-Sana & Chiang §3.2): every `L` levels of a binary
//! view-dependence tree (up to `2^L - 1` nodes, breadth-first), top-down
//! from each root, form one meta-node sized to a disk block. A meta-node holds its nodes, the *local triangle list*
//! (the triangles its nodes' splits add back, each stored once) and the
//! coordinates of only those leaves its nodes need: a node uses its left
//! child's position, so inside a meta-node only the bottom-boundary nodes'
//! (and real leaves') positions are stored.
//!
//! Serialised as a DATA part (the meta-node payloads, each with a CRC-32)
//! and an MNT part (one 32-byte record per meta-node: payload range, CRC,
//! parent, contiguous children — meta-nodes are numbered breadth-first).

use bytemuck::{Pod, Zeroable};

use super::{NONE, VdNode, VdTree};

/// One meta-node.
#[derive(Clone, Debug, PartialEq)]
pub struct MetaNode {
    /// View-dependence-tree nodes, top-down.
    pub nodes: Vec<u32>,
    pub parent: u32,
    /// Child meta-nodes (contiguous ids).
    pub children: Vec<u32>,
    /// Local triangle list: the triangles added by splitting these nodes.
    pub triangles: Vec<u32>,
    /// Leaves whose coordinates are stored here.
    pub leaves: Vec<u32>,
}

/// The meta-node forest of a [`VdTree`].
#[derive(Clone, Debug, PartialEq)]
pub struct MetaTree {
    pub levels: u32,
    pub metas: Vec<MetaNode>,
    /// Meta-node of every tree node.
    pub node_meta: Vec<u32>,
    /// Meta-node of every node's children when they are not in its own
    /// (`NONE` otherwise, and for leaves).
    pub child_meta: Vec<u32>,
    /// Root meta-nodes (those of the tree's roots).
    pub roots: Vec<u32>,
}

/// Bytes a node takes in a meta-node payload.
pub const NODE_BYTES: usize = std::mem::size_of::<VdNodeRecord>();

/// `L` such that an `L`-level meta-node (up to 2^L - 1 nodes, each with
/// about two adjacent triangles and, for half of them, a position) fits in
/// `block_bytes`.
pub fn levels_for_block(block_bytes: usize) -> u32 {
    let per_node = NODE_BYTES + 2 * 16 + 8;
    let mut l = 1;
    while l < 20 && ((1usize << (l + 1)) - 1) * per_node + 16 <= block_bytes {
        l += 1;
    }
    l
}

/// Blocks `tree` into meta-nodes of `levels` levels (at least 2: a pair of
/// siblings must fit).
///
/// A meta-node holds up to `2^L - 1` nodes: for a complete binary tree
/// exactly `L` levels. Collapse trees are far from complete (long chains
/// with small side subtrees), so
/// - the nodes are taken breadth-first from the meta-node's tops until the
///   capacity is reached, siblings always together (the children of a node
///   are both inside, or both below in one child meta-node);
/// - the sibling pairs left below are packed, in order, into child
///   meta-nodes: consecutive pairs share one while their whole subtrees fit
///   in it, so small side subtrees do not each cost a disk read. Roots are
///   packed the same way into the root meta-nodes.
pub fn block(tree: &VdTree, levels: u32) -> MetaTree {
    let levels = levels.clamp(2, 20);
    let cap = (1usize << levels) - 1;
    let n = tree.leaf_count();
    // Nodes in the subtree of v (a full binary tree over its leaves).
    let size = |v: u32| {
        let nd = &tree.nodes[v as usize];
        2 * (nd.leaf_end - nd.leaf) as usize - 1
    };
    let pack = |units: Vec<Vec<u32>>| -> Vec<Vec<Vec<u32>>> {
        let mut groups: Vec<Vec<Vec<u32>>> = Vec::new();
        let mut total = 0;
        for u in units {
            let s: usize = u.iter().map(|&v| size(v)).sum();
            match groups.last_mut() {
                Some(g) if total + s <= cap => g.push(u),
                _ => {
                    groups.push(vec![u]);
                    total = 0;
                }
            }
            total += s;
        }
        groups
    };
    let mut node_meta = vec![NONE; tree.nodes.len()];
    let mut child_meta = vec![NONE; tree.nodes.len()];
    let mut metas: Vec<MetaNode> = Vec::new();
    // Breadth-first over meta-nodes: (tops, parent meta).
    let mut queue: std::collections::VecDeque<(Vec<u32>, u32)> =
        pack(tree.roots.iter().map(|&r| vec![r]).collect())
            .into_iter()
            .map(|g| (g.concat(), NONE))
            .collect();
    let mut roots = Vec::new();
    while let Some((tops, parent)) = queue.pop_front() {
        let id = metas.len() as u32;
        if parent == NONE {
            roots.push(id);
        } else {
            metas[parent as usize].children.push(id);
        }
        let mut nodes = Vec::new();
        let mut below: Vec<(u32, Vec<u32>)> = Vec::new();
        // Nodes taken or promised (queued inside).
        let mut taken = tops.len();
        let mut inside = std::collections::VecDeque::from(tops);
        while let Some(v) = inside.pop_front() {
            nodes.push(v);
            node_meta[v as usize] = id;
            let nd: &VdNode = &tree.nodes[v as usize];
            if nd.left != NONE {
                if taken + 2 <= cap {
                    inside.extend([nd.left, nd.right]);
                    taken += 2;
                } else {
                    below.push((v, vec![nd.left, nd.right]));
                }
            }
        }
        // Ids the child meta-nodes will get: after everything queued.
        let first = id + 1 + queue.len() as u32;
        let groups = pack(below.iter().map(|b| b.1.clone()).collect());
        let mut owners = below.iter().map(|b| b.0);
        for (next, g) in (first..).zip(groups) {
            for v in owners.by_ref().take(g.len()) {
                child_meta[v as usize] = next;
            }
            queue.push_back((g.concat(), id));
        }
        let triangles = nodes
            .iter()
            .filter(|&&v| v as usize >= n)
            .flat_map(|&v| tree.adjacent[v as usize - n].iter().copied())
            .collect();
        // A node's position is stored here unless its left child is here too.
        let mut leaves: Vec<u32> = nodes
            .iter()
            .filter(|&&v| {
                let l = tree.nodes[v as usize].left;
                l == NONE || node_meta[l as usize] != id
            })
            .map(|&v| tree.nodes[v as usize].leaf)
            .collect();
        leaves.sort_unstable();
        leaves.dedup();
        metas.push(MetaNode {
            nodes,
            parent,
            children: Vec::new(),
            triangles,
            leaves,
        });
    }
    MetaTree {
        levels,
        metas,
        node_meta,
        child_meta,
        roots,
    }
}

impl MetaTree {
    /// Checks the blocking against `tree`: every node in exactly one
    /// meta-node, at most `2^L - 1` per meta-node, siblings together or both
    /// tops of child meta-nodes, parent links of nodes
    /// within or to the parent meta-node, children contiguous and
    /// breadth-first, every triangle in exactly one local list (or
    /// permanent), every node's position stored in its own meta-node.
    pub fn validate(&self, tree: &VdTree) -> Result<(), String> {
        let mut count = vec![0u32; tree.nodes.len()];
        let cap = (1usize << self.levels.min(31)) - 1;
        let mut tri_seen = vec![0u8; tree.triangles.len()];
        for (i, m) in self.metas.iter().enumerate() {
            let i = i as u32;
            if m.nodes.is_empty() || m.nodes.len() > cap {
                return Err(format!("meta-node {i}: {} nodes", m.nodes.len()));
            }
            for &v in &m.nodes {
                count[v as usize] += 1;
                if m.leaves
                    .binary_search(&tree.nodes[v as usize].leaf)
                    .is_err()
                {
                    return Err(format!("node {v}: its position is not in meta-node {i}"));
                }
                if self.node_meta[v as usize] != i {
                    return Err(format!("node {v}: meta index disagrees"));
                }
                let nd = &tree.nodes[v as usize];
                if nd.left != NONE {
                    let (a, b) = (
                        self.node_meta[nd.left as usize],
                        self.node_meta[nd.right as usize],
                    );
                    let want = if a == i { NONE } else { a };
                    if a != b || self.child_meta[v as usize] != want {
                        return Err(format!("node {v}: children split or misfiled"));
                    }
                }
                let p = nd.parent;
                let pm = if p == NONE {
                    NONE
                } else {
                    self.node_meta[p as usize]
                };
                if pm != i && pm != m.parent {
                    return Err(format!("node {v}: parent in an unrelated meta-node"));
                }
            }
            if let (Some(&a), Some(&b)) = (m.children.first(), m.children.last())
                && (b - a + 1 != m.children.len() as u32 || a <= i)
            {
                return Err(format!("meta-node {i}: children not contiguous after it"));
            }
            for &c in &m.children {
                if self.metas.get(c as usize).map(|x| x.parent) != Some(i) {
                    return Err(format!("meta-node {c}: parent link"));
                }
            }
            for &t in &m.triangles {
                tri_seen[t as usize] += 1;
            }
        }
        if let Some(v) = count.iter().position(|&c| c != 1) {
            return Err(format!("node {v} is in {} meta-nodes", count[v]));
        }
        for &t in &tree.permanent {
            tri_seen[t as usize] += 1;
        }
        if let Some(t) = tri_seen.iter().position(|&c| c != 1) {
            return Err(format!("triangle {t} listed {} times", tri_seen[t]));
        }
        Ok(())
    }
}

/// A node as stored in a meta-node payload: its id, the node itself, how
/// many of the meta-node's local triangles are its adjacent ones (the
/// local list is the nodes' lists in node order), and the meta-node of its
/// children when they are not here.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct VdNodeRecord {
    pub id: u32,
    pub node: VdNode,
    pub adjacent: u32,
    pub child_meta: u32,
}
const _: () = assert!(std::mem::size_of::<VdNodeRecord>() == 48);

/// An MNT record: where a meta-node's payload is and its tree links.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MntRecord {
    pub offset: u64,
    pub len: u32,
    pub checksum: u32,
    pub parent: u32,
    pub first_child: u32,
    pub child_count: u32,
    pub node_count: u32,
}
const _: () = assert!(std::mem::size_of::<MntRecord>() == 32);

/// Payload magic.
pub const META_MAGIC: u32 = u32::from_le_bytes(*b"MND1");

/// The DATA and MNT parts of a meta-node forest.
#[derive(Clone, Debug, PartialEq)]
pub struct MetaFiles {
    pub data: Vec<u8>,
    pub mnt: Vec<MntRecord>,
}

/// Serialises every meta-node: header (magic, counts), node records, local
/// triangles (triangle id + leaf-id triple), leaf positions (id + xyz).
pub fn encode(tree: &VdTree, meta: &MetaTree) -> MetaFiles {
    let mut data = Vec::new();
    let mut mnt = Vec::with_capacity(meta.metas.len());
    for m in &meta.metas {
        let start = data.len();
        for w in [
            META_MAGIC,
            m.nodes.len() as u32,
            m.triangles.len() as u32,
            m.leaves.len() as u32,
        ] {
            data.extend_from_slice(&w.to_le_bytes());
        }
        for &v in &m.nodes {
            let r = VdNodeRecord {
                id: v,
                node: tree.nodes[v as usize],
                adjacent: if (v as usize) < tree.leaf_count() {
                    0
                } else {
                    tree.adjacent[v as usize - tree.leaf_count()].len() as u32
                },
                child_meta: meta.child_meta[v as usize],
            };
            data.extend_from_slice(bytemuck::bytes_of(&r));
        }
        for &t in &m.triangles {
            data.extend_from_slice(&t.to_le_bytes());
            for c in tree.triangles[t as usize] {
                data.extend_from_slice(&c.to_le_bytes());
            }
        }
        for &l in &m.leaves {
            data.extend_from_slice(&l.to_le_bytes());
            for c in tree.positions[l as usize] {
                data.extend_from_slice(&c.to_le_bytes());
            }
        }
        let payload = &data[start..];
        mnt.push(MntRecord {
            offset: start as u64,
            len: payload.len() as u32,
            checksum: crc32fast::hash(payload),
            parent: m.parent,
            first_child: m.children.first().copied().unwrap_or(NONE),
            child_count: m.children.len() as u32,
            node_count: m.nodes.len() as u32,
        });
    }
    MetaFiles { data, mnt }
}

/// A meta-node read back from its payload.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodedMeta {
    pub nodes: Vec<VdNodeRecord>,
    /// `(triangle id, leaf corners)`.
    pub triangles: Vec<(u32, [u32; 3])>,
    pub leaves: Vec<(u32, [f32; 3])>,
}

/// Checks a payload against its MNT record and parses it.
pub fn decode(bytes: &[u8], rec: &MntRecord) -> Result<DecodedMeta, String> {
    if bytes.len() != rec.len as usize {
        return Err(format!(
            "payload of {} bytes, record says {}",
            bytes.len(),
            rec.len
        ));
    }
    if crc32fast::hash(bytes) != rec.checksum {
        return Err("checksum mismatch".into());
    }
    let word = |i: usize| -> Result<u32, String> {
        bytes
            .get(4 * i..4 * i + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| "truncated".to_string())
    };
    if word(0)? != META_MAGIC {
        return Err("bad magic".into());
    }
    let (nn, nt, nl) = (word(1)? as usize, word(2)? as usize, word(3)? as usize);
    let need = 16usize
        .checked_add(nn.checked_mul(NODE_BYTES).ok_or("overflow")?)
        .and_then(|x| x.checked_add(nt.checked_mul(16)?))
        .and_then(|x| x.checked_add(nl.checked_mul(16)?))
        .ok_or("overflow")?;
    if need != bytes.len() || nn != rec.node_count as usize {
        return Err(format!(
            "counts need {need} bytes, payload has {}",
            bytes.len()
        ));
    }
    let mut at = 16;
    let nodes = (0..nn)
        .map(|_| {
            let r = bytemuck::pod_read_unaligned(&bytes[at..at + NODE_BYTES]);
            at += NODE_BYTES;
            r
        })
        .collect();
    let mut w = at / 4;
    let mut next = || {
        let v = u32::from_le_bytes([
            bytes[4 * w],
            bytes[4 * w + 1],
            bytes[4 * w + 2],
            bytes[4 * w + 3],
        ]);
        w += 1;
        v
    };
    let triangles = (0..nt)
        .map(|_| (next(), [next(), next(), next()]))
        .collect();
    let leaves = (0..nl)
        .map(|_| {
            let id = next();
            (id, [next(), next(), next()].map(f32::from_bits))
        })
        .collect();
    Ok(DecodedMeta {
        nodes,
        triangles,
        leaves,
    })
}
