//! Models that are not glTF: PLY scans ([`super::ply`]), OBJ exports
//! ([`super::obj`]) and STL ([`super::stl`]), each read by a well-kept crate
//! into [`Part`]s (one object each) and assembled here into the same
//! [`Opened`] scene as a glTF's: positions read in `f64` and stored relative
//! to an origin (survey coordinates keep millimetres), degenerate triangles
//! dropped and said, normals computed where the file has none.

use std::path::Path;

use glam::{DVec3, Mat4};

use super::lazy::Opened;
use super::{ImportError, Imported, Instance, MeshMeta};
use crate::mesh::Mesh;

/// The kinds of model the importer reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// glTF 2.0, `.glb` or `.gltf`.
    Gltf,
    /// Stanford PLY, ASCII or binary of either endianness.
    Ply,
    /// Wavefront OBJ, with its MTL material libraries.
    Obj,
    /// STL, ASCII or binary.
    Stl,
    /// IFC (STEP), converted by IfcOpenShell ([`super::ifc`]).
    Ifc,
}

impl Format {
    /// The format a path's extension names (case-insensitive), `None` for
    /// an extension that names none of them.
    pub fn of_extension(path: &Path) -> Option<Format> {
        let e = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match e.as_str() {
            "glb" | "gltf" => Format::Gltf,
            "ply" => Format::Ply,
            "obj" => Format::Obj,
            "stl" => Format::Stl,
            "ifc" => Format::Ifc,
            _ => return None,
        })
    }

    /// How a model at `path` is read: by its extension, glTF otherwise
    /// (whose reader says what it found if it is not glTF either).
    pub fn of(path: &Path) -> Format {
        Self::of_extension(path).unwrap_or(Format::Gltf)
    }

    pub fn name(self) -> &'static str {
        match self {
            Format::Gltf => "glTF",
            Format::Ply => "PLY",
            Format::Obj => "OBJ",
            Format::Stl => "STL",
            Format::Ifc => "IFC",
        }
    }
}

/// One object of a mesh file, as read.
#[derive(Debug, Default)]
pub struct Part {
    pub name: String,
    pub positions: Vec<DVec3>,
    /// One per position, or empty (computed).
    pub normals: Vec<[f32; 3]>,
    /// One per position, or empty (`colour` for all).
    pub colors: Vec<[u8; 4]>,
    /// The colour of vertices without their own (a material's).
    pub colour: [u8; 4],
    /// Triangles, three indices each, checked against `positions`.
    pub indices: Vec<u32>,
}

/// Reads `path` as `format` (not glTF) into a scene.
pub fn open(path: &Path, format: Format) -> Result<Opened, ImportError> {
    let (parts, mut warnings) = match format {
        Format::Ply => super::ply::read(path),
        Format::Obj => super::obj::read(path),
        Format::Stl => super::stl::read(path),
        Format::Gltf | Format::Ifc => unreachable!("glTF and IFC are read by import::lazy"),
    }?;
    let assembled = assemble(parts, &mut warnings);
    if assembled.instances.is_empty() {
        return Err(ImportError::NoTriangles {
            path: path.to_path_buf(),
            why: if warnings.is_empty() {
                format!("the {} file has no faces", format.name())
            } else {
                warnings.join("; ")
            },
        });
    }
    let (mut scene, meshes) = assembled.split();
    scene.warnings = warnings;
    Ok(Opened::in_memory(scene, meshes, path))
}

/// Reads a PLY, OBJ or STL file's bytes (an OBJ's material libraries from
/// `base`) and assembles them, as [`open`] does: the triangles usable (the
/// fuzz target's entry, `tests/fuzz/fuzz_targets/mesh_import.rs`).
pub fn parse_bytes(bytes: &[u8], format: Format, base: &Path) -> Result<u64, String> {
    let (parts, mut warnings) = match format {
        Format::Ply => super::ply::read_from(bytes, "mesh".into(), bytes.len() as u64),
        Format::Obj => super::obj::read_from(bytes, base),
        Format::Stl => super::stl::read_from(&mut std::io::Cursor::new(bytes), "mesh".into()),
        Format::Gltf => return Err("glTF bytes are read by import::load_slice".into()),
        Format::Ifc => return Err("IFC is read by IfcOpenShell, from a file".into()),
    }?;
    let a = assemble(parts, &mut warnings);
    Ok(a.scene.meta.iter().flatten().map(|m| m.tris as u64).sum())
}

/// The scene and its meshes, apart.
struct Assembled {
    scene: Imported,
    meshes: Vec<Option<Mesh>>,
    instances: Vec<Instance>,
}

impl Assembled {
    fn split(self) -> (Imported, Vec<Option<Mesh>>) {
        let mut scene = self.scene;
        scene.instances = self.instances;
        (scene, self.meshes)
    }
}

