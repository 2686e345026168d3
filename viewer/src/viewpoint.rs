//! BCF 2.1 viewpoints (`.bcfv`, buildingSMART's `visinfo.xsd`): the camera,
//! the clipping planes and the components selected or hidden, as BIM tools
//! exchange them.
//!
//! BCF coordinates are the project's world coordinates, Z up, in metres. A
//! scene is glTF's Y up, stored relative to its origin (the header's
//! survey position): BCF `(x, y, z)` is glTF world `(x, z, −y)`, and scene
//! coordinates are glTF world minus the origin — the mapping IfcOpenShell
//! uses when it writes glTF, and the one `export-3dtiles` inverts.
//! A clipping plane's `Direction` points into the half-space it removes
//! ([`engine::section`] takes planes the same way).

use std::fmt::Write as _;

use anyhow::{Context, Result, bail};
use engine::camera::Pose;
use engine::section::Section;
use glam::{DVec3, Mat3, Quat, Vec3};

/// What a viewpoint holds, in scene coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    pub pose: Pose,
    pub section: Section,
    /// GlobalIds of the components selected.
    pub selected: Vec<String>,
    /// Whether components are visible unless listed in `exceptions`.
    pub default_visible: bool,
    /// GlobalIds whose visibility is the opposite of `default_visible`.
    pub exceptions: Vec<String>,
}

type Node<'a, 'i> = roxmltree::Node<'a, 'i>;

/// The first child element of `n` named `name`.
fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
}

/// The finite number in `n`'s child `name`.
fn number(n: Node<'_, '_>, name: &str) -> Result<f64> {
    let t = child(n, name)
        .and_then(|c| c.text())
        .with_context(|| format!("<{}> has no <{name}>", n.tag_name().name()))?;
    t.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .with_context(|| format!("<{}><{name}> {t:?} is not a number", n.tag_name().name()))
}

/// The `X`, `Y`, `Z` of `n`'s child `name`.
fn vector(n: Node<'_, '_>, name: &str) -> Result<DVec3> {
    let v = child(n, name).with_context(|| format!("<{}> has no <{name}>", n.tag_name().name()))?;
    Ok(DVec3::new(
        number(v, "X")?,
        number(v, "Y")?,
        number(v, "Z")?,
    ))
}

/// BCF (Z up) to glTF world (Y up).
fn from_bcf(v: DVec3) -> DVec3 {
    DVec3::new(v.x, v.z, -v.y)
}

/// glTF world (Y up) to BCF (Z up).
fn to_bcf(v: DVec3) -> DVec3 {
    DVec3::new(v.x, -v.z, v.y)
}

fn is_global_id(s: &str) -> bool {
    s.len() == 22
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'$')
}

impl Viewpoint {
    /// Reads a `.bcfv` document; `origin` is the scene's.
    pub fn parse(xml: &str, origin: [f64; 3]) -> Result<Self> {
        let doc = roxmltree::Document::parse(xml).context("not an XML document")?;
        let root = doc.root_element();
        if root.tag_name().name() != "VisualizationInfo" {
            bail!(
                "the root element is <{}>, not <VisualizationInfo>",
                root.tag_name().name()
            );
        }
        let o = DVec3::from(origin);
        let cam = child(root, "PerspectiveCamera").with_context(|| {
            if child(root, "OrthogonalCamera").is_some() {
                "an orthogonal camera: only perspective cameras are supported"
            } else {
                "no <PerspectiveCamera>"
            }
        })?;
        let eye = from_bcf(vector(cam, "CameraViewPoint")?) - o;
        let dir = from_bcf(vector(cam, "CameraDirection")?).as_vec3();
        let up = from_bcf(vector(cam, "CameraUpVector")?).as_vec3();
        let fov = number(cam, "FieldOfView")?;
        if !(fov > 0.5 && fov < 179.0) {
            bail!("<FieldOfView> {fov}: expected degrees in (0.5, 179)");
        }
        let rotation = look_rotation(dir, up).context("<CameraDirection> and <CameraUpVector>")?;
        let pose = Pose {
            position: eye.as_vec3(),
            rotation,
            fov_y_deg: fov as f32,
        };
        let mut planes = Vec::new();
        if let Some(cp) = child(root, "ClippingPlanes") {
            for p in cp
                .children()
                .filter(|c| c.is_element() && c.tag_name().name() == "ClippingPlane")
            {
                let at = from_bcf(vector(p, "Location")?) - o;
                let d = from_bcf(vector(p, "Direction")?);
                planes.push((at.as_vec3(), d.as_vec3()));
            }
        }
        let section = Section::from_planes(&planes).context("<ClippingPlanes>")?;
        let ids = |n: Option<Node<'_, '_>>| -> Vec<String> {
            n.into_iter()
                .flat_map(|n| n.children())
                .filter(|c| c.is_element() && c.tag_name().name() == "Component")
                .filter_map(|c| c.attribute("IfcGuid").map(str::to_string))
                .collect()
        };
        let comps = child(root, "Components");
        let selected = ids(comps.and_then(|c| child(c, "Selection")));
        let vis = comps.and_then(|c| child(c, "Visibility"));
        let default_visible = vis
            .and_then(|v| v.attribute("DefaultVisibility"))
            .is_none_or(|a| a.trim() != "false");
        let exceptions = ids(vis.and_then(|v| child(v, "Exceptions")));
        Ok(Self {
            pose,
            section,
            selected,
            default_visible,
            exceptions,
        })
    }

