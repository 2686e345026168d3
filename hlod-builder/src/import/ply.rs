//! Stanford PLY (ASCII, binary little- and big-endian) through `ply-rs-bw`,
//! the maintained fork of `ply-rs`: element `vertex` (`x y z` of any scalar
//! type, read as `f64`; `nx ny nz`; `red green blue [alpha]` as bytes,
//! shorts or floats) and element `face` (`vertex_indices` or
//! `vertex_index`, polygons fanned into triangles). Other elements are
//! read past. The whole file is one object, named by its stem.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use glam::DVec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{Header, Property, PropertyAccess, PropertyAccessResult};

use super::ImportError;
use super::meshfile::{Part, check_indices, fan, invalid, open_file};

/// A vertex as read: position, normal and colour (channels in [0, 1]).
#[derive(Clone, Copy, Debug)]
struct Vertex {
    p: [f64; 3],
    n: [f32; 3],
    c: [f32; 4],
}

/// A scalar property as `f64`, and the scale that maps it to [0, 1] when it
/// is a colour channel.
fn scalar(p: &Property) -> Option<(f64, f64)> {
    Some(match *p {
        Property::Char(v) => (f64::from(v), 127.0),
        Property::UChar(v) => (f64::from(v), 255.0),
        Property::Short(v) => (f64::from(v), 32767.0),
        Property::UShort(v) => (f64::from(v), 65535.0),
        Property::Int(v) => (f64::from(v), f64::from(i32::MAX)),
        Property::UInt(v) => (f64::from(v), f64::from(u32::MAX)),
        Property::Float(v) => (f64::from(v), 1.0),
        Property::Double(v) => (v, 1.0),
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Self {
            p: [0.0; 3],
            n: [0.0; 3],
            c: [1.0; 4],
        }
    }

    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        let Some((v, unit)) = scalar(&p) else {
            return PropertyAccessResult::Ignored;
        };
        match name {
            "x" => self.p[0] = v,
            "y" => self.p[1] = v,
            "z" => self.p[2] = v,
            "nx" => self.n[0] = v as f32,
            "ny" => self.n[1] = v as f32,
            "nz" => self.n[2] = v as f32,
            _ => match colour_channel(name) {
                Some(k) => self.c[k] = (v / unit) as f32,
                None => return PropertyAccessResult::Ignored,
            },
        }
        PropertyAccessResult::Set
    }
}

/// Which colour channel a vertex property is (`red`, `diffuse_red`, …).
fn colour_channel(name: &str) -> Option<usize> {
    let name = name.strip_prefix("diffuse_").unwrap_or(name);
    ["red", "green", "blue", "alpha"]
        .iter()
        .position(|c| *c == name)
}

/// A face as read: its corners (`None` for a negative index).
#[derive(Debug, Default)]
struct Face {
    corners: Option<Vec<u32>>,
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        fn all<T: Copy>(v: &[T], f: impl Fn(T) -> Option<u32>) -> Option<Vec<u32>> {
            v.iter().map(|&x| f(x)).collect()
        }
        self.corners = match &p {
            Property::ListChar(v) => all(v, |x| u32::try_from(x).ok()),
            Property::ListUChar(v) => all(v, |x| Some(u32::from(x))),
            Property::ListShort(v) => all(v, |x| u32::try_from(x).ok()),
            Property::ListUShort(v) => all(v, |x| Some(u32::from(x))),
            Property::ListInt(v) => all(v, |x| u32::try_from(x).ok()),
            Property::ListUInt(v) => all(v, Some),
            _ => return PropertyAccessResult::UnsupportedType,
        };
        PropertyAccessResult::Set
    }
}

/// Any other element, read past.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// Reads the PLY file at `path`.
pub fn read(path: &Path) -> Result<(Vec<Part>, Vec<String>), ImportError> {
    let (file, name) = open_file(path)?;
    let len = file.metadata().map_or(u64::MAX, |m| m.len());
    read_from(BufReader::with_capacity(1 << 20, file), name, len).map_err(invalid(path))
}

