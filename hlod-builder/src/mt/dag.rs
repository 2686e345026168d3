//! The cluster DAG behind a Multi-Triangulation, level by level: split into
//! clusters (`meshopt::build_meshlets`), group neighbouring clusters
//! (`meshopt::partition_clusters`), lock the vertices shared by two groups
//! (and the input's border), simplify each group (`simplify_with_locks`,
//! sparse, absolute error) to half and split the result into new clusters.
//!
//! `meshopt`'s own `clod_build` abandons a group that will not simplify and
//! forgets its clusters, so the next levels stop locking the vertices they
//! share with their neighbours, and a cut that shows that group beside a
//! coarser neighbour has a crack. Here such a group's clusters go on to the
//! next level unchanged and are grouped again; only what no level can
//! reduce ends in the last (root) group.

use meshopt::{SimplifyOptions, VertexDataAdapter, build_meshlets, partition_clusters};

/// A group as the MT sees it: the error and sphere of its simplified
/// result (terminal groups are never coarsened).
pub(super) struct Group {
    pub error: f32,
    pub center: [f32; 3],
    pub radius: f32,
    pub terminal: bool,
}

/// Each cluster: the group it is in, the group that made it (-1: input),
/// its triangles.
pub(super) type Clusters = Vec<(u32, i32, Vec<u32>)>;

struct Cluster {
    refined: i32,
    indices: Vec<u32>,
    center: [f32; 3],
    radius: f32,
    error: f32,
}

/// Triangles a level keeps at most for a group to count as simplified.
const STUCK: f32 = 0.85;
/// Levels at most (each halves most groups).
const MAX_LEVELS: usize = 64;

pub(super) fn build(
    positions: &[[f32; 3]],
    tris: &[u32],
    weld: &[u32],
    input_locks: &[bool],
    cluster_tris: usize,
    group_clusters: usize,
) -> (Vec<Group>, Clusters) {
    let bytes: &[u8] = bytemuck::cast_slice(positions);
    let adapter = VertexDataAdapter::new(bytes, 12, 0).expect("12-byte positions");
    let mut groups = Vec::new();
    let mut out: Clusters = Vec::new();
    let mut clusters = split(tris, &adapter, positions, cluster_tris, -1, None);
    for level in 0.. {
        if clusters.len() <= 1 || level == MAX_LEVELS {
            break;
        }
        let assign = group(&clusters, weld, group_clusters);
        let count = assign.iter().map(|&g| g as usize + 1).max().unwrap_or(0);
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
        for (c, &g) in assign.iter().enumerate() {
            members[g as usize].push(c);
        }
        let locks = shared_locks(&clusters, &members, weld, input_locks);
        let mut next = Vec::new();
        let mut progress = false;
        let mut taken: Vec<Option<Cluster>> = clusters.into_iter().map(Some).collect();
        for m in members.iter().filter(|m| !m.is_empty()) {
            let cs: Vec<Cluster> = m.iter().map(|&c| taken[c].take().expect("once")).collect();
            let merged: Vec<u32> = cs.iter().flat_map(|c| c.indices.iter().copied()).collect();
            let target = (merged.len() / 3) / 2 * 3;
            let mut err = 0f32;
            let simplified = meshopt::simplify_with_locks(
                &merged,
                &adapter,
                &locks,
                target,
                f32::MAX,
                SimplifyOptions::Sparse | SimplifyOptions::ErrorAbsolute,
                Some(&mut err),
            );
            if simplified.is_empty() || simplified.len() as f32 > merged.len() as f32 * STUCK {
                next.extend(cs);
                continue;
            }
            progress = true;
            let mut b = (cs[0].center, cs[0].radius);
            for c in &cs[1..] {
                b = enclose(b, (c.center, c.radius));
            }
            let error = cs.iter().map(|c| c.error).fold(err, f32::max);
            let id = groups.len() as i32;
            groups.push(Group {
                error,
                center: b.0,
                radius: b.1,
                terminal: false,
            });
            for c in cs {
                out.push((id as u32, c.refined, c.indices));
            }
            next.extend(split(
                &simplified,
                &adapter,
                positions,
                cluster_tris,
                id,
                Some((b, error)),
            ));
        }
        clusters = next;
        if !progress {
            break;
        }
    }
    // What is left is never coarsened: the root.
    let id = groups.len() as u32;
    let (mut center, mut radius) = ([0.0; 3], -1.0f32);
    for c in &clusters {
        (center, radius) = if radius < 0.0 {
            (c.center, c.radius)
        } else {
            enclose((center, radius), (c.center, c.radius))
        };
    }
    groups.push(Group {
        error: f32::MAX,
        center,
        radius: radius.max(0.0),
        terminal: true,
    });
    for c in clusters {
        out.push((id, c.refined, c.indices));
    }
    (groups, out)
}

