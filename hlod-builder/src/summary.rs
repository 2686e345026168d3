//! The Table-1-style summary (Varadhan & Manocha, Table 1) of a built scene.

use std::fmt::Write as _;

use engine::{ByteSource, SceneFile};

use crate::build::BuildStats;

/// Summary figures derived from a scene file's skeleton.
pub fn stats_of<S: ByteSource>(scene: &SceneFile<S>) -> BuildStats {
    let s = scene.skeleton();
    let h = scene.header();
    BuildStats {
        objects: u64::from(h.object_count),
        nodes: s.nodes.len() as u64,
        leaves: s.nodes.iter().filter(|n| n.is_leaf()).count() as u64,
        chunked_objects: 0,
        hidden_objects: 0,
        hidden_triangles: 0,
        vdt_objects: s.reps.iter().filter(|r| r.is_vdt()).count() as u64,
        mt_objects: s.reps.iter().filter(|r| r.is_mt()).count() as u64,
        height: s.height(),
        reps: s.reps.len() as u64,
        input_triangles: h.input_triangles,
        usable_triangles: s
            .nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| u64::from(s.reps[(n.first_rep + n.rep_count - 1) as usize].tri_count))
            .sum(),
        output_triangles: s.total_triangles(),
        skeleton_bytes: h.skeleton_len,
        data_bytes: (s.reps.iter().enumerate())
            .filter(|&(r, _)| s.owns_payload(r as u32))
            .map(|(_, r)| r.extent())
            .sum(),
        file_bytes: h.file_len,
        seconds: f64::NAN,
        warnings: Vec::new(),
        origin: h.origin,
        object_bytes: h.objects_len,
        cells: 0,
        memory_plan: None,
        peak_heap: None,
        walk: crate::walkmap::WalkStats {
            cell: scene
                .read_walk_index()
                .ok()
                .flatten()
                .map_or(0.0, |i| i.header.cell),
            cells: 0,
            bytes: h.walk_len,
            bands: 0,
        },
    }
}

/// Markdown header of the summary table.
pub const TABLE_HEADER: &str = "| scene | input tris | objects | nodes | leaves | height | reps | output tris | skeleton | data | file | skeleton/data | time |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|";

/// One Markdown row of the summary table.
pub fn table_row(name: &str, s: &BuildStats) -> String {
    let mut row = String::new();
    let time = if s.seconds.is_finite() {
        format!("{:.1} s", s.seconds)
    } else {
        "-".into()
    };
    let _ = write!(
        row,
        "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3}% | {time} |",
        s.input_triangles,
        s.objects,
        s.nodes,
        s.leaves,
        s.height,
        s.reps,
        s.output_triangles,
        human_bytes(s.skeleton_bytes),
        human_bytes(s.data_bytes),
        human_bytes(s.file_bytes),
        100.0 * s.skeleton_bytes as f64 / s.data_bytes.max(1) as f64,
    );
    row
}

/// `1.23 MiB`-style sizes.
pub use engine::limits::human as human_bytes;
