//! A glTF mesh's primitives read and merged into one [`Mesh`], each vertex
//! coloured by its material's base colour (times `COLOR_0`).

use super::access::{self, Buffers, F32, I8, I16, U8, U16, U32};
use super::draco;
use crate::mesh::Mesh;

/// Triangle topologies (points and lines are skipped).
const TRIANGLES: u32 = 4;
const STRIP: u32 = 5;
const FAN: u32 = 6;

/// All primitives of mesh `m` merged, with the triangle count read
/// (degenerate ones included) and the offset [`recentre`] took off its
/// positions. Structural errors (an accessor out of its buffer) fail the
/// file; a part that cannot be drawn is a warning.
pub fn read_mesh(
    bufs: &Buffers,
    m: usize,
    warnings: &mut Vec<String>,
) -> Result<(Option<Mesh>, u64, [f32; 3]), String> {
    let doc = bufs.doc;
    let mut out = Mesh::default();
    let mut source = 0u64;
    for (p, prim) in doc.meshes[m].primitives.iter().enumerate() {
        let what = format!("meshes[{m}].primitives[{p}]");
        let Some(&pos) = prim.attributes.get("POSITION") else {
            warnings.push(format!("{what}: no POSITION, skipped"));
            continue;
        };
        if !matches!(prim.mode, TRIANGLES | STRIP | FAN) {
            let name = match prim.mode {
                0 => "POINTS",
                1 => "LINES",
                2 => "LINE_LOOP",
                3 => "LINE_STRIP",
                _ => "unknown",
            };
            warnings.push(format!(
                "{what}: mode {} ({name}) is not triangles, skipped",
                prim.mode
            ));
            continue;
        }
        let draco = if draco::is_compressed(prim) {
            let named = match &doc.meshes[m].name {
                Some(n) => format!("{what} (mesh {n:?})"),
                None => what.clone(),
            };
            Some(draco::decode(bufs, prim).map_err(|e| format!("{named}: {e}"))?)
        } else {
            check_position_type(bufs, pos, &what, warnings);
            None
        };
        let (positions, draco_normals, draco_colors, raw, mode) = match draco {
            Some(d) => (d.positions, d.normals, d.colors, Some(d.indices), TRIANGLES),
            None => {
                let p = access::read_f32::<3>(bufs, pos)
                    .map_err(|e| format!("{what}.attributes.POSITION: {e}"))?;
                (p, None, None, None, prim.mode)
            }
        };
        if positions.iter().flatten().any(|c| !c.is_finite()) {
            warnings.push(format!("{what}: non-finite positions, skipped"));
            continue;
        }
        let normals = match draco_normals {
            Some(n) => Some(n),
            None => read_normals(
                bufs,
                prim.attributes.get("NORMAL").copied(),
                &what,
                warnings,
            )?,
        }
        .filter(|n| n.len() == positions.len() && n.iter().flatten().all(|c| c.is_finite()));
        let raw = match (raw, prim.indices) {
            (Some(r), _) => r,
            (None, Some(a)) => {
                access::read_indices(bufs, a).map_err(|e| format!("{what}.indices: {e}"))?
            }
            (None, None) => (0..positions.len() as u32).collect(),
        };
        if let Some(&bad) = raw.iter().find(|&&i| i as usize >= positions.len()) {
            warnings.push(format!(
                "{what}: index {bad} out of range of {} vertices, skipped",
                positions.len()
            ));
            continue;
        }
        let indices = triangulate(mode, &raw);
        let material = prim.material.and_then(|i| doc.materials.get(i));
        let base = material.map_or([1.0; 4], |mat| mat.base_color());
        let mut colors = match (draco_colors, prim.attributes.get("COLOR_0")) {
            (Some(rgba), _) => tint(rgba, base),
            (None, Some(&a)) => read_colors(bufs, a, base, positions.len())
                .map_err(|e| format!("{what}.attributes.COLOR_0: {e}"))?,
            (None, None) => vec![to_rgba8(base); positions.len()],
        };
        // The alpha mode decides what the alpha means (opaque without one).
        if let Some(m) = material {
            for c in &mut colors {
                c[3] = (m.alpha(f64::from(c[3]) / 255.0) * 255.0).round() as u8;
            }
        } else {
            colors.iter_mut().for_each(|c| c[3] = u8::MAX);
        }
        let mut part = Mesh {
            colors,
            normals: normals.clone().unwrap_or_default(),
            positions,
            indices,
        };
        if normals.is_none() {
            part.compute_normals();
        }
        source += part.tri_count() as u64;
        let dropped = part.remove_degenerate();
        if dropped > 0 {
            warnings.push(format!("{what}: {dropped} degenerate triangles dropped"));
        }
        out.append(&part);
    }
    if out.tri_count() == 0 {
        warnings.push(format!(
            "meshes[{m}]: no usable triangles, its instances skipped"
        ));
        return Ok((None, source, [0.0; 3]));
    }
    let offset = recentre(&mut out);
    Ok((Some(out), source, offset))
}

