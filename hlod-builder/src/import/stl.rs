//! STL (ASCII or binary) through `stl_io`: the facets welded into one
//! indexed mesh by exact position (what simplification needs; normals are
//! then computed, smooth across welded corners), one object named by the
//! file's stem. STL has no colours: the mesh is white.

use std::io::{BufReader, Read, Seek};
use std::path::Path;

use glam::DVec3;

use super::ImportError;
use super::meshfile::{Part, check_indices, invalid, open_file};

/// Reads the STL file at `path`.
pub fn read(path: &Path) -> Result<(Vec<Part>, Vec<String>), ImportError> {
    let (file, name) = open_file(path)?;
    read_from(&mut BufReader::with_capacity(1 << 20, file), name).map_err(invalid(path))
}

/// Reads an STL file from `source` as one part named `name`.
pub fn read_from(
    source: &mut (impl Read + Seek),
    name: String,
) -> Result<(Vec<Part>, Vec<String>), String> {
    let mesh = stl_io::read_stl(source)
        .map_err(|e| format!("STL: {e} (not a whole ASCII or binary STL file)"))?;
    if mesh.vertices.len() > u32::MAX as usize {
        return Err(format!(
            "STL: {} distinct vertices, at most 2^32",
            mesh.vertices.len()
        ));
    }
    let indices: Vec<u32> = (mesh.faces.iter())
        .flat_map(|f| f.vertices.map(|i| i as u32))
        .collect();
    check_indices(&indices, mesh.vertices.len(), "STL facet")?;
    let part = Part {
        name,
        positions: (mesh.vertices.iter())
            .map(|v| DVec3::from_array(v.0.map(f64::from)))
            .collect(),
        colour: [255; 4],
        indices,
        ..Part::default()
    };
    Ok((vec![part], Vec::new()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    const ASCII: &str = "solid two\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
        vertex 1 1 0\nendloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n\
        vertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid two\n";

    fn binary(tris: &[[[f32; 3]; 3]], claimed: u32) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend(claimed.to_le_bytes());
        for t in tris {
            b.extend([0u8; 12]);
            for v in t {
                for c in v {
                    b.extend(c.to_le_bytes());
                }
            }
            b.extend([0u8; 2]);
        }
        b
    }

    #[test]
    fn ascii_and_binary_weld_into_one_mesh() {
        let (parts, _) = read_from(&mut Cursor::new(ASCII), "a".into()).unwrap();
        assert_eq!(parts[0].positions.len(), 4, "the shared corners welded");
        assert_eq!(parts[0].indices.len(), 6);
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        ];
        let (parts, _) = read_from(&mut Cursor::new(binary(&tris, 2)), "b".into()).unwrap();
        assert_eq!(parts[0].positions.len(), 4);
        assert_eq!(parts[0].indices, [0, 1, 2, 0, 2, 3]);
    }

    #[test]
    fn a_truncated_binary_file_is_an_error() {
        let tris = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]];
        let e = read_from(&mut Cursor::new(binary(&tris, 5)), "b".into()).unwrap_err();
        assert!(e.starts_with("STL: "), "{e}");
        let e = read_from(&mut Cursor::new(&b"solid x\nfacet normal"[..]), "b".into());
        assert!(e.is_err());
    }
}
