//! Cells: the scene graph cut into subtrees that are built one at a time.
//!
//! A node's HLOD needs its children's coarsest reps, so a build that makes
//! every leaf first holds every leaf's coarsest rep at once, in proportion
//! to the input. Cut into cells instead (maximal subtrees of at most
//! `cell_tris` input triangles, consecutive small ones grouped), a build
//! makes one cell's leaves and then its interior nodes, deepest first, and
//! keeps only the cells' roots' reps for the levels above, built last. Each
//! node's reps are the same whatever the cut; only the order they are made
//! in changes (and not at all when the whole tree is one cell).

use crate::cluster::TreeNode;

/// The nodes of one cell (or group of small cells).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct Cell {
    /// Its leaves, in index order.
    pub leaves: Vec<usize>,
    /// Its interior nodes, deepest first (then by index).
    pub interior: Vec<usize>,
    /// Input triangles under it.
    pub tris: u64,
    /// The roots of its subtrees.
    pub roots: Vec<usize>,
}

/// Cells in depth-first order, and the interior nodes above them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct Plan {
    pub cells: Vec<Cell>,
    /// Interior nodes above every cell, deepest first.
    pub upper: Vec<usize>,
}

/// Input triangles under each node.
pub(super) fn subtree_tris(tree: &[TreeNode], item_tris: &[usize]) -> Vec<u64> {
    let mut t = vec![0u64; tree.len()];
    // Breadth-first order: children come after their parent.
    for i in (0..tree.len()).rev() {
        let n = &tree[i];
        t[i] = n
            .items
            .iter()
            .map(|&k| item_tris[k as usize] as u64)
            .sum::<u64>()
            + n.children.iter().map(|&c| t[c as usize]).sum::<u64>();
    }
    t
}

fn deepest_first(tree: &[TreeNode], nodes: &mut [usize]) {
    nodes.sort_unstable_by_key(|&i| (std::cmp::Reverse(tree[i].depth), i));
}

/// Cuts the subtrees under `tops` (the whole tree: `&[0]`) into cells of at
/// most `cell_tris` input triangles (a leaf larger than that is a cell of
/// its own); `upper` is the nodes of those subtrees above the cells.
pub(super) fn plan(tree: &[TreeNode], item_tris: &[usize], cell_tris: u64, tops: &[usize]) -> Plan {
    if tree.is_empty() {
        return Plan::default();
    }
    let tris = subtree_tris(tree, item_tris);
    // Maximal subtrees within the size, in depth-first order.
    let mut roots = Vec::new();
    let mut upper = Vec::new();
    let mut stack: Vec<usize> = tops.iter().rev().copied().collect();
    while let Some(n) = stack.pop() {
        if tris[n] <= cell_tris || tree[n].children.is_empty() {
            roots.push(n);
        } else {
            upper.push(n);
            stack.extend(tree[n].children.iter().rev().map(|&c| c as usize));
        }
    }
    // Consecutive subtrees grouped while the group stays within the size.
    let mut cells: Vec<Cell> = Vec::new();
    let mut group: Vec<usize> = Vec::new();
    let mut group_tris = 0u64;
    let mut flush = |group: &mut Vec<usize>, group_tris: &mut u64| {
        if group.is_empty() {
            return;
        }
        let mut cell = Cell {
            tris: *group_tris,
            roots: group.clone(),
            ..Cell::default()
        };
        let mut stack = std::mem::take(group);
        while let Some(n) = stack.pop() {
            if tree[n].children.is_empty() {
                cell.leaves.push(n);
            } else {
                cell.interior.push(n);
                stack.extend(tree[n].children.iter().map(|&c| c as usize));
            }
        }
        cell.leaves.sort_unstable();
        deepest_first(tree, &mut cell.interior);
        cells.push(cell);
        *group_tris = 0;
    };
    for r in roots {
        if !group.is_empty() && group_tris + tris[r] > cell_tris {
            flush(&mut group, &mut group_tris);
        }
        group.push(r);
        group_tris += tris[r];
    }
    flush(&mut group, &mut group_tris);
    deepest_first(tree, &mut upper);
    Plan { cells, upper }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A complete tree of `branching` and `depth`, leaves of one item each.
    fn tree(branching: u32, depth: u32) -> (Vec<TreeNode>, Vec<usize>) {
        let mut nodes = vec![TreeNode {
            parent: None,
            depth: 0,
            children: Vec::new(),
            items: Vec::new(),
        }];
        let mut i = 0;
        while i < nodes.len() {
            if nodes[i].depth < depth {
                for _ in 0..branching {
                    let c = nodes.len() as u32;
                    nodes[i].children.push(c);
                    nodes.push(TreeNode {
                        parent: Some(i as u32),
                        depth: nodes[i].depth + 1,
                        children: Vec::new(),
                        items: Vec::new(),
                    });
                }
            }
            i += 1;
        }
        let mut items = 0;
        for n in &mut nodes {
            if n.children.is_empty() {
                n.items.push(items);
                items += 1;
            }
        }
        let tris = (0..items as usize).map(|k| 100 + k * 7).collect();
        (nodes, tris)
    }

    /// Every node in exactly one cell or above them all; a node's children
    /// are made before it.
    fn check(tree: &[TreeNode], plan: &Plan) {
        let mut order: Vec<usize> = Vec::new();
        for c in &plan.cells {
            order.extend(&c.leaves);
            order.extend(&c.interior);
        }
        order.extend(&plan.upper);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..tree.len()).collect::<Vec<_>>());
        let mut pos = vec![0; tree.len()];
        for (k, &n) in order.iter().enumerate() {
            pos[n] = k;
        }
        for (i, n) in tree.iter().enumerate() {
            for &c in &n.children {
                assert!(pos[c as usize] < pos[i], "child {c} after its parent {i}");
            }
        }
    }

    #[test]
    fn one_cell_when_everything_fits() {
        let (t, tris) = tree(4, 3);
        let p = plan(&t, &tris, u64::MAX, &[0]);
        assert_eq!(p.cells.len(), 1);
        assert!(p.upper.is_empty());
        check(&t, &p);
        // The whole tree as one cell is the in-core order: leaves by index,
        // then interior nodes deepest first.
        let leaves: Vec<usize> = (0..t.len()).filter(|&i| t[i].children.is_empty()).collect();
        assert_eq!(p.cells[0].leaves, leaves);
    }

    #[test]
    fn cells_stay_within_the_size() {
        let (t, tris) = tree(3, 4);
        let all = subtree_tris(&t, &tris)[0];
        for cell_tris in [1, 150, 500, 2_000, all / 2, all - 1] {
            let p = plan(&t, &tris, cell_tris, &[0]);
            check(&t, &p);
            for c in &p.cells {
                assert!(
                    c.tris <= cell_tris || c.leaves.len() == 1,
                    "{c:?} over {cell_tris}"
                );
                let sum: u64 = c
                    .leaves
                    .iter()
                    .map(|&l| tris[t[l].items[0] as usize] as u64)
                    .sum();
                assert_eq!(sum, c.tris);
            }
            assert!(!p.upper.is_empty());
        }
    }
}
