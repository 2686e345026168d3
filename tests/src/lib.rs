//! End-to-end tests of the builder and the scene format; the tests live in
//! `tests/tests/`. This library holds their shared helpers.

pub mod conformance;
pub mod reencode;
pub mod servers;
pub mod web;

use std::path::PathBuf;

/// The repository's `tests/data` directory.
pub fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data")
}

/// A glTF 2.0 JSON document with one mesh of one primitive, its buffer embedded
/// as a data URI. `count` overrides the POSITION accessor's count.
pub fn tiny_gltf(
    positions: &[[f32; 3]],
    indices: &[u32],
    mode: u32,
    count: Option<usize>,
) -> String {
    use base64::Engine as _;
    let mut bin: Vec<u8> = Vec::new();
    for p in positions {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let ioff = bin.len();
    for i in indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let finite = positions
        .iter()
        .flatten()
        .copied()
        .filter(|c| c.is_finite());
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":{mode}}}]}}],
"accessors":[
 {{"bufferView":0,"componentType":5126,"count":{pc},"type":"VEC3","min":[{lo},{lo},{lo}],"max":[{hi},{hi},{hi}]}},
 {{"bufferView":1,"componentType":5125,"count":{ic},"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pl}}},{{"buffer":0,"byteOffset":{ioff},"byteLength":{il}}}],
"buffers":[{{"byteLength":{bl},"uri":"{uri}"}}]}}"#,
        pc = count.unwrap_or(positions.len()),
        lo = finite.clone().fold(0f32, f32::min),
        hi = finite.fold(0f32, f32::max),
        ic = indices.len(),
        pl = ioff,
        il = bin.len() - ioff,
        bl = bin.len(),
    )
}

/// A bumpy grid of `n x n` quads.
pub fn grid(n: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut p = Vec::new();
    for y in 0..=n {
        for x in 0..=n {
            p.push([x as f32, y as f32, ((x * 7 + y * 3) % 5) as f32 * 0.1]);
        }
    }
    let w = n + 1;
    let mut idx = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let i = y * w + x;
            idx.extend_from_slice(&[i, i + 1, i + w + 1, i, i + w + 1, i + w]);
        }
    }
    (p, idx)
}

/// A GPU context for a test, or `None` when this machine has no adapter:
/// the test then returns early, and its name and the reason are appended to
/// `target/test-skips.txt` (which `scripts/test.sh` counts and prints), so a
/// skip is reported, not hidden. With `HLOD_REQUIRE_GPU` set (as
/// `scripts/test.sh` sets it once it has installed lavapipe) a missing
/// adapter fails the test instead.
pub fn gpu_or_skip(test: &str) -> Option<engine_gpu::GpuContext> {
    match engine_gpu::GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(e) => {
            if std::env::var_os("HLOD_REQUIRE_GPU").is_some() {
                panic!("{test}: no GPU adapter although HLOD_REQUIRE_GPU is set: {e}");
            }
            record_skip(test, &e.to_string());
            None
        }
    }
}

/// Appends a skipped test and why to `target/test-skips.txt`.
pub fn record_skip(test: &str, why: &str) {
    use std::io::Write;
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target");
    let _ = std::fs::create_dir_all(&dir);
    if let Ok(mut f) = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("test-skips.txt"))
    {
        let _ = writeln!(f, "SKIPPED {test}: {why}");
    }
    eprintln!("SKIPPED {test}: {why}");
}

/// Runs `cmd` in `cwd` with no input and its output captured, killed after
/// `limit` (a program blocked on a FIFO or waiting for ever would hang the
/// test otherwise: this panics instead, with what it printed).
pub fn run_limited(
    cmd: &mut std::process::Command,
    cwd: &std::path::Path,
    limit: std::time::Duration,
) -> std::process::Output {
    use std::process::Stdio;
    let mut child = cmd
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let t = std::time::Instant::now();
    while child.try_wait().expect("waits").is_none() {
        if t.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().expect("ends");
            panic!(
                "{cmd:?} still running after {limit:?} (blocked?): {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.wait_with_output().expect("output")
}

/// The names in a folder, sorted.
pub fn names(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("a folder")
        .map(|e| {
            e.expect("an entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    v.sort();
    v
}

/// Makes a FIFO at `path` (`mkfifo`).
pub fn mkfifo(path: &std::path::Path) {
    let ok = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "mkfifo {}", path.display());
}

/// A closed box `[-h, h]³` around `centre`, of one colour: faces wound
/// counter-clockwise seen from outside, normals outwards (the GPU tests'
/// solid to cut, hide and measure).
pub fn cube(centre: glam::Vec3, h: f32, color: [u8; 4]) -> hlod_builder::mesh::Mesh {
    let mut m = hlod_builder::mesh::Mesh::default();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = glam::Vec3::ZERO;
            n[axis] = sign;
            // Two axes spanning the face, u × v = n.
            let (mut u, mut v) = n.any_orthonormal_pair();
            if u.cross(v).dot(n) < 0.0 {
                std::mem::swap(&mut u, &mut v);
            }
            let base = m.positions.len() as u32;
            for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                m.positions
                    .push((centre + (n + u * su + v * sv) * h).to_array());
                m.normals.push(n.to_array());
                m.colors.push(color);
            }
            m.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    m
}