/// Reads a PLY file of `len` bytes from `source` as one part named `name`;
/// errors name the element. An element count that `len` bytes cannot hold
/// is refused before anything is read for it.
pub fn read_from(
    mut source: impl BufRead,
    name: String,
    len: u64,
) -> Result<(Vec<Part>, Vec<String>), String> {
    let (head, mut warnings) = header_lines(&mut source)?;
    let mut reader = Reader::new(std::io::Cursor::new(head).chain(source));
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| format!("PLY header: {}", describe(&e)))?;
    let (mut vertices, mut faces) = (None, None);
    for (element, def) in &header.elements {
        fits(def, &header, len).map_err(|e| format!("PLY element {element}: {e}"))?;
        let what = |e: ply_rs_bw::parser::ParseError| {
            format!(
                "PLY element {element} ({} of them): {}",
                def.count,
                describe(&e)
            )
        };
        match element.as_str() {
            "vertex" if vertices.is_none() => {
                if def.count > u32::MAX as usize {
                    return Err(format!(
                        "PLY element vertex: {} vertices, at most 2^32",
                        def.count
                    ));
                }
                let v = Parser::<Vertex>::new().read_payload_for_element(&mut reader, def, &header);
                vertices = Some(v.map_err(what)?);
            }
            "face" if faces.is_none() => {
                let f = Parser::<Face>::new().read_payload_for_element(&mut reader, def, &header);
                faces = Some(f.map_err(what)?);
            }
            _ => {
                if vertices.is_some() && faces.is_some() {
                    break;
                }
                warnings.push(format!("PLY element {element}: not read"));
                Parser::<Skip>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(what)?;
            }
        }
    }
    let vertices = vertices.ok_or("PLY: no vertex element")?;
    let Some(faces) = faces else {
        return Err("PLY: no face element (a point cloud has no surface to build)".into());
    };
    let mut indices = Vec::with_capacity(faces.len() * 3);
    let mut bad = 0usize;
    for (k, f) in faces.iter().enumerate() {
        let corners = f
            .corners
            .as_ref()
            .ok_or_else(|| format!("PLY face {k}: a negative vertex index"))?;
        if !fan(corners, &mut indices) {
            bad += 1;
        }
    }
    if bad > 0 {
        warnings.push(format!("PLY: {bad} faces of fewer than 3 vertices skipped"));
    }
    check_indices(&indices, vertices.len(), "PLY triangle")?;
    let has = |names: &[&str]| declares(&header, names);
    let part = Part {
        name,
        positions: vertices.iter().map(|v| DVec3::from_array(v.p)).collect(),
        normals: if has(&["nx", "ny", "nz"]) {
            vertices.iter().map(|v| v.n).collect()
        } else {
            Vec::new()
        },
        colors: if has(&["red", "green", "blue"]) || has(&["diffuse_red"]) {
            vertices.iter().map(|v| v.c.map(to_u8)).collect()
        } else {
            Vec::new()
        },
        colour: [255; 4],
        indices,
    };
    Ok((vec![part], warnings))
}

/// Whether `def.count` elements can be in a file of `len` bytes: each
/// takes at least its scalars' and list counts' bytes in binary, a byte in
/// ASCII. (A header that claims a billion elements of a file of a few
/// hundred bytes would otherwise have the parser make them.)
fn fits(def: &ply_rs_bw::ply::ElementDef, header: &Header, len: u64) -> Result<(), String> {
    use ply_rs_bw::ply::{Encoding, PropertyType, ScalarType};
    let size = |t: &ScalarType| match t {
        ScalarType::Char | ScalarType::UChar => 1u64,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    };
    let each = match header.encoding {
        Encoding::Ascii => 1,
        _ => (def.properties.values())
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) | PropertyType::List(t, _) => size(t),
            })
            .sum::<u64>()
            .max(1),
    };
    let count = def.count as u64;
    if count.saturating_mul(each) > len {
        return Err(format!(
            "{count} of them cannot be in a file of {len} bytes (at least {each} B each)"
        ));
    }
    Ok(())
}

/// The words a PLY header line may start with.
const KEYWORDS: [&str; 7] = [
    "ply",
    "format",
    "comment",
    "element",
    "property",
    "obj_info",
    "end_header",
];

/// The header's lines up to `end_header` (at most 1 MiB), with a line that
/// starts with no keyword made a comment (old Blender exporters wrote a
/// bare "Created by …" line), said once.
fn header_lines(source: &mut impl BufRead) -> Result<(Vec<u8>, Vec<String>), String> {
    let (mut head, mut line, mut fixed) = (Vec::new(), Vec::new(), Vec::new());
    for n in 1.. {
        line.clear();
        let read = (source.take(1 << 20)).read_until(b'\n', &mut line);
        if read.map_err(|e| format!("PLY header: {e}"))? == 0 {
            break;
        }
        if head.len() + line.len() > 1 << 20 {
            return Err("PLY header: no end_header in its first MiB".into());
        }
        let text = String::from_utf8_lossy(&line);
        let word = text.split_whitespace().next().unwrap_or("");
        if n > 1 && !word.is_empty() && !KEYWORDS.contains(&word) {
            head.extend_from_slice(b"comment ");
            fixed.push(n);
        }
        head.extend_from_slice(&line);
        if word == "end_header" {
            break;
        }
    }
    let warnings = match fixed.first() {
        Some(first) => vec![format!(
            "PLY header: {} line(s) with no keyword read as comments, the first line {first}",
            fixed.len()
        )],
        None => Vec::new(),
    };
    Ok((head, warnings))
}

/// A parser error on one line: its message and the text it could not
/// parse, without the parser's internal detail.
fn describe(e: &ply_rs_bw::parser::ParseError) -> String {
    let text = e.to_string();
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("Error:"))
        .collect();
    parts.join(" ")
}