/// Moves a mesh that lies far from its own origin (its centre farther than
/// it is large: quantized positions under a scale and a translation that
/// cancels them, survey coordinates) to its centre, and returns the offset
/// taken off, which the placement adds back in `f64`. In `f32` the
/// placement's large translation and large products would cancel and
/// lose the millimetres; near the centre they do not. Other meshes are
/// left as they are (offset zero).
pub fn recentre(mesh: &mut Mesh) -> [f32; 3] {
    let b = mesh.bounds_of_all();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let centre = (lo + hi) * 0.5;
    if centre.abs().max_element() <= (hi - lo).max_element() {
        return [0.0; 3];
    }
    let c = centre.as_vec3().to_array();
    for p in &mut mesh.positions {
        for k in 0..3 {
            p[k] -= c[k];
        }
    }
    c
}

/// POSITION's component type against glTF 2.0 and `KHR_mesh_quantization`:
/// FLOAT, or (with the extension in `extensionsUsed`) BYTE, UNSIGNED_BYTE,
/// SHORT or UNSIGNED_SHORT, normalized or not; `normalized` is never valid
/// on FLOAT or UNSIGNED_INT. A file that breaks this is warned about,
/// naming the primitive and the accessor, and read as its type says (the
/// geometry is kept: these files come from exporters that mean them).
fn check_position_type(bufs: &Buffers, a: usize, what: &str, warnings: &mut Vec<String>) {
    let Some(acc) = bufs.doc.accessors.get(a) else {
        return; // the read reports it
    };
    let t = acc.component_type;
    let name = access::component_name(t);
    let problem = match t {
        F32 if acc.normalized => Some(format!(
            "is a normalized {name}, which glTF 2.0 does not allow (normalized is for 8- and \
             16-bit integers); read as plain floats"
        )),
        U32 => Some(format!(
            "has {name} components, which no glTF 2.0 POSITION may have{}; read as {}",
            if acc.normalized {
                " (nor normalized)"
            } else {
                ""
            },
            if acc.normalized {
                "integers scaled to [0, 1]"
            } else {
                "integers"
            }
        )),
        I8 | U8 | I16 | U16
            if !bufs
                .doc
                .extensions_used
                .iter()
                .any(|e| e == "KHR_mesh_quantization") =>
        {
            Some(format!(
                "has {name} components without KHR_mesh_quantization in extensionsUsed; read as \
                 that extension says"
            ))
        }
        _ => None,
    };
    // Said once a file for each kind of problem (an exporter repeats it in
    // every primitive), naming the first part that has it.
    if let Some(p) = problem
        && !warnings.iter().any(|w| w.ends_with(&p))
    {
        warnings.push(format!("{what}.attributes.POSITION: accessors[{a}] {p}"));
    }
}

/// NORMAL as float or normalized signed integers (`KHR_mesh_quantization`);
/// another type is a warning, and the normals are recomputed.
fn read_normals(
    bufs: &Buffers,
    acc: Option<usize>,
    what: &str,
    warnings: &mut Vec<String>,
) -> Result<Option<Vec<[f32; 3]>>, String> {
    let Some(a) = acc else { return Ok(None) };
    let (t, dims) =
        access::shape(bufs.doc, a).map_err(|e| format!("{what}.attributes.NORMAL: {e}"))?;
    let normalized = bufs.doc.accessors[a].normalized;
    if dims != Some(3) || !(t == F32 || (matches!(t, I8 | I16) && normalized)) {
        warnings.push(format!(
            "{what}.attributes.NORMAL: accessors[{a}] is not float or normalized signed VEC3, normals recomputed"
        ));
        return Ok(None);
    }
    access::read_f32::<3>(bufs, a)
        .map(Some)
        .map_err(|e| format!("{what}.attributes.NORMAL: {e}"))
}