/// Splits triangles into clusters made by group `refined`; their bounds
/// and error are the group's (`None`: the input's, measured).
fn split(
    tris: &[u32],
    adapter: &VertexDataAdapter<'_>,
    positions: &[[f32; 3]],
    cluster_tris: usize,
    refined: i32,
    bounds: Option<(([f32; 3], f32), f32)>,
) -> Vec<Cluster> {
    let max_t = cluster_tris.next_multiple_of(4);
    let m = build_meshlets(tris, adapter, cluster_tris.min(255), max_t, 0.0);
    m.iter()
        .map(|ml| {
            let indices: Vec<u32> = ml
                .triangles
                .iter()
                .map(|&t| ml.vertices[t as usize])
                .collect();
            let ((center, radius), error) =
                bounds.unwrap_or_else(|| (sphere(&indices, positions), 0.0));
            Cluster {
                refined,
                indices,
                center,
                radius,
                error,
            }
        })
        .collect()
}

fn sphere(indices: &[u32], positions: &[[f32; 3]]) -> ([f32; 3], f32) {
    let mut lo = glam::Vec3::splat(f32::INFINITY);
    let mut hi = glam::Vec3::splat(f32::NEG_INFINITY);
    for &i in indices {
        let p = glam::Vec3::from(positions[i as usize]);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let c = (lo + hi) * 0.5;
    let r = indices
        .iter()
        .map(|&i| c.distance(glam::Vec3::from(positions[i as usize])))
        .fold(0.0f32, f32::max);
    (c.to_array(), r)
}

/// Groups of about `size` clusters that share vertices (by position).
fn group(clusters: &[Cluster], weld: &[u32], size: usize) -> Vec<u32> {
    let idx: Vec<u32> = clusters
        .iter()
        .flat_map(|c| c.indices.iter().map(|&v| weld[v as usize]))
        .collect();
    let counts: Vec<u32> = clusters.iter().map(|c| c.indices.len() as u32).collect();
    let vertex_count = weld.iter().map(|&w| w as usize + 1).max().unwrap_or(0);
    let mut dest = vec![0u32; clusters.len()];
    partition_clusters(&mut dest, &idx, &counts, vertex_count, size);
    dest
}

/// Locks the input's locks and every vertex (by position) that two groups
/// share.
fn shared_locks(
    clusters: &[Cluster],
    members: &[Vec<usize>],
    weld: &[u32],
    input_locks: &[bool],
) -> Vec<bool> {
    let welded = weld.iter().map(|&w| w as usize + 1).max().unwrap_or(0);
    let mut owner = vec![u32::MAX; welded];
    let mut shared = vec![false; welded];
    for (g, m) in members.iter().enumerate() {
        for &c in m {
            for &v in &clusters[c].indices {
                let w = weld[v as usize] as usize;
                if owner[w] == u32::MAX {
                    owner[w] = g as u32;
                } else if owner[w] != g as u32 {
                    shared[w] = true;
                }
            }
        }
    }
    input_locks
        .iter()
        .zip(weld)
        .map(|(&l, &w)| l || shared[w as usize])
        .collect()
}

/// The smallest sphere holding two spheres (with a little slack).
pub(super) fn enclose(a: ([f32; 3], f32), b: ([f32; 3], f32)) -> ([f32; 3], f32) {
    let (ac, bc) = (glam::Vec3::from(a.0), glam::Vec3::from(b.0));
    let d = ac.distance(bc);
    if d + b.1 <= a.1 {
        return a;
    }
    if d + a.1 <= b.1 {
        return b;
    }
    let r = 0.5 * (d + a.1 + b.1);
    let dir = (bc - ac) / d.max(f32::MIN_POSITIVE);
    ((ac + dir * (r - a.1)).to_array(), r * (1.0 + 1e-6))
}
