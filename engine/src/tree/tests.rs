use super::*;
use crate::format::SceneFile;
use crate::io::MemSource;
use crate::testutil::build_with;

/// An object section of these descriptions (over a small skeleton that
/// names none of them).
fn table(infos: &[String]) -> ObjectTable {
    let (bytes, _) = build_with(&[1], &[0], [0.0; 3], &ObjectTable::encode(&[], &[]));
    let file = SceneFile::from_source(MemSource::new(bytes)).unwrap();
    let mut s = file.skeleton().clone();
    s.nodes[0].object = crate::format::NONE;
    ObjectTable::decode(&ObjectTable::encode(infos, &[]), &s).unwrap()
}

/// An IfcOpenShell-style element of `storey` at `elev`.
fn ifc(class: &str, name: &str, id: &str, storey: &str, elev: f64) -> String {
    format!(
        r#"{{"name":"{class}:{name}:{id}","extras":{{"GlobalId":"{id}","type":"{class}","Name":"{name}","site":"Gelände","building":"Haus","storey":"{storey}","storey_elevation":{elev}}},"box_min":[0,{elev},0],"box_max":[1,{},1]}}"#,
        elev + 2.5
    )
}

fn labels(t: &ModelTree, g: u32) -> Vec<String> {
    t.groups()[g as usize]
        .children
        .iter()
        .map(|&c| t.groups()[c as usize].label.clone())
        .collect()
}

#[test]
fn ifc_elements_group_by_site_building_storey_and_type() {
    let infos = vec![
        ifc("IfcWall", "W-OG", "3rPX_Juz59peXXY6wDJl18", "1. OG", 2.7),
        ifc("IfcWall", "W-EG", "2O2Fr$t4X7Zf8NOew3FLOH", "0. EG", 0.0),
        ifc("IfcDoor", "Tür", "1srAI$R4T8ihLXSNHmUSET", "0. EG", 0.0),
        ifc("IfcWall", "W-EG2", "0ONCKt8ie0GYP_5u6XcWtK", "0. EG", 0.0),
        // Storeys sort by elevation, not by name.
        ifc("IfcSlab", "Keller", "33$Toku5SFE2CZorHL__a9", "Z-Keller", -2.5),
        // Contained in no storey.
        r#"{"name":"IfcSite:Gelände:1Qvf0xqDT4HXo8jI81mHB$","extras":{"type":"IfcSite","site":"Gelände"}}"#
            .to_string(),
    ];
    let t = ModelTree::new(&table(&infos), "haus", &[]);
    t.validate().unwrap();
    assert_eq!(labels(&t, 0), ["Gelände"]);
    let site = t.groups()[0].children[0];
    assert_eq!(labels(&t, site), ["Haus", "(no building)"]);
    let haus = t.groups()[site as usize].children[0];
    assert_eq!(labels(&t, haus), ["Z-Keller", "0. EG", "1. OG"]);
    let eg = t.groups()[haus as usize].children[1];
    assert_eq!(t.groups()[eg as usize].level, Level::Storey);
    assert_eq!(labels(&t, eg), ["IfcDoor", "IfcWall"]);
    let walls = t.groups()[eg as usize].children[1];
    // Elements by label within their type.
    let names: Vec<&str> = t.direct(walls).iter().map(|&k| t.label(k)).collect();
    assert_eq!(names, ["W-EG", "W-EG2"]);
    assert_eq!(t.objects(eg).len(), 3);
    assert_eq!(t.group_of(2), t.groups()[eg as usize].children[0]);
    assert_eq!(t.ancestry(walls), [walls, eg, haus, site, 0]);
    // The storey's box is its elements' boxes.
    assert_eq!(
        t.bounds_of(t.objects(eg)),
        Some(([0.0; 3], [1.0, 2.5, 1.0]))
    );
    assert_eq!(t.groups_named("0. eg "), [eg]);
    // A type: one group per storey, all of its elements.
    let ifc_walls = t.groups_named("ifcwall");
    assert_eq!(ifc_walls.len(), 2);
    assert_eq!(ifc_walls[0], walls);
    assert_eq!(t.objects_named("IfcWall"), [1, 3, 0]);
    assert!(t.groups_named("nothing").is_empty());
}

#[test]
fn search_finds_by_name_and_global_id_in_tree_order() {
    let infos = vec![
        ifc("IfcWall", "Wand-1", "3rPX_Juz59peXXY6wDJl18", "EG", 0.0),
        ifc("IfcDoor", "Tür", "1srAI$R4T8ihLXSNHmUSET", "EG", 0.0),
        ifc("IfcWall", "Wand-2", "2O2Fr$t4X7Zf8NOew3FLOH", "OG", 2.7),
    ];
    let tab = table(&infos);
    let t = ModelTree::new(&tab, "m", &[]);
    assert_eq!(t.search(&tab, "wand", 10), [0, 2]);
    assert_eq!(t.search(&tab, "1SRAI$", 10), [1]);
    assert_eq!(t.search(&tab, "ifcwall", 1), [0]);
    assert_eq!(t.search(&tab, "   ", 10), Vec::<u32>::new());
    assert_eq!(t.global_id(1), "1srAI$R4T8ihLXSNHmUSET");
}