/// Whether the vertex element declares every property of `names`.
fn declares(header: &Header, names: &[&str]) -> bool {
    header
        .elements
        .get("vertex")
        .is_some_and(|e| names.iter().all(|n| e.properties.contains_key(*n)))
}

fn to_u8(c: f32) -> u8 {
    if c.is_finite() {
        (c.clamp(0.0, 1.0) * 255.0).round() as u8
    } else {
        255
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "ply\nformat ascii 1.0\ncomment a quad and a triangle\n\
        element vertex 5\nproperty float x\nproperty float y\nproperty double z\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element face 2\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 10 20 30\n0.5 2 0 0 0 0\n\
        4 0 1 2 3\n3 3 2 4\n";

    /// The same mesh in binary, with normals, in either byte order.
    fn binary(big: bool) -> Vec<u8> {
        let mut b = format!(
            "ply\nformat binary_{}_endian 1.0\nelement vertex 3\nproperty double x\n\
             property double y\nproperty double z\nproperty float nx\nproperty float ny\n\
             property float nz\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n\
             element face 1\nproperty list uchar uint vertex_index\nend_header\n",
            if big { "big" } else { "little" }
        )
        .into_bytes();
        let f64b = |v: f64| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let f32b = |v: f32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let u32b = |v: u32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            for c in p {
                b.extend(f64b(c));
            }
            for c in [0.0, 0.0, 1.0] {
                b.extend(f32b(c));
            }
        }
        b.extend(u32b(0));
        b.extend(u32b(1));
        b.push(3);
        for i in [0, 1, 2] {
            b.extend(u32b(i));
        }
        b
    }

    #[test]
    fn ascii_and_binary_of_both_byte_orders() {
        let (parts, w) = read_from(ASCII.as_bytes(), "q".into(), 1 << 20).unwrap();
        assert!(w.is_empty(), "{w:?}");
        let p = &parts[0];
        assert_eq!(p.indices, [0, 1, 2, 0, 2, 3, 3, 2, 4]);
        assert_eq!(p.colors[0], [255, 0, 0, 255]);
        assert_eq!(p.colors[3], [10, 20, 30, 255]);
        assert!(p.normals.is_empty());
        for big in [false, true] {
            let (parts, w) = read_from(&binary(big)[..], "b".into(), 1 << 20).unwrap();
            assert_eq!(w, ["PLY element edge: not read"]);
            assert_eq!(parts[0].indices, [0, 1, 2]);
            assert_eq!(parts[0].positions[1], DVec3::X);
            assert_eq!(parts[0].normals[2], [0.0, 0.0, 1.0]);
            assert!(parts[0].colors.is_empty());
        }
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        let cut = &binary(false)[..binary(false).len() - 5];
        let e = read_from(cut, "b".into(), cut.len() as u64).unwrap_err();
        assert!(e.starts_with("PLY element face"), "{e}");
        let e = read_from(
            &b"ply\nformat ascii 1.0\nelement vertex x\n"[..],
            "b".into(),
            40,
        );
        assert!(e.unwrap_err().starts_with("PLY header"));
        let e = read_from(
            ASCII.replace("3 3 2 4", "3 3 2 9").as_bytes(),
            "b".into(),
            1 << 20,
        );
        assert_eq!(
            e.unwrap_err(),
            "PLY triangle 2: vertex index 9 out of range of 5 vertices"
        );
        let e = read_from(
            ASCII.replace("3 3 2 4", "3 3 2 -1").as_bytes(),
            "b".into(),
            1 << 20,
        );
        assert_eq!(e.unwrap_err(), "PLY face 1: a negative vertex index");
        let points = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
        // A count the file cannot hold: refused before it is read.
        let huge = ASCII.replace("element vertex 5", "element vertex 777777777");
        let e = read_from(huge.as_bytes(), "b".into(), huge.len() as u64).unwrap_err();
        assert!(
            e.starts_with("PLY element vertex: 777777777 of them cannot be in a file"),
            "{e}"
        );
        let e = read_from(points.as_bytes(), "b".into(), 1 << 20).unwrap_err();
        assert!(e.contains("point cloud"), "{e}");
        let e = read_from(&b"solid x\nendsolid\n"[..], "b".into(), 20).unwrap_err();
        assert!(e.starts_with("PLY header"), "{e}");
        // A header line with no keyword (old Blender exports) is a comment.
        let blender = ASCII.replace("comment a quad", "Created by Blender 2.47: a quad");
        let (parts, w) = read_from(blender.as_bytes(), "q".into(), 1 << 20).unwrap();
        assert_eq!(parts[0].indices.len(), 9);
        assert_eq!(
            w,
            ["PLY header: 1 line(s) with no keyword read as comments, the first line 3"]
        );
    }
}