fn to_rgba8(c: [f64; 4]) -> [u8; 4] {
    c.map(|x| {
        let x = if x.is_finite() {
            x.clamp(0.0, 1.0)
        } else {
            1.0
        };
        (x * 255.0).round() as u8
    })
}

/// `COLOR_0` (VEC3 or VEC4; float or normalized unsigned) times the base colour.
fn read_colors(bufs: &Buffers, a: usize, base: [f64; 4], n: usize) -> Result<Vec<[u8; 4]>, String> {
    let (t, dims) = access::shape(bufs.doc, a)?;
    let normalized = bufs.doc.accessors[a].normalized;
    if !(t == F32 || (matches!(t, U8 | U16) && normalized)) {
        return Err(format!(
            "accessors[{a}] is not float or normalized unsigned"
        ));
    }
    let rgba: Vec<[f32; 4]> = match dims {
        Some(3) => access::read_f32::<3>(bufs, a)?
            .into_iter()
            .map(|[r, g, b]| [r, g, b, 1.0])
            .collect(),
        Some(4) => access::read_f32::<4>(bufs, a)?,
        _ => return Err(format!("accessors[{a}] is not VEC3 or VEC4")),
    };
    if rgba.len() != n {
        return Err(format!("{} colours for {n} vertices", rgba.len()));
    }
    Ok(tint(rgba, base))
}

/// Vertex colours times the material's base colour, as bytes.
fn tint(rgba: Vec<[f32; 4]>, base: [f64; 4]) -> Vec<[u8; 4]> {
    rgba.into_iter()
        .map(|c| to_rgba8(std::array::from_fn(|k| base[k] * f64::from(c[k]))))
        .collect()
}

fn triangulate(mode: u32, idx: &[u32]) -> Vec<u32> {
    match mode {
        STRIP => (2..idx.len())
            .flat_map(|i| {
                if i % 2 == 0 {
                    [idx[i - 2], idx[i - 1], idx[i]]
                } else {
                    [idx[i - 1], idx[i - 2], idx[i]]
                }
            })
            .collect(),
        FAN => (2..idx.len())
            .flat_map(|i| [idx[0], idx[i - 1], idx[i]])
            .collect(),
        _ => idx[..idx.len() - idx.len() % 3].to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use base64::Engine as _;
    use serde_json::json;

    /// The alpha of the one triangle placed for each material.
    fn alphas(materials: serde_json::Value) -> Vec<u8> {
        let n = materials.as_array().map_or(0, Vec::len);
        let pos: Vec<u8> = [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&pos)
        );
        let doc = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": 36, "uri": uri}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
            "materials": materials,
            "meshes": (0..n).map(|m| json!({"primitives": [{"attributes": {"POSITION": 0}, "material": m}]})).collect::<Vec<_>>(),
            "nodes": (0..n).map(|m| json!({"mesh": m})).collect::<Vec<_>>(),
            "scenes": [{"nodes": (0..n).collect::<Vec<_>>()}],
            "scene": 0,
        });
        let bytes = serde_json::to_vec(&doc).unwrap();
        let p = std::path::Path::new("alpha.gltf");
        let imp = crate::import::load_slice(&bytes, std::path::Path::new("."), p).unwrap();
        imp.meshes
            .iter()
            .map(|m| m.as_ref().unwrap().colors[0][3])
            .collect()
    }

    #[test]
    fn the_alpha_mode_decides_what_a_colours_alpha_means() {
        let pbr = |a: f64| json!({"baseColorFactor": [0.5, 0.5, 0.5, a]});
        let got = alphas(json!([
            {"pbrMetallicRoughness": pbr(0.3)},
            {"pbrMetallicRoughness": pbr(0.3), "alphaMode": "OPAQUE"},
            {"pbrMetallicRoughness": pbr(0.3), "alphaMode": "BLEND"},
            {"pbrMetallicRoughness": pbr(0.3), "alphaMode": "MASK"},
            {"pbrMetallicRoughness": pbr(0.7), "alphaMode": "MASK"},
            {"pbrMetallicRoughness": pbr(0.3), "alphaMode": "MASK", "alphaCutoff": 0.2},
        ]));
        // Opaque unless blended; masked to 0 or 1 by the cutoff.
        assert_eq!(got, [255, 255, 77, 0, 255, 255]);
    }
}
