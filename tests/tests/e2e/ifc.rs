//! IFC input through IfcOpenShell (`scripts/setup.sh` installs it in
//! `target/ifc-venv`): the FZK-Haus and the Duplex, opened from their IFC
//! files, against the GLB of the same files in `tests/data` (converted by
//! the same IfcOpenShell 0.9.0): the same objects by name, GlobalId and
//! class, the same triangles, the same box; every element's extras carry its
//! GlobalId, type and storey; openings and spaces left out as for the GLB.

use std::collections::BTreeSet;

use e2e_tests::data_dir;
use hlod_builder::import::{self, Imported};

use crate::conformance::world_box;

#[test]
fn ifc_files_open_with_the_objects_triangles_and_box_of_their_glb() {
    for stem in ["AC14-FZK-Haus", "Ifc2x3_Duplex_Architecture"] {
        let ifc = import::load(&data_dir().join(format!("ifc/{stem}.ifc")))
            .unwrap_or_else(|e| panic!("{stem}.ifc: {e}"));
        let glb = import::load(&data_dir().join(format!("{stem}.glb"))).unwrap();
        let names = |imp: &Imported| -> BTreeSet<String> {
            imp.instances.iter().map(|i| i.name.clone()).collect()
        };
        assert_eq!(names(&ifc), names(&glb), "{stem}: the same products");
        assert_eq!(ifc.instances.len(), glb.instances.len(), "{stem}");
        // Exact with the pinned IfcOpenShell; another version may
        // triangulate curved parts differently: 0.5% is the tolerance.
        let (a, b) = (
            ifc.instanced_source_triangles(),
            glb.instanced_source_triangles(),
        );
        assert!(
            a.abs_diff(b) * 200 <= b,
            "{stem}: {a} triangles from the IFC, {b} from the GLB"
        );
        assert_eq!(
            ifc.instanced_triangles(),
            glb.instanced_triangles(),
            "{stem}"
        );
        let (p, q) = (world_box(&ifc), world_box(&glb));
        assert!(
            (p.0 - q.0).abs().max_element() < 1e-3 && (p.1 - q.1).abs().max_element() < 1e-3,
            "{stem}: box {p:?}, the GLB's {q:?}"
        );
        // Element data: GlobalId, type and storey on every product's node.
        let mut storeys = 0;
        for inst in &ifc.instances {
            let node = inst.node.unwrap();
            let extras = ifc.node_extras[node].as_ref().unwrap();
            let guid = extras["GlobalId"].as_str().unwrap();
            let class = extras["type"].as_str().unwrap();
            assert!(
                inst.name.starts_with(&format!("{class}:")) && inst.name.ends_with(guid),
                "{stem}: {} against {extras}",
                inst.name
            );
            storeys += usize::from(extras.get("storey").is_some());
        }
        assert!(
            storeys * 10 >= ifc.instances.len() * 8,
            "{stem}: {storeys} of {} elements name their storey",
            ifc.instances.len()
        );
    }
}

#[test]
fn an_ifc_build_leaves_openings_and_spaces_out_as_for_a_bim_export() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("duplex.hlod");
    let stats = hlod_builder::build_file(
        &data_dir().join("ifc/Ifc2x3_Duplex_Architecture.ifc"),
        &out,
        &hlod_builder::BuildParams::default(),
        false,
    )
    .unwrap();
    assert_eq!(stats.objects, 286);
    assert_eq!(
        stats.hidden_triangles, 1392,
        "the Duplex's voids and spaces"
    );
    assert_eq!(stats.input_triangles, 27740);
}
