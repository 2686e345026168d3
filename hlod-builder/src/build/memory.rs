//! Sizing a build to a memory limit (`hlod-build build --memory-limit`).
//!
//! What a build holds grows with the scene's *objects* (its document, the
//! instances, the graph and the records) and, besides, with three things the
//! plan bounds: the leaves being made at once (their geometry and results),
//! the coarsest reps of a cell's finished nodes awaiting their parents, and
//! an interior batch's merged children. The objects' share is measured
//! (the heap in use once the graph is made, where the heap is counted) or
//! estimated; the per-triangle costs are upper bounds measured on the
//! generated plants and the tiled BIM models (`docs/results.md`).

/// Heap per input triangle of a leaf being made: its geometry, world copy,
/// optimised copy, simplifier buffers and LOD chain.
pub const WORK_BYTES_PER_TRI: u64 = 320;
/// Heap per input triangle of a leaf made and not yet written (its chain)
/// or loaded for its batch.
pub const HELD_BYTES_PER_TRI: u64 = 96;
/// Heap per input triangle of a cell for the coarsest reps held until the
/// parents' HLODs are made.
pub const COARSE_BYTES_PER_TRI: u64 = 24;
/// Heap per node still to come: its records (three copies while the file is
/// finished and laid out) and its reps' records.
pub const BYTES_PER_NODE: u64 = 1_200;
/// Heap per object still to come: its entry in the object section.
pub const BYTES_PER_OBJECT: u64 = 480;
/// Heap per object while the graph is made, where the heap is not counted.
pub const ESTIMATED_BYTES_PER_OBJECT: u64 = 2_048;

/// How a build runs within its limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryPlan {
    pub limit: u64,
    /// Input triangles per cell.
    pub cell_tris: u64,
    /// Leaves made at once.
    pub batch: usize,
    /// What the scene's objects and graph take (measured or estimated).
    pub fixed: u64,
}

/// The default limit: half of the machine's memory.
pub fn default_limit() -> u64 {
    engine::limits::memory_total() / 2
}

/// What the plan needs to know of the scene.
#[derive(Clone, Debug, Default)]
pub struct Demand {
    /// Heap in use now (the document, instances, items and graph).
    pub fixed_now: u64,
    pub nodes: u64,
    pub objects: u64,
    /// Input triangles of the leaves, largest first.
    pub leaf_tris_desc: Vec<u64>,
    /// Heap of an interior batch (32 nodes' merged children and their HLODs).
    pub interior_batch: u64,
    /// The LOD chains of shared meshes, held through the build.
    pub chains: u64,
}

/// Heap of an interior batch: 32 nodes' merged children (at most
/// `node_tris` each, and never more than the scene) held, `threads` of them
/// being simplified.
pub fn interior_batch(node_tris: u64, scene_tris: u64, threads: usize) -> u64 {
    (32 * node_tris).min(scene_tris) * HELD_BYTES_PER_TRI
        + threads as u64 * node_tris.min(scene_tris) * WORK_BYTES_PER_TRI
}

/// The plan for `limit`, or why the limit is too small (what it needs at least).
pub fn plan(limit: u64, d: &Demand, threads: usize) -> Result<MemoryPlan, String> {
    let fixed = d.fixed_now + d.chains + d.nodes * BYTES_PER_NODE + d.objects * BYTES_PER_OBJECT;
    let threads = threads.max(1);
    let largest = d.leaf_tris_desc.first().copied().unwrap_or(0);
    let batch_need = |b: usize| -> u64 {
        let held: u64 = d.leaf_tris_desc.iter().take(b).sum();
        held * HELD_BYTES_PER_TRI + threads as u64 * largest * WORK_BYTES_PER_TRI
    };
    let human = engine::limits::human;
    let minimum =
        fixed + batch_need(threads) + d.interior_batch + largest.max(1) * COARSE_BYTES_PER_TRI;
    if limit < minimum {
        return Err(format!(
            "--memory-limit {} is below what this build needs at least: {} ({} for the scene's \
             objects and graph, {} for making its largest leaves {threads} at a time)",
            human(limit),
            human(minimum),
            human(fixed),
            human(batch_need(threads))
        ));
    }
    // The largest batch that leaves room for cells of at least the largest leaf.
    let mut batch = 64usize;
    while batch > threads
        && fixed + batch_need(batch) + d.interior_batch + largest * COARSE_BYTES_PER_TRI > limit
    {
        batch /= 2;
    }
    let batch = batch.max(threads);
    let left = limit - fixed - batch_need(batch) - d.interior_batch;
    Ok(MemoryPlan {
        limit,
        cell_tris: (left / COARSE_BYTES_PER_TRI).max(1),
        batch,
        fixed,
    })
}

/// Parses a size: bytes, or with a K, M, G or T suffix (powers of 1024;
/// `iB` or `B` after it allowed), e.g. `4G`, `512MiB`.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (num, mult) = match t.chars().last() {
        Some(c @ ('K' | 'k' | 'M' | 'm' | 'G' | 'g' | 'T' | 't')) => {
            let shift = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                _ => 40,
            };
            (&t[..t.len() - 1], 1u64 << shift)
        }
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("{s:?}: expected a size such as 4G, 512M or 1073741824"))?;
    if !(v.is_finite() && v > 0.0) || v * mult as f64 > u64::MAX as f64 / 2.0 {
        return Err(format!("{s:?}: a size must be positive and finite"));
    }
    Ok((v * mult as f64) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("4G").unwrap(), 4 << 30);
        assert_eq!(parse_size("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_size("1.5k").unwrap(), 1536);
        assert_eq!(parse_size("1000").unwrap(), 1000);
        for bad in ["", "G", "-1G", "0", "x", "nanG", "1e300T"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn plans_shrink_with_the_limit_and_refuse_below_the_minimum() {
        let d = Demand {
            fixed_now: 100 << 20,
            nodes: 10_000,
            objects: 50_000,
            leaf_tris_desc: vec![65_536; 200],
            interior_batch: 50 << 20,
            chains: 0,
        };
        let big = plan(16 << 30, &d, 2).unwrap();
        let small = plan(1 << 30, &d, 2).unwrap();
        assert!(big.cell_tris > small.cell_tris && big.batch >= small.batch);
        assert_eq!(big.batch, 64);
        let e = plan(200 << 20, &d, 2).unwrap_err();
        assert!(e.contains("needs at least"), "{e}");
    }
}