/// Parts as meshes relative to one origin, one object each.
fn assemble(parts: Vec<Part>, warnings: &mut Vec<String>) -> Assembled {
    let (lo, hi) = parts.iter().flat_map(|p| &p.positions).fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let extent = lo.abs().max(hi.abs()).max_element();
    let origin = if !extent.is_finite() || extent <= super::ORIGIN_FREE_EXTENT {
        DVec3::ZERO
    } else {
        ((lo + hi) * 0.5).round()
    };
    let mut scene = Imported {
        origin: origin.to_array(),
        ..Imported::default()
    };
    let mut meshes = Vec::new();
    let mut instances = Vec::new();
    for part in parts {
        let m = meshes.len();
        let source = (part.indices.len() / 3) as u64;
        let mut mesh = Mesh {
            positions: (part.positions.iter())
                .map(|&p| (p - origin).as_vec3().to_array())
                .collect(),
            normals: part.normals,
            colors: if part.colors.is_empty() {
                vec![part.colour; part.positions.len()]
            } else {
                part.colors
            },
            indices: part.indices,
        };
        if mesh.normals.len() != mesh.positions.len() {
            mesh.compute_normals();
        }
        let dropped = mesh.remove_degenerate();
        if dropped > 0 {
            warnings.push(format!(
                "{}: {dropped} degenerate triangles dropped",
                part.name
            ));
        }
        scene.source_tris.push(source);
        scene.mesh_info.push((Some(part.name.clone()), None));
        if mesh.tri_count() == 0 {
            warnings.push(format!("{}: no usable triangles, skipped", part.name));
            scene.meta.push(None);
            meshes.push(None);
            continue;
        }
        scene.meta.push(Some(MeshMeta::of(&mesh)));
        meshes.push(Some(mesh));
        instances.push(Instance {
            mesh: m,
            transform: Mat4::IDENTITY,
            name: part.name,
            node: None,
            instance: None,
            parents: std::sync::Arc::from([]),
        });
    }
    Assembled {
        scene,
        meshes,
        instances,
    }
}

/// A mesh file opened under the input policy, and the name of the object
/// it makes when it makes one (its stem).
pub fn open_file(path: &Path) -> Result<(std::fs::File, String), ImportError> {
    let file = engine::infile::open(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let name = path
        .file_stem()
        .map_or_else(|| "mesh".into(), |s| s.to_string_lossy().into_owned());
    Ok((file, name))
}

/// A reader's message as the error naming `path`.
pub fn invalid(path: &Path) -> impl Fn(String) -> ImportError + '_ {
    move |what| ImportError::Invalid {
        path: path.to_path_buf(),
        what,
    }
}

/// Checks every index against `vertices`, naming the first face out of
/// range (`what` names the element, e.g. "face").
pub fn check_indices(indices: &[u32], vertices: usize, what: &str) -> Result<(), String> {
    match indices.iter().position(|&i| i as usize >= vertices) {
        None => Ok(()),
        Some(k) => Err(format!(
            "{what} {}: vertex index {} out of range of {vertices} vertices",
            k / 3,
            indices[k]
        )),
    }
}

/// A polygon's corners as triangles (a fan, as glTF's TRIANGLE_FAN and
/// every OBJ/PLY reader do); `false` for fewer than three corners.
pub fn fan(corners: &[u32], out: &mut Vec<u32>) -> bool {
    if corners.len() < 3 {
        return false;
    }
    for k in 1..corners.len() - 1 {
        out.extend_from_slice(&[corners[0], corners[k], corners[k + 1]]);
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn survey_coordinates_keep_millimetres_and_small_ones_keep_the_origin() {
        let part = |at: f64| Part {
            name: "p".into(),
            positions: vec![
                DVec3::new(at, at, 0.0),
                DVec3::new(at + 1.0, at, 0.0),
                DVec3::new(at, at + 0.001, 0.0),
            ],
            colour: [255; 4],
            indices: vec![0, 1, 2],
            ..Part::default()
        };
        let mut w = Vec::new();
        let (s, meshes) = assemble(vec![part(10.0)], &mut w).split();
        assert_eq!(s.origin, [0.0; 3]);
        assert_eq!(meshes[0].as_ref().unwrap().positions[0], [10.0, 10.0, 0.0]);
        let (s, meshes) = assemble(vec![part(3.5e6)], &mut w).split();
        assert!(s.origin[0] > 3.4e6);
        let m = meshes[0].as_ref().unwrap();
        let dy = f64::from(m.positions[2][1]) - f64::from(m.positions[0][1]);
        assert!((dy - 0.001).abs() < 1e-5, "{dy}");
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(s.instances.len(), 1);
    }

    #[test]
    fn fans_and_indices() {
        let mut out = Vec::new();
        assert!(fan(&[0, 1, 2, 3], &mut out));
        assert_eq!(out, [0, 1, 2, 0, 2, 3]);
        assert!(!fan(&[0, 1], &mut out));
        assert!(check_indices(&[0, 1, 2], 3, "face").is_ok());
        let e = check_indices(&[0, 1, 2, 0, 1, 7], 3, "face").unwrap_err();
        assert_eq!(e, "face 1: vertex index 7 out of range of 3 vertices");
        assert_eq!(Format::of(Path::new("a/B.PLY")), Format::Ply);
        assert_eq!(Format::of(Path::new("x.stl")), Format::Stl);
        assert_eq!(Format::of(Path::new("x.bin")), Format::Gltf);
        assert_eq!(Format::of_extension(Path::new("x.bin")), None);
    }
}
