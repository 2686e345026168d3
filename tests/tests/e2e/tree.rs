//! The model tree of real BIM files, from their scene's object section
//! only: the FZK-Haus opened from its IFC (site, building, storeys bottom
//! up, IFC types), the same house from its GLB (no storeys in the file:
//! IFC types), and the Schependomlaan, whose GLB groups its elements by
//! subcontractor file (the glTF node hierarchy).

use e2e_tests::data_dir;
use engine::tree::{Level, ModelTree};

/// The tree of `model` built into a scene, and its object count.
fn tree_of(model: &str) -> (ModelTree, engine::format::objects::ObjectTable) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.hlod");
    let params = hlod_builder::BuildParams {
        walk_cell: 0.0,
        ..Default::default()
    };
    hlod_builder::build_file(&data_dir().join(model), &out, &params, false).unwrap();
    let file = engine::SceneFile::open(&out).unwrap();
    let table = file.read_objects().unwrap();
    let drawn = engine::tree::drawn_objects(file.skeleton(), &table);
    let tree = ModelTree::new(&table, model, &drawn);
    tree.validate().unwrap();
    (tree, table)
}

fn children(t: &ModelTree, g: u32) -> Vec<(String, usize)> {
    t.groups()[g as usize]
        .children
        .iter()
        .map(|&c| (t.groups()[c as usize].label.clone(), t.objects(c).len()))
        .collect()
}

#[test]
fn an_ifc_house_is_site_building_storeys_bottom_up_then_types() {
    let (t, table) = tree_of("ifc/AC14-FZK-Haus.ifc");
    let top = children(&t, 0);
    assert_eq!(top.len(), 2, "{top:?}");
    assert_eq!(top[0].0, "Gelände");
    // Openings' voids (and spaces) are described but not drawn: one last
    // group says so.
    let out = t.groups()[0].children[1];
    assert_eq!(t.groups()[out as usize].level, Level::LeftOut);
    for &k in t.objects(out) {
        let info = table.info(k).unwrap();
        assert!(
            info.contains("IfcOpeningElement") || info.contains("IfcSpace"),
            "{info}"
        );
    }
    let site = t.groups()[0].children[0];
    // The terrain is the site itself: in no building.
    let buildings = children(&t, site);
    assert_eq!(buildings[0].0, "AC14-FZK-Haus", "{buildings:?}");
    let haus = t.groups()[site as usize].children[0];
    let storeys = children(&t, haus);
    let names: Vec<&str> = storeys.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["0. Erdgeschoss", "1. Dachgeschoss"], "{storeys:?}");
    assert!(storeys.iter().all(|(_, n)| *n > 20), "{storeys:?}");
    let eg = t.groups()[haus as usize].children[0];
    let types = children(&t, eg);
    assert!(
        types.iter().any(|(n, _)| n == "IfcDoor")
            && types.iter().any(|(n, _)| n.starts_with("IfcWall")),
        "{types:?}"
    );
    for &ty in &t.groups()[eg as usize].children {
        assert_eq!(t.groups()[ty as usize].level, Level::Type);
        // Every element of a type group is of that type.
        for &k in t.direct(ty) {
            let info = table.info(k).unwrap();
            assert!(
                info.contains(&format!("\"type\":\"{}\"", t.groups()[ty as usize].label)),
                "{info}"
            );
        }
    }
    // A ground-storey door found by a lower-case part of its GlobalId.
    let mut doors = t.groups()[eg as usize].children.iter().copied();
    let doors = doors
        .find(|&g| t.groups()[g as usize].label == "IfcDoor")
        .unwrap();
    let door = t.direct(doors)[0];
    let id = t.global_id(door).to_lowercase();
    assert_eq!(id.len(), 22);
    let found = t.search(&table, &id[3..15], 10);
    assert_eq!(found, [door]);
    assert!(t.ancestry(t.group_of(door)).contains(&eg));
    assert_eq!(t.objects(0).len(), table.len());
}

#[test]
fn glb_exports_group_by_type_or_by_their_node_hierarchy() {
    // IfcConvert's GLB of the same house: types from the names.
    let (t, table) = tree_of("AC14-FZK-Haus.glb");
    let top = children(&t, 0);
    let (types, out) = top.split_at(top.len() - 1);
    assert!(types.iter().all(|(n, _)| n.starts_with("Ifc")), "{top:?}");
    assert!(out[0].0.starts_with("left out"), "{top:?}");
    assert!(top.iter().any(|(n, _)| n == "IfcWindow"), "{top:?}");
    assert_eq!(t.objects(0).len(), table.len());
    // The Schependomlaan: one group per subcontractor's file.
    let (t, _) = tree_of("schependomlaan_subcontractors.glb");
    let top = children(&t, 0);
    assert!(top.len() >= 5, "{top:?}");
    assert!(
        top.iter().any(|(n, _)| n.contains("kalkzandsteen")),
        "{top:?}"
    );
    assert!(top.iter().all(|(_, n)| *n > 0));
    let first = t.groups()[0].children[0];
    assert_eq!(t.groups()[first as usize].level, Level::Group);
}