    /// Writes the viewpoint as a `.bcfv` document. Its `Guid` is derived
    /// from the content, so the same viewpoint is the same file.
    pub fn to_xml(&self, origin: [f64; 3]) -> String {
        let o = DVec3::from(origin);
        let mut body = String::new();
        let xyz = |out: &mut String, tag: &str, v: DVec3| {
            let _ = write!(
                out,
                "<{tag}><X>{:.6}</X><Y>{:.6}</Y><Z>{:.6}</Z></{tag}>",
                v.x, v.y, v.z
            );
        };
        let ids: Vec<&String> = self.selected.iter().filter(|s| is_global_id(s)).collect();
        let hidden: Vec<&String> = self.exceptions.iter().filter(|s| is_global_id(s)).collect();
        body.push_str("  <Components>\n");
        if !ids.is_empty() {
            body.push_str("    <Selection>\n");
            for id in &ids {
                let _ = writeln!(body, "      <Component IfcGuid=\"{id}\"/>");
            }
            body.push_str("    </Selection>\n");
        }
        let _ = write!(
            body,
            "    <Visibility DefaultVisibility=\"{}\"",
            self.default_visible
        );
        if hidden.is_empty() {
            body.push_str("/>\n");
        } else {
            body.push_str(">\n      <Exceptions>\n");
            for id in &hidden {
                let _ = writeln!(body, "        <Component IfcGuid=\"{id}\"/>");
            }
            body.push_str("      </Exceptions>\n    </Visibility>\n");
        }
        body.push_str("  </Components>\n  <PerspectiveCamera>\n    ");
        let p = &self.pose;
        xyz(
            &mut body,
            "CameraViewPoint",
            to_bcf(p.position.as_dvec3() + o),
        );
        body.push_str("\n    ");
        xyz(&mut body, "CameraDirection", to_bcf(p.forward().as_dvec3()));
        body.push_str("\n    ");
        xyz(
            &mut body,
            "CameraUpVector",
            to_bcf((p.rotation * Vec3::Y).as_dvec3()),
        );
        let _ = write!(
            body,
            "\n    <FieldOfView>{:.4}</FieldOfView>\n  </PerspectiveCamera>\n",
            p.fov_y_deg
        );
        if !self.section.is_empty() {
            body.push_str("  <ClippingPlanes>\n");
            for (at, dir) in self.section.as_location_direction() {
                body.push_str("    <ClippingPlane>");
                xyz(&mut body, "Location", to_bcf(at.as_dvec3() + o));
                xyz(&mut body, "Direction", to_bcf(dir.as_dvec3()));
                body.push_str("</ClippingPlane>\n");
            }
            body.push_str("  </ClippingPlanes>\n");
        }
        let h = blake3::hash(body.as_bytes()).to_hex();
        let g = &h.as_str()[..32];
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<VisualizationInfo Guid=\"{}-{}-{}-{}-{}\">\n{body}</VisualizationInfo>\n",
            &g[..8],
            &g[8..12],
            &g[12..16],
            &g[16..20],
            &g[20..32]
        )
    }
}

/// The camera-to-world rotation of a camera looking along `dir` with `up`
/// (orthogonalised) as its screen's up.
fn look_rotation(dir: Vec3, up: Vec3) -> Result<Quat> {
    let f = dir
        .try_normalize()
        .context("the direction is the zero vector")?;
    let right = f
        .cross(up)
        .try_normalize()
        .or_else(|| f.cross(Vec3::Y).try_normalize())
        .or_else(|| f.cross(Vec3::X).try_normalize())
        .context("no up direction")?;
    let u = right.cross(f);
    Ok(Quat::from_mat3(&Mat3::from_cols(right, u, -f)).normalize())
}

#[cfg(test)]
mod tests;
