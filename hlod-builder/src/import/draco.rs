//! `KHR_draco_mesh_compression`: a primitive's triangles and attributes
//! decoded from its Draco buffer view by the reference Draco decoder
//! (libdraco, through [`super::draco_ffi`]), what Cesium ion,
//! gltf-transform's web presets and many BIM exporters write.
//!
//! The extension names a buffer view holding one Draco stream and maps
//! glTF attribute names to the stream's attribute unique ids; attributes
//! it does not map are read from their accessors as usual. The accessors
//! of compressed attributes keep their `normalized` flag, which says how
//! the decoded integers are read (colours as normalized bytes, for
//! instance). The decoder dequantises positions and normals itself.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde_json::Value;

use super::access::{self, Buffers, F32, I8, I16, U8, U16, U32};
use super::doc::Primitive;
use super::draco_ffi::{self as ffi, DracoMesh, Shape};

pub const EXTENSION: &str = "KHR_draco_mesh_compression";

/// The extension object of a primitive.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
struct Ext {
    buffer_view: Option<usize>,
    attributes: BTreeMap<String, u64>,
}

/// A primitive's geometry as the Draco stream holds it, one entry per
/// point; attributes the extension does not map are `None`.
#[derive(Debug, Default)]
pub struct Decoded {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    /// RGBA, as the accessor's type and `normalized` flag read them.
    pub colors: Option<Vec<[f32; 4]>>,
    pub indices: Vec<u32>,
}

/// Whether the primitive's geometry is Draco-compressed.
pub fn is_compressed(prim: &Primitive) -> bool {
    prim.extensions.contains_key(EXTENSION)
}

/// Decodes the primitive's Draco stream. Errors name the buffer view and
/// what in the stream is wrong; the caller adds the primitive.
pub fn decode(bufs: &Buffers, prim: &Primitive) -> Result<Decoded, String> {
    let raw = prim.extensions.get(EXTENSION).unwrap_or(&Value::Null);
    let ext: Ext =
        serde_json::from_value(raw.clone()).map_err(|e| format!("extensions.{EXTENSION}: {e}"))?;
    let v = ext
        .buffer_view
        .ok_or_else(|| format!("extensions.{EXTENSION}: no bufferView"))?;
    let bytes = bufs
        .view(v, 0, None)
        .map_err(|e| format!("extensions.{EXTENSION}: {e}"))?;
    let at = format!(
        "extensions.{EXTENSION} (bufferViews[{v}], {} bytes)",
        bytes.len()
    );
    let mesh = DracoMesh::decode(&bytes).map_err(|e| format!("{at}: Draco stream: {e}"))?;
    let points = mesh.num_points();
    // How the accessor reads an integer attribute (normalized or not).
    let normalized = |name: &str| {
        prim.attributes
            .get(name)
            .and_then(|&a| bufs.doc.accessors.get(a))
            .is_some_and(|a| a.normalized)
    };
    let read = |name: &str, dims: &[usize]| -> Result<Option<Vec<[f32; 4]>>, String> {
        let Some(&uid) = ext.attributes.get(name) else {
            return Ok(None);
        };
        let uid = u32::try_from(uid).unwrap_or(u32::MAX);
        let shape = mesh.attribute(uid).ok_or_else(|| {
            format!("{at}: attributes.{name} is unique id {uid}, which the stream does not have")
        })?;
        values(&mesh, uid, shape, dims, normalized(name))
            .map(Some)
            .map_err(|e| format!("{at}: attributes.{name}: {e}"))
    };
    let xyz = |v: Vec<[f32; 4]>| v.into_iter().map(|[x, y, z, _]| [x, y, z]).collect();
    let Some(positions) = read("POSITION", &[3])? else {
        return Err(format!(
            "{at}: POSITION is not among the compressed attributes"
        ));
    };
    let normals = read("NORMAL", &[3])?.map(xyz);
    let colors = read("COLOR_0", &[3, 4])?;
    let indices = mesh.faces().map_err(|e| format!("{at}: {e}"))?;
    if let Some(&i) = indices.iter().find(|&&i| i as usize >= points) {
        return Err(format!("{at}: a face names point {i} of {points}"));
    }
    Ok(Decoded {
        positions: xyz(positions),
        normals,
        colors,
        indices,
    })
}

/// glTF's component type for a Draco data type (64-bit, `INT32` and `BOOL`
/// have none).
fn gltf_type(t: i32) -> Option<u32> {
    Some(match t {
        ffi::DT_INT8 => I8,
        ffi::DT_UINT8 => U8,
        ffi::DT_INT16 => I16,
        ffi::DT_UINT16 => U16,
        ffi::DT_UINT32 => U32,
        ffi::DT_FLOAT32 => F32,
        _ => return None,
    })
}

/// Each point's value of an attribute with one of `dims` components as up
/// to four floats (the rest 1), integers read as the glTF accessor says.
fn values(
    mesh: &DracoMesh,
    uid: u32,
    shape: Shape,
    dims: &[usize],
    normalized: bool,
) -> Result<Vec<[f32; 4]>, String> {
    let n = shape.components;
    if !dims.contains(&n) {
        return Err(format!("{n} components, {dims:?} expected"));
    }
    let t = gltf_type(shape.data_type)
        .filter(|&t| access::component_size(t) == Some(shape.component_bytes as u64))
        .ok_or_else(|| format!("Draco data type {} is not one glTF reads", shape.data_type))?;
    let raw = mesh.values(uid, shape)?;
    let size = shape.component_bytes;
    Ok(raw
        .chunks_exact(n * size)
        .map(|v| {
            std::array::from_fn(|c| {
                if c < n {
                    access::component_f32(t, normalized, &v[c * size..(c + 1) * size])
                } else {
                    1.0
                }
            })
        })
        .collect())
}
