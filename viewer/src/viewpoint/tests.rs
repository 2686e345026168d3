use super::*;

/// Written by hand in the layout of the BCF 2.1 test case
/// "Visualization/ClippingPlanes" (schema namespace, empty `Selection`,
/// `Exceptions` and `Coloring`, `ViewSetupHints`, no `Guid`), with values
/// of our own: a camera at (20, -25, 15) looking down towards the model, a
/// horizontal plane at z = 6 removing what lies above, and a vertical
/// plane at x = 12 removing what lies east of it.
const HAND_WRITTEN: &str = r#"<?xml version="1.0" encoding="UTF-8" standalone="yes"?>
<VisualizationInfo xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="visinfo.xsd">
  <Components>
    <ViewSetupHints SpacesVisible="false" SpaceBoundariesVisible="false" OpeningsVisible="false"/>
    <Selection/>
    <Visibility DefaultVisibility="true">
      <Exceptions/>
    </Visibility>
    <Coloring/>
  </Components>
  <PerspectiveCamera>
    <CameraViewPoint><X>20.0</X><Y>-25.0</Y><Z>15.0</Z></CameraViewPoint>
    <CameraDirection><X>-0.5</X><Y>0.6</Y><Z>-0.6244998</Z></CameraDirection>
    <CameraUpVector><X>-0.4</X><Y>0.48</Y><Z>0.78</Z></CameraUpVector>
    <FieldOfView>55.0</FieldOfView>
  </PerspectiveCamera>
  <ClippingPlanes>
    <ClippingPlane>
      <Location><X>0.0</X><Y>0.0</Y><Z>6.0</Z></Location>
      <Direction><X>0.0</X><Y>0.0</Y><Z>1.0</Z></Direction>
    </ClippingPlane>
    <ClippingPlane>
      <Location><X>12.0</X><Y>-1.0</Y><Z>0.0</Z></Location>
      <Direction><X>1.0</X><Y>0.0</Y><Z>0.0</Z></Direction>
    </ClippingPlane>
  </ClippingPlanes>
</VisualizationInfo>
"#;

/// A BCF (Z up) point in scene coordinates (Y up) for `origin`.
fn scene(bcf: [f64; 3], origin: [f64; 3]) -> Vec3 {
    (from_bcf(DVec3::from(bcf)) - DVec3::from(origin)).as_vec3()
}

#[test]
fn a_hand_written_viewpoint_reads_as_bcf_means_it() {
    let origin = [1000.0, 5.0, -2000.0];
    let v = Viewpoint::parse(HAND_WRITTEN, origin).unwrap();
    let eye = scene([20.0, -25.0, 15.0], origin);
    assert!(
        (v.pose.position - eye).length() < 1e-3,
        "{}",
        v.pose.position
    );
    // Looking down (BCF z < 0 is scene y < 0) and up is up.
    let f = v.pose.forward();
    let want = from_bcf(DVec3::new(-0.5, 0.6, -0.6244998))
        .as_vec3()
        .normalize();
    assert!(f.dot(want) > 0.9999, "{f} {want}");
    assert!((v.pose.rotation * Vec3::Y).y > 0.7);
    assert_eq!(v.pose.fov_y_deg, 55.0);
    // Below z = 6 and west of x = 12: kept; above or east: cut away.
    assert_eq!(v.section.planes().len(), 2);
    assert!(v.section.keeps(scene([5.0, 3.0, 2.0], origin)));
    assert!(!v.section.keeps(scene([5.0, 3.0, 6.5], origin)));
    assert!(!v.section.keeps(scene([12.5, 3.0, 2.0], origin)));
    assert!(v.selected.is_empty() && v.exceptions.is_empty() && v.default_visible);
}

#[test]
fn a_viewpoint_round_trips_and_is_deterministic() {
    let origin = [-3.5, 100.0, 42.0];
    let pose = Pose::look_at(Vec3::new(4.0, 1.6, -7.0), Vec3::new(0.0, 1.0, 0.0), 48.0);
    let section = Section::boxed(Vec3::new(-5.0, 0.0, -6.0), Vec3::new(5.0, 3.0, 6.0)).unwrap();
    let v = Viewpoint {
        pose,
        section,
        selected: vec!["2O2Fr$t4X7Zf8NOew3FLOH".into()],
        default_visible: true,
        exceptions: vec!["1hOSvn6df7F8_7GcBWlRGQ".into()],
    };
    let xml = v.to_xml(origin);
    assert_eq!(xml, v.to_xml(origin), "the same viewpoint, the same file");
    let back = Viewpoint::parse(&xml, origin).unwrap();
    assert!((back.pose.position - pose.position).length() < 1e-4);
    assert!(back.pose.forward().dot(pose.forward()) > 0.99999);
    assert!((back.pose.rotation * Vec3::Y).dot(pose.rotation * Vec3::Y) > 0.99999);
    assert!((back.pose.fov_y_deg - 48.0).abs() < 1e-3);
    for (a, b) in back.section.planes().iter().zip(section.planes()) {
        assert!((*a - *b).abs().max_element() < 1e-4, "{a} {b}");
    }
    assert_eq!(back.selected, v.selected);
    assert_eq!(back.exceptions, v.exceptions);
    // Other tools read it: the schema's element order, a GUID, BCF's Z up.
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let root = doc.root_element();
    let guid = root.attribute("Guid").unwrap();
    assert_eq!(guid.len(), 36);
    let order: Vec<&str> = root
        .children()
        .filter(|c| c.is_element())
        .map(|c| c.tag_name().name())
        .collect();
    assert_eq!(order, ["Components", "PerspectiveCamera", "ClippingPlanes"]);
    // The box's top (scene y = 3) is BCF z = 3 + origin's y.
    assert!(xml.contains("<Z>103.000000</Z>"), "{xml}");
}

#[test]
fn bad_viewpoints_say_what_is_wrong() {
    let err = |xml: &str| format!("{:#}", Viewpoint::parse(xml, [0.0; 3]).unwrap_err());
    assert!(err("not xml <").contains("not an XML document"));
    assert!(err("<Markup/>").contains("<Markup>"));
    assert!(err("<VisualizationInfo/>").contains("no <PerspectiveCamera>"));
    let ortho = HAND_WRITTEN.replace("PerspectiveCamera", "OrthogonalCamera");
    assert!(err(&ortho).contains("orthogonal"));
    let nan = HAND_WRITTEN.replace("<X>20.0</X>", "<X>NaN</X>");
    assert!(err(&nan).contains("is not a number"), "{}", err(&nan));
    let fov = HAND_WRITTEN.replace("55.0", "0");
    assert!(err(&fov).contains("FieldOfView"));
    let flat = HAND_WRITTEN.replace(
        "<X>1.0</X><Y>0.0</Y><Z>0.0</Z></Direction>",
        "<X>0</X><Y>0</Y><Z>0</Z></Direction>",
    );
    assert!(err(&flat).contains("zero vector"), "{}", err(&flat));
    let no_dir = HAND_WRITTEN.replace(
        "<CameraDirection><X>-0.5</X><Y>0.6</Y><Z>-0.6244998</Z></CameraDirection>",
        "",
    );
    assert!(err(&no_dir).contains("<CameraDirection>"));
}
