//! Writes every conformance variant of a model: `gltf-variants MODEL OUT_DIR`
//! (`OUT_DIR/NAME.VARIANT.glb`), for trying the builder and the viewer on them.

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, model, out] = args.as_slice() else {
        eprintln!("usage: gltf-variants MODEL.glb|MODEL.gltf OUT_DIR");
        std::process::exit(2);
    };
    let model = std::path::Path::new(model);
    let flat = e2e_tests::conformance::read_flat(model);
    let stem = model.file_stem().unwrap_or_default().to_string_lossy();
    std::fs::create_dir_all(out).expect("cannot create the output folder");
    for &v in e2e_tests::conformance::VARIANTS {
        let (bytes, expect) = e2e_tests::conformance::write(&flat, v);
        let name = format!("{v:?}").replace([' ', '{', '}', ':'], "");
        let path = std::path::Path::new(out).join(format!("{stem}.{name}.glb"));
        std::fs::write(&path, bytes).expect("cannot write a variant");
        println!("{}\t{expect:?}", path.display());
    }
}