#[test]
fn without_ifc_structure_the_node_hierarchy_groups() {
    let obj = |name: &str, parents: &[&str]| {
        let p: Vec<String> = parents.iter().map(|p| format!("\"{p}\"")).collect();
        format!(r#"{{"name":"{name}","parents":[{}]}}"#, p.join(","))
    };
    let infos = vec![
        obj("pump", &["root", "plant", "B"]),
        obj("pipe", &["root", "plant", "A", "A1"]),
        obj("valve", &["root", "plant", "A"]),
        obj("tank", &["root", "plant", "B"]),
    ];
    let t = ModelTree::new(&table(&infos), "plant.glb", &[]);
    t.validate().unwrap();
    // "root" and "plant" hold everything: left out.
    assert_eq!(labels(&t, 0), ["A", "B"]);
    let a = t.groups()[0].children[0];
    assert_eq!(labels(&t, a), ["A1"]);
    // A's own element after its subgroup.
    assert_eq!(t.direct(a), [2]);
    assert_eq!(t.objects(a), [1, 2]);
    let b = t.groups()[0].children[1];
    assert_eq!(t.groups()[b as usize].level, Level::Group);
    let names: Vec<&str> = t.direct(b).iter().map(|&k| t.label(k)).collect();
    assert_eq!(names, ["pump", "tank"]);
}

#[test]
fn ifc_names_without_spatial_structure_group_by_type() {
    // IfcConvert's glTF: types in the names, no storeys.
    let infos: Vec<String> = [
        "IfcWall:W1:3rPX_Juz59peXXY6wDJl18",
        "IfcWindow:F1:1srAI$R4T8ihLXSNHmUSET",
        "IfcWall:W2:2O2Fr$t4X7Zf8NOew3FLOH",
    ]
    .iter()
    .map(|n| format!(r#"{{"name":"{n}","parents":["file.ifc"]}}"#))
    .collect();
    let tab = table(&infos);
    let t = ModelTree::new(&tab, "m", &[]);
    t.validate().unwrap();
    assert_eq!(labels(&t, 0), ["IfcWall", "IfcWindow"]);
    assert_eq!(t.label(1), "F1");
    assert_eq!(t.global_id(2), "2O2Fr$t4X7Zf8NOew3FLOH");
}

#[test]
fn ops_hide_isolate_and_xray_slices_of_objects() {
    let infos: Vec<String> = (0..6).map(|k| format!(r#"{{"name":"o{k}"}}"#)).collect();
    let t = ModelTree::new(&table(&infos), "m", &[]);
    t.validate().unwrap();
    let mut looks = Vec::new();
    t.apply(&mut looks, &[1, 2], Op::Hide);
    use Look::*;
    assert_eq!(looks, [Shown, Hidden, Hidden, Shown, Shown, Shown]);
    t.apply(&mut looks, &[3], Op::XRay);
    assert_eq!(
        ModelTree::counts(t.objects(0), &looks),
        Counts {
            shown: 3,
            hidden: 2,
            xray: 1
        }
    );
    // X-ray the others: hidden ones stay hidden.
    t.apply(&mut looks, &[0], Op::XRayOthers);
    assert_eq!(looks, [Shown, Hidden, Hidden, XRay, XRay, XRay]);
    t.apply(&mut looks, &[4, 5], Op::Isolate);
    assert_eq!(looks, [Hidden, Hidden, Hidden, Hidden, Shown, Shown]);
    t.apply(&mut looks, t.objects(0), Op::Show);
    assert!(looks.iter().all(|l| *l == Shown));
}

#[test]
fn descriptions_that_are_not_json_describe_nothing_and_every_tree_validates() {
    let infos = vec![
        "not json".to_string(),
        String::new(),
        r#"{"name":7,"parents":[1,{"x":2}],"box_min":[1,2]}"#.to_string(),
    ];
    let t = ModelTree::new(&table(&infos), "m", &[]);
    t.validate().unwrap();
    assert_eq!(t.objects(0).len(), 3);
    assert_eq!(t.bounds_of(t.objects(0)), None);
    assert_eq!(Described::parse("[]"), Described::default());
    let empty = ModelTree::new(&table(&[]), "m", &[]);
    empty.validate().unwrap();
    assert!(empty.groups()[0].children.is_empty());
}

#[test]
fn what_the_build_left_out_is_one_last_group() {
    let infos = vec![
        ifc("IfcWall", "W", "3rPX_Juz59peXXY6wDJl18", "EG", 0.0),
        ifc("IfcOpeningElement", "", "2O2Fr$t4X7Zf8NOew3FLOH", "EG", 0.0),
        ifc("IfcSpace", "R1", "1srAI$R4T8ihLXSNHmUSET", "OG", 2.7),
    ];
    let t = ModelTree::new(&table(&infos), "m", &[true, false, false]);
    t.validate().unwrap();
    let top = labels(&t, 0);
    assert_eq!(top.len(), 2, "{top:?}");
    let out = *t.groups()[0].children.last().unwrap();
    assert_eq!(t.groups()[out as usize].level, Level::LeftOut);
    assert_eq!(t.objects(out), [1, 2]);
    // The storeys hold only what is drawn.
    assert_eq!(t.groups_named("OG"), Vec::<u32>::new());
}
