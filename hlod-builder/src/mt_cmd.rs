//! `hlod-build mt`: the Multi-Triangulation of a model's largest mesh,
//! reported and written as an MT file.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use hlod_builder::mt::{MtParams, build_mt};
use hlod_builder::summary::human_bytes;

pub fn mt_report(
    input: &Path,
    theta: u32,
    cluster_tris: usize,
    group_clusters: usize,
    output: Option<&Path>,
) -> Result<()> {
    if !(1..=engine::mt::partition::MAX_THETA).contains(&theta) {
        bail!(
            "--theta {theta}: must be in 1..={} nodes per partition",
            engine::mt::partition::MAX_THETA
        );
    }
    if !(8..=256).contains(&cluster_tris) {
        bail!("--cluster-tris {cluster_tris}: must be in 8..=256");
    }
    if !(2..=64).contains(&group_clusters) {
        bail!("--group-clusters {group_clusters}: must be in 2..=64");
    }
    let inputs = hlod_builder::import::model_files(input);
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    if let Some(out) = output {
        engine_cli::outfile::check_output(out, &inputs)?;
    }
    let imp = hlod_builder::import::load(input)?;
    let (i, m) = imp
        .meshes
        .iter()
        .enumerate()
        .filter_map(|(i, m)| m.as_ref().map(|m| (i, m)))
        .max_by_key(|(i, m)| (m.indices.len(), std::cmp::Reverse(*i)))
        .ok_or_else(|| anyhow!("{}: no mesh", input.display()))?;
    let t = std::time::Instant::now();
    let mt = build_mt(
        &m.positions,
        &m.normals,
        &m.indices,
        &MtParams {
            cluster_tris,
            group_clusters,
        },
    )
    .map_err(|e| anyhow!("{}: mesh {i}: {e}", input.display()))?;
    let build_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    mt.validate().map_err(|e| {
        anyhow!(
            "{}: mesh {i}: invalid Multi-Triangulation: {e}",
            input.display()
        )
    })?;
    let check_s = t.elapsed().as_secs_f64();
    let parts = engine::mt::partition(&mt, theta)?;
    let bytes = engine::mt::file::encode(&mt, &parts)?;
    println!(
        "| mesh | input tris | nodes | arcs | layers | tris in arcs | mean patch | partitions (θ = {theta}) | file | build s | check s |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {i} | {} | {} | {} | {} | {} | {:.1} | {} | {} | {build_s:.2} | {check_s:.2} |",
        mt.input_triangles,
        mt.nodes.len(),
        mt.arcs.len(),
        mt.layers(),
        mt.arc_triangles(),
        mt.mean_patch(),
        parts.count,
        human_bytes(bytes.len() as u64),
    );
    if let Some(out) = output {
        use std::io::Write;
        engine_cli::outfile::write_with(out, &inputs, |w| w.write_all(&bytes))
            .with_context(|| format!("cannot write {}", out.display()))?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

/// One line of `hlod-build info` for MT rep `r`.
pub fn info_line<S: engine::ByteSource>(scene: &engine::SceneFile<S>, r: u32) -> Result<String> {
    let rec = scene.skeleton().reps[r as usize];
    let f = scene.read_mt(r)?;
    let h = f.header;
    Ok(format!(
        "  MT rep {r} (node {}): {} triangles, error {:.5}; {} nodes, {} arcs ({:.1} triangles per arc), {} layers, {} partitions (θ = {}), in core {}, nodes {} (largest {})",
        rec.node,
        h.input_triangles,
        rec.error,
        h.node_count,
        h.arc_count,
        h.arc_triangles as f64 / f64::from(h.arc_count.max(1)),
        h.layers,
        h.partition_count,
        h.theta,
        human_bytes(u64::from(rec.len)),
        human_bytes(h.data_len),
        human_bytes(u64::from(h.max_record)),
    ))
}
