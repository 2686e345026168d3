//! Sharded builds (issue 23, item 4): `build --shard i/n` jobs and a merge
//! give the single job's bytes; the merge refuses a missing shard, a shard
//! given twice, a shard of other parameters and a corrupt shard file, each
//! by name, leaving no output.

use std::path::{Path, PathBuf};

use hlod_builder::build::shard::{ShardSpec, build_shard_file, merge_files};
use hlod_builder::build::{BuildError, BuildParams, RunOptions, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

fn opts() -> RunOptions<'static> {
    RunOptions {
        progress: false,
        report: &|_, _, _| {},
        memory_limit: None,
    }
}

fn shards(input: &Path, dir: &Path, params: &BuildParams, n: u32) -> Vec<PathBuf> {
    (0..n)
        .map(|i| {
            let out = dir.join(format!("s{i}of{n}.hlsh"));
            let spec = ShardSpec { index: i, count: n };
            build_shard_file(input, &out, params, &opts(), spec).unwrap();
            out
        })
        .collect()
}

fn merge(
    input: &Path,
    files: &[PathBuf],
    out: &Path,
    params: &BuildParams,
) -> Result<(), BuildError> {
    merge_files(input, files, out, params, &opts()).map(|_| ())
}

#[test]
fn shards_merge_to_the_single_jobs_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = d.join("plant.glb");
    let p = PlantParams {
        seed: 11,
        objects: 700,
        triangles: 500_000,
    };
    write_plant(&p, &glb).unwrap();
    // Shards store every placement's levels (the merge shares none), as a
    // single job does with sharing off.
    let params = BuildParams {
        share_instances: false,
        ..BuildParams::default()
    };
    let single = d.join("single.hlod");
    build_file(&glb, &single, &params, false).unwrap();
    let want = std::fs::read(&single).unwrap();
    for n in [1, 3, 4] {
        let files = shards(&glb, d, &params, n);
        let out = d.join(format!("merged{n}.hlod"));
        // Any order of the files.
        let mut rev = files.clone();
        rev.reverse();
        merge(&glb, &rev, &out, &params).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), want, "{n} shards");
    }
    // Re-running a shard job gives the same file (a scheduler's retry is safe).
    let again = shards(&glb, &d.join(""), &params, 4);
    let first = std::fs::read(&again[2]).unwrap();
    build_shard_file(
        &glb,
        &again[2],
        &params,
        &opts(),
        ShardSpec { index: 2, count: 4 },
    )
    .unwrap();
    assert_eq!(std::fs::read(&again[2]).unwrap(), first);
}

#[test]
fn the_merge_refuses_what_does_not_add_up() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = d.join("plant.glb");
    let p = PlantParams {
        seed: 12,
        objects: 300,
        triangles: 200_000,
    };
    write_plant(&p, &glb).unwrap();
    let params = BuildParams::default();
    let files = shards(&glb, d, &params, 4);
    let out = d.join("m.hlod");
    let fails = |files: &[PathBuf], params: &BuildParams| -> String {
        let e = merge(&glb, files, &out, params).unwrap_err().to_string();
        assert!(!out.exists(), "a refused merge leaves no output: {e}");
        e
    };
    // A shard missing.
    let e = fails(
        &[files[0].clone(), files[1].clone(), files[3].clone()],
        &params,
    );
    assert!(e.contains("shard 2/4 is missing"), "{e}");
    // A shard given twice.
    let e = fails(
        &[
            files[0].clone(),
            files[1].clone(),
            files[1].clone(),
            files[2].clone(),
            files[3].clone(),
        ],
        &params,
    );
    assert!(
        e.contains("s1of4.hlsh") && e.contains("give each shard once"),
        "{e}"
    );
    // Other parameters than the merge's.
    let other = BuildParams {
        hlod_ratio: 0.4,
        ..params
    };
    let e = fails(&files, &other);
    assert!(e.contains("other parameters"), "{e}");
    // Shards of two counts.
    let three = shards(&glb, &d.join(""), &params, 3);
    let e = fails(&[files[0].clone(), three[1].clone()], &params);
    assert!(e.contains("of 4") || e.contains("of 3"), "{e}");
    // A corrupt trailer, and a file that is no shard.
    let mut bytes = std::fs::read(&files[3]).unwrap();
    let n = bytes.len();
    bytes[n - 20] ^= 0x55;
    let bad = d.join("bad.hlsh");
    std::fs::write(&bad, &bytes).unwrap();
    let e = fails(
        &[
            files[0].clone(),
            files[1].clone(),
            files[2].clone(),
            bad.clone(),
        ],
        &params,
    );
    assert!(e.contains("bad.hlsh") && e.contains("digest"), "{e}");
    // Altered and resealed (trailer checksum and digest recomputed, as one
    // who holds the input could): a rep byte changed fails that rep's own
    // checksum, and nothing is written.
    let mut bytes = std::fs::read(&files[3]).unwrap();
    bytes[4096 + 40] ^= 0x55;
    hlod_builder::build::shard::reseal(&mut bytes).unwrap();
    std::fs::write(&bad, &bytes).unwrap();
    let mut with_bad = files[..3].to_vec();
    with_bad.push(bad.clone());
    let e = fails(&with_bad, &params);
    assert!(e.contains("checksum"), "{e}");
    // A shard of another input (same parameters, index and count).
    let other_glb = d.join("other.glb");
    write_plant(&PlantParams { seed: 13, ..p }, &other_glb).unwrap();
    let foreign = d.join("foreign.hlsh");
    build_shard_file(
        &other_glb,
        &foreign,
        &params,
        &opts(),
        ShardSpec { index: 3, count: 4 },
    )
    .unwrap();
    let mut with_foreign = files[..3].to_vec();
    with_foreign.push(foreign);
    let e = fails(&with_foreign, &params);
    assert!(
        e.contains("foreign.hlsh") && e.contains("another input"),
        "{e}"
    );
    std::fs::write(&bad, b"not a shard at all, just some bytes that are long enough to have a header, really long enough").unwrap();
    let e = fails(&[bad], &params);
    assert!(e.contains("not a shard file"), "{e}");
    // Bad specs.
    for s in ["4/4", "1/0", "x/2", "3", "-1/2"] {
        assert!(s.parse::<ShardSpec>().is_err(), "{s}");
    }
}
