//! Every WGSL file in `shaders/` parses and validates with naga, and the
//! renderer's entry points exist with the stages it uses.

use std::path::Path;

fn validate(path: &Path) -> naga::Module {
    let src = std::fs::read_to_string(path).unwrap();
    let module = naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(&src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(&src)));
    module
}

#[test]
fn all_wgsl_files_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shaders");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no WGSL files in {}", dir.display());
    for f in &files {
        validate(f);
    }
}

#[test]
fn mesh_shader_has_the_renderers_entry_points() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shaders");
    let m = validate(&dir.join("mesh.wgsl"));
    let stages: Vec<(String, naga::ShaderStage)> = m
        .entry_points
        .iter()
        .map(|e| (e.name.clone(), e.stage))
        .collect();
    assert!(stages.contains(&("vs_main".into(), naga::ShaderStage::Vertex)));
    assert!(stages.contains(&("fs_main".into(), naga::ShaderStage::Fragment)));
    // The renderer embeds the same file.
    assert_eq!(
        engine_gpu::MESH_WGSL,
        std::fs::read_to_string(dir.join("mesh.wgsl")).unwrap()
    );
}
