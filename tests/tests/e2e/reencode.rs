//! The re-encoding corpus as a test: the small test models written again by
//! gltfpack 1.3 (default, `-cc`) and gltf-transform 4.5.1 (`quantize`,
//! `meshopt`, `instance`, `draco`, `weld`, `flatten`), as `scripts/setup.sh`
//! installs them; each file imports with the triangle count it declares
//! (counted from its JSON, not by the importer) and the plain model's box
//! (to 0.2% of its size: the tools quantize). `scripts/reencode.sh` runs it
//! on every model (`HLOD_REENCODE_MODELS=all`).

use e2e_tests::conformance;
use e2e_tests::data_dir;
use e2e_tests::reencode::{self, ENCODINGS};
use hlod_builder::import;

use crate::conformance::world_box;

const SMALL: &[&str] = &[
    "AC14-FZK-Haus.glb",
    "Ifc2x3_Duplex_Architecture.glb",
    "dragon_res4.glb",
    "grid-colours.glb",
];

const ALL: &[&str] = &[
    "AC14-FZK-Haus.glb",
    "Ifc2x3_Duplex_Architecture.glb",
    "dragon_res4.glb",
    "grid-colours.glb",
    "2CylinderEngine/2CylinderEngine.gltf",
    "schependomlaan_subcontractors.glb",
    "bunny.glb",
];

#[test]
fn re_encodings_by_gltfpack_and_gltf_transform_import_with_their_declared_count_and_box() {
    let models = match std::env::var("HLOD_REENCODE_MODELS").as_deref() {
        Ok("all") => ALL,
        _ => SMALL,
    };
    let dir = tempfile::tempdir().unwrap();
    let mut wrong = Vec::new();
    println!("| model | encoding | declared | imported | box |");
    println!("|---|---|---:|---:|---|");
    for model in models {
        let src = data_dir().join(model);
        let stem = src.file_stem().unwrap().to_string_lossy().into_owned();
        let (a, b) = conformance::world_box(&conformance::read_flat(&src));
        let tol = (b - a).max_element() * 2e-3;
        for (name, tool, args) in ENCODINGS {
            let out = dir.path().join(format!("{stem}.{name}.glb"));
            reencode::write(tool, args, &src, &out)
                .unwrap_or_else(|e| panic!("{stem}.{name}: the tool failed: {e}"));
            let declared =
                reencode::declared_triangles(&reencode::json_of(&std::fs::read(&out).unwrap()));
            let (got, boxed) = match import::load(&out) {
                Ok(imp) => {
                    let (p, q) = world_box(&imp);
                    let ok = (p - a).abs().max_element() < tol && (q - b).abs().max_element() < tol;
                    (imp.instanced_source_triangles(), ok)
                }
                Err(e) => {
                    wrong.push(format!("{stem}.{name}: {e}"));
                    continue;
                }
            };
            println!(
                "| {stem} | {name} | {declared} | {got} | {} |",
                if boxed { "ok" } else { "WRONG" }
            );
            if got != declared || !boxed {
                wrong.push(format!(
                    "{stem}.{name}: {got} triangles imported, {declared} declared, box ok: {boxed}"
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}
