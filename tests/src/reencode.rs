//! The re-encoding corpus: the test models written again by gltfpack and
//! gltf-transform (installed from npm by `scripts/setup.sh` in
//! `target/npm-tools`, pinned), in the encodings users bring, and the
//! triangle count each file declares, counted here from its JSON alone
//! (independently of the importer: accessor counts, primitive modes, the
//! default scene's nodes and `EXT_mesh_gpu_instancing` counts).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// The tools' folder, made by `scripts/setup.sh`.
pub fn tools_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/npm-tools/node_modules/.bin")
}

/// A re-encoding: its name and the tool's command line (`IN` and `OUT`
/// stand for the files).
pub const ENCODINGS: &[(&str, &str, &[&str])] = &[
    ("gltfpack", "gltfpack", &["-i", "IN", "-o", "OUT"]),
    ("gltfpack-cc", "gltfpack", &["-i", "IN", "-o", "OUT", "-cc"]),
    ("gt-quantize", "gltf-transform", &["quantize", "IN", "OUT"]),
    ("gt-meshopt", "gltf-transform", &["meshopt", "IN", "OUT"]),
    ("gt-instance", "gltf-transform", &["instance", "IN", "OUT"]),
    ("gt-draco", "gltf-transform", &["draco", "IN", "OUT"]),
    ("gt-weld", "gltf-transform", &["weld", "IN", "OUT"]),
    ("gt-flatten", "gltf-transform", &["flatten", "IN", "OUT"]),
];

/// Writes `model` in `encoding` to `out`; the tool's stderr on failure.
pub fn write(tool: &str, args: &[&str], model: &Path, out: &Path) -> Result<(), String> {
    let bin = tools_dir().join(tool);
    if !bin.is_file() {
        return Err(format!(
            "{} is missing: scripts/setup.sh installs gltfpack and gltf-transform there",
            bin.display()
        ));
    }
    let args: Vec<&std::ffi::OsStr> = args
        .iter()
        .map(|a| match *a {
            "IN" => model.as_os_str(),
            "OUT" => out.as_os_str(),
            a => std::ffi::OsStr::new(a),
        })
        .collect();
    let r = Command::new(&bin)
        .args(args)
        .output()
        .map_err(|e| e.to_string())?;
    if r.status.success() && out.is_file() {
        Ok(())
    } else {
        Err(String::from_utf8_lossy(&r.stderr).into_owned())
    }
}

/// The JSON of a `.glb` or `.gltf`.
pub fn json_of(bytes: &[u8]) -> Value {
    if bytes.starts_with(b"glTF") {
        crate::conformance::split_glb(bytes).0
    } else {
        serde_json::from_slice(bytes).unwrap()
    }
}

/// Triangles a document declares after instancing: each placement of a
/// mesh (a node, times its `EXT_mesh_gpu_instancing` count) counts its
/// triangle primitives (lists: indices / 3; strips and fans: n − 2).
pub fn declared_triangles(doc: &Value) -> u64 {
    let count = |a: &Value| {
        a.as_u64()
            .and_then(|i| doc["accessors"][i as usize]["count"].as_u64())
            .unwrap_or(0)
    };
    let mesh_tris = |m: u64| -> u64 {
        let prims = doc["meshes"][m as usize]["primitives"].as_array();
        prims
            .into_iter()
            .flatten()
            .map(|p| {
                let n = if p["indices"].is_null() {
                    count(&p["attributes"]["POSITION"])
                } else {
                    count(&p["indices"])
                };
                match p["mode"].as_u64().unwrap_or(4) {
                    4 => n / 3,
                    5 | 6 => n.saturating_sub(2),
                    _ => 0,
                }
            })
            .sum()
    };
    let scene = doc["scene"].as_u64().unwrap_or(0) as usize;
    let mut stack: Vec<u64> = match doc["scenes"][scene]["nodes"].as_array() {
        Some(roots) => roots.iter().filter_map(Value::as_u64).collect(),
        None => Vec::new(),
    };
    let mut total = 0;
    while let Some(n) = stack.pop() {
        let node = &doc["nodes"][n as usize];
        if let Some(m) = node["mesh"].as_u64() {
            let inst = &node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
            let k = inst
                .as_object()
                .and_then(|o| o.values().next())
                .map_or(1, count);
            total += k * mesh_tris(m);
        }
        if let Some(c) = node["children"].as_array() {
            stack.extend(c.iter().filter_map(Value::as_u64));
        }
    }
    total
}
