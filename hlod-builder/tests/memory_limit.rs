//! The bounded-memory build (issue 23, item 2): under a memory limit the
//! scene graph is built in cells, the heap never exceeds the limit, the
//! output is byte-identical to the unbounded build's, and a limit below
//! what the build needs at least is refused before anything is written.
//!
//! This file is its own test binary so that the counted heap is this
//! build's alone (one test, one build at a time).

use std::path::Path;

use hlod_builder::build::{BuildError, BuildParams, RunOptions, build_file_with};
use hlod_builder::heap;
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

fn build(
    input: &Path,
    out: &Path,
    params: &BuildParams,
    limit: Option<u64>,
) -> Result<hlod_builder::BuildStats, BuildError> {
    let opts = RunOptions {
        progress: false,
        report: &|_, _, _| {},
        memory_limit: limit,
    };
    heap::reset_peak();
    build_file_with(input, out, params, &opts)
}

#[test]
fn cells_keep_the_heap_under_the_limit_and_the_bytes_the_same() {
    heap::mark_installed();
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("plant.glb");
    let p = PlantParams {
        seed: 4,
        objects: 600,
        triangles: 600_000,
    };
    write_plant(&p, &glb).unwrap();
    // Small HLODs, so that an interior batch is small beside the cells.
    let params = BuildParams {
        hlod_tris: 512,
        ..BuildParams::default()
    };
    let reference = dir.path().join("ref.hlod");
    let s = build(&glb, &reference, &params, None).unwrap();
    assert_eq!(s.cells, 1, "the default limit holds this scene in one cell");
    let want = std::fs::read(&reference).unwrap();

    let mut accepted = Vec::new();
    let mut refused = None;
    for mib in [64u64, 40, 28, 20, 14, 10, 7, 5, 3] {
        let limit = mib << 20;
        let out = dir.path().join(format!("l{mib}.hlod"));
        match build(&glb, &out, &params, Some(limit)) {
            Ok(s) => {
                let peak = s.peak_heap.expect("the heap is counted here");
                assert!(peak <= limit, "limit {mib} MiB: peak heap {peak}");
                assert_eq!(
                    std::fs::read(&out).unwrap(),
                    want,
                    "limit {mib} MiB: other bytes"
                );
                accepted.push((mib, s.cells));
            }
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("needs at least"), "limit {mib} MiB: {msg}");
                assert!(!out.exists(), "a refused build leaves no output");
                refused = Some(mib);
                break;
            }
        }
    }
    assert!(
        accepted.iter().any(|&(_, cells)| cells >= 3),
        "some limit cuts the graph into cells: {accepted:?}"
    );
    assert!(
        refused.is_some(),
        "some limit is below the minimum: {accepted:?}"
    );
    // Nothing but the outputs is left in the directory (no staging files).
    for e in std::fs::read_dir(dir.path()).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            name.ends_with(".hlod") || name.ends_with(".glb"),
            "left behind: {name}"
        );
    }
}
