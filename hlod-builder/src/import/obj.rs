//! Wavefront OBJ through `tobj` (positions in `f64`, polygons fanned into
//! triangles, points and lines skipped): each model `tobj` makes (a group
//! or object, split where its material changes) is one object, named by
//! its group. Colours are the material's diffuse `Kd` (alpha from `d`)
//! times the vertex colours where the file has them. Material libraries
//! are read from the model's folder only (as glTF buffers are); one that
//! cannot be read leaves its materials white, with a warning.

use std::cell::RefCell;
use std::io::BufRead;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::ImportError;
use super::meshfile::{Part, check_indices, invalid, open_file};

/// Reads the OBJ file at `path` (and the material libraries it names).
pub fn read(path: &Path) -> Result<(Vec<Part>, Vec<String>), ImportError> {
    let (file, _) = open_file(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let reader = std::io::BufReader::with_capacity(1 << 20, file);
    read_from(reader, base).map_err(invalid(path))
}

/// Reads an OBJ file from `source`, its material libraries from `base`.
pub fn read_from(source: impl BufRead, base: &Path) -> Result<(Vec<Part>, Vec<String>), String> {
    let (text, prepared) = prepare(source)?;
    let warnings = RefCell::new(prepared);
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let loaded = tobj::load_obj_buf(&mut &text[..], &options, |name| {
        load_mtl(name, base).unwrap_or_else(|why| {
            warnings.borrow_mut().push(why);
            Err(tobj::LoadError::OpenFileFailed)
        })
    });
    let (models, materials) = loaded.map_err(|e| {
        // tobj says what went wrong, not where: find the line.
        let what = format!("OBJ: {e}");
        match locate(&String::from_utf8_lossy(&text), &what) {
            Some(n) => format!("{what} (line {n})"),
            None => what,
        }
    })?;
    let mut warnings = warnings.into_inner();
    let materials = materials.unwrap_or_else(|e| {
        if warnings.is_empty() {
            warnings.push(format!("OBJ materials: {e}; drawn white"));
        }
        Vec::new()
    });
    let mut parts = Vec::with_capacity(models.len());
    for model in models {
        let m = model.mesh;
        let n = m.positions.len() / 3;
        if n > u32::MAX as usize {
            return Err(format!("OBJ {}: {n} vertices, at most 2^32", model.name));
        }
        check_indices(&m.indices, n, &format!("OBJ {} triangle", model.name))?;
        let kd = m
            .material_id
            .and_then(|k| materials.get(k))
            .map_or([1.0; 4], |mat| {
                let [r, g, b] = mat.diffuse.unwrap_or([1.0; 3]);
                [r, g, b, mat.dissolve.unwrap_or(1.0)]
            });
        let colors = if m.vertex_color.len() == m.positions.len() {
            (m.vertex_color.chunks_exact(3))
                .map(|c| [c[0] * kd[0], c[1] * kd[1], c[2] * kd[2], kd[3]].map(to_u8))
                .collect()
        } else {
            Vec::new()
        };
        parts.push(Part {
            name: model.name,
            positions: (m.positions.chunks_exact(3))
                .map(|p| DVec3::new(p[0], p[1], p[2]))
                .collect(),
            normals: if m.normals.len() == m.positions.len() {
                (m.normals.chunks_exact(3))
                    .map(|v| [v[0] as f32, v[1] as f32, v[2] as f32])
                    .collect()
            } else {
                Vec::new()
            },
            colors,
            colour: kd.map(to_u8),
            indices: m.indices,
        });
    }
    Ok((parts, warnings))
}

/// The OBJ text for `tobj`, checked line by line first: every face
/// corner's vertex and normal index within the vertices and normals before
/// it (`tobj` 4.0.5 overflows on a relative index past the start). Left
/// out, as blank lines so that line numbers hold: texture coordinates (not
/// drawn) and a `usemtl` without a name (`tobj` refuses the file). A line
/// that is not UTF-8 (a Latin-1 name) is read with its bad bytes replaced;
/// both are said once, with the first line.
fn prepare(mut source: impl BufRead) -> Result<(Vec<u8>, Vec<String>), String> {
    let mut out = Vec::new();
    let (mut vertices, mut normals) = (0u64, 0u64);
    let mut line = Vec::new();
    let (mut not_utf8, mut unnamed) = (Vec::new(), Vec::new());
    for n in 1.. {
        line.clear();
        if source
            .read_until(b'\n', &mut line)
            .map_err(|e| format!("OBJ: {e}"))?
            == 0
        {
            break;
        }
        if n == 1 && (line.starts_with(b"\xFE\xFF") || line.starts_with(b"\xFF\xFE")) {
            return Err("OBJ: the file is UTF-16 text (save it as UTF-8)".into());
        }
        if std::str::from_utf8(&line).is_err() {
            not_utf8.push(n);
            line = String::from_utf8_lossy(&line).into_owned().into_bytes();
        }
        let text = String::from_utf8_lossy(&line).into_owned();
        let mut tokens = text.split_whitespace();
        let first = tokens.next();
        if first == Some("usemtl") && tokens.clone().next().is_none() {
            unnamed.push(n);
        }
        match first {
            Some("vt") => {
                out.push(b'\n');
                continue;
            }
            Some("usemtl") if unnamed.last() == Some(&n) => {
                out.push(b'\n');
                continue;
            }
            Some("v") => vertices += 1,
            Some("vn") => normals += 1,
            Some("f") => {
                for corner in tokens {
                    check_corner(corner, vertices, normals)
                        .map_err(|e| format!("OBJ: line {n}: {e}"))?;
                }
            }
            _ => {}
        }
        out.extend_from_slice(&line);
        if !line.ends_with(b"\n") {
            out.push(b'\n');
        }
    }
    let mut warnings = Vec::new();
    let said = |lines: &[usize], what: &str| {
        format!(
            "OBJ: {} line(s) {what}, the first line {}",
            lines.len(),
            lines[0]
        )
    };
    if !not_utf8.is_empty() {
        warnings.push(said(
            &not_utf8,
            "not UTF-8 text, read with the bad bytes replaced",
        ));
    }
    if !unnamed.is_empty() {
        warnings.push(said(&unnamed, "`usemtl` without a name, ignored"));
    }
    Ok((out, warnings))
}

/// A face corner `v[/vt[/vn]]` against the `vertices` and `normals`
/// defined so far (1-based, or negative: counted back from the last).
fn check_corner(corner: &str, vertices: u64, normals: u64) -> Result<(), String> {
    let mut parts = corner.split('/');
    let check = |s: Option<&str>, count: u64, what: &str| -> Result<(), String> {
        let Some(s) = s.filter(|s| !s.is_empty()) else {
            return Ok(());
        };
        let i: i64 = s
            .parse()
            .map_err(|_| format!("{what} index {s:?} is not a number"))?;
        if i != 0 && i.unsigned_abs() <= count {
            Ok(())
        } else {
            Err(format!(
                "{what} index {i} out of range of the {count} {what} entries before it"
            ))
        }
    };
    check(parts.next(), vertices, "vertex")?;
    parts.next(); // texture coordinates: not read
    check(parts.next(), normals, "normal")
}

/// One material library, named by `name` in the OBJ file: read from the
/// model's folder only.
fn load_mtl(name: &Path, base: &Path) -> Result<tobj::MTLLoadResult, String> {
    let shown = name.to_string_lossy();
    let file: PathBuf = super::files::resolve_in("mtllib", &shown, &shown, base)
        .map_err(|e| format!("OBJ {e}; its materials drawn white"))?;
    let f = engine::infile::open(&file)
        .map_err(|e| format!("OBJ mtllib {shown:?}: {e}; its materials drawn white"))?;
    Ok(tobj::load_mtl_buf(&mut std::io::BufReader::new(f)))
}

fn to_u8(c: f64) -> u8 {
    if c.is_finite() {
        (c.clamp(0.0, 1.0) * 255.0).round() as u8
    } else {
        255
    }
}

/// The first line of `text` that makes the error `what` (tobj's message),
/// where it can be told: a `v`, `vn` or `vt` line whose numbers do not
/// parse, or an `f` line whose corners do not.
fn locate(text: &str, what: &str) -> Option<usize> {
    let prefix = if what.contains("material") {
        "usemtl"
    } else if what.contains("position") {
        "v"
    } else if what.contains("normal") {
        "vn"
    } else if what.contains("texture") || what.contains("texcoord") {
        "vt"
    } else if what.contains("face") || what.contains("polygon") {
        "f"
    } else {
        return None;
    };
    let number = |t: &str| {
        if prefix == "usemtl" {
            true
        } else if prefix == "f" {
            t.split('/')
                .next()
                .is_some_and(|i| i.parse::<i64>().is_ok_and(|i| i != 0))
        } else {
            t.parse::<f64>().is_ok()
        }
    };
    text.lines()
        .position(|l| {
            let mut t = l.split_whitespace();
            t.next() == Some(prefix) && {
                let rest: Vec<&str> = t.collect();
                rest.is_empty() || !rest.iter().all(|x| number(x))
            }
        })
        .map(|k| k + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    const OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 3 0 0\nv 4 0 0\n\
        v 4 1 0\ng red_box\nusemtl red\nf 1 2 3 4\ng plain\nusemtl none\nf 5 6 3\nl 1 2\n";
    const MTL: &str = "newmtl red\nKd 1 0 0\nd 0.5\n";

    #[test]
    fn groups_are_objects_coloured_by_their_materials() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("m.mtl"), MTL).unwrap();
        let (parts, w) = read_from(OBJ.as_bytes(), dir.path()).unwrap();
        assert!(w.is_empty(), "{w:?}");
        let names: Vec<&str> = parts.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["red_box", "plain"]);
        assert_eq!(parts[0].indices.len(), 6, "the quad fanned");
        assert_eq!(parts[0].colour, [255, 0, 0, 128]);
        assert_eq!(parts[1].colour, [255; 4], "an unknown material is white");
    }

    #[test]
    fn a_library_outside_the_folder_is_not_read_and_bad_lines_are_found() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("model");
        std::fs::create_dir(&sub).unwrap();
        std::fs::write(dir.path().join("m.mtl"), MTL).unwrap();
        let obj = OBJ.replace("mtllib m.mtl", "mtllib ../m.mtl");
        let (parts, w) = read_from(obj.as_bytes(), &sub).unwrap();
        assert_eq!(parts[0].colour, [255; 4]);
        assert!(w[0].contains("outside the model's folder"), "{w:?}");
        let bad = OBJ.replace("v 1 1 0", "v 1 x 0");
        let e = read_from(bad.as_bytes(), dir.path()).unwrap_err();
        assert!(e.starts_with("OBJ: "), "{e}");
        assert_eq!(locate(&bad, &e), Some(4), "{e}");
        let oob = OBJ.replace("f 5 6 3", "f 5 6 99");
        let e = read_from(oob.as_bytes(), dir.path()).unwrap_err();
        assert_eq!(
            e,
            "OBJ: line 14: vertex index 99 out of range of the 7 vertex entries before it"
        );
        // A relative index past the start (tobj 4.0.5 overflowed on it).
        let rel = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1/-3/-2 2//1 3//1\n";
        let e = read_from(rel.as_bytes(), dir.path()).unwrap_err();
        assert_eq!(
            e,
            "OBJ: line 6: normal index -2 out of range of the 1 normal entries before it"
        );
        // Latin-1 text and a bare `usemtl` are read, and said.
        let mut latin = rel.replace("1/-3/-2", "1//1").into_bytes();
        latin.extend_from_slice(b"g caf\xe9\nusemtl\n");
        let (_, w) = read_from(&latin[..], dir.path()).unwrap();
        assert!(
            w[0].contains("not UTF-8 text") && w[0].contains("line 7"),
            "{w:?}"
        );
        assert!(
            w[1].contains("`usemtl` without a name") && w[1].contains("line 8"),
            "{w:?}"
        );
        let ok = rel.replace("1/-3/-2", "-3/1/-1");
        let (parts, _) = read_from(ok.as_bytes(), dir.path()).unwrap();
        assert_eq!(parts[0].indices.len(), 3);
        assert_eq!(parts[0].normals.len(), 3, "the file's normals kept");
    }
}
