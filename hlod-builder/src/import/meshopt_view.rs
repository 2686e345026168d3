//! `EXT_meshopt_compression` (and its `KHR_` successor): a buffer view's
//! bytes decoded with the `meshopt` crate's decoders and filters.

use super::doc::Meshopt;

/// Largest `byteStride` the extension allows.
const MAX_STRIDE: u64 = 256;

/// One vertex of `N` bytes, the element type the vertex decoder fills.
#[derive(Clone, Copy)]
struct Elem<const N: usize>([u8; N]);

impl<const N: usize> Default for Elem<N> {
    fn default() -> Self {
        Self([0; N])
    }
}

fn vertices<const N: usize>(src: &[u8], count: usize) -> Result<Vec<u8>, String> {
    let v = meshopt::decode_vertex_buffer::<Elem<N>>(src, count).map_err(|e| e.to_string())?;
    Ok(v.into_iter().flat_map(|e| e.0).collect())
}

macro_rules! by_stride {
    ($stride:expr, $src:expr, $count:expr; $($n:literal)*) => {
        match $stride {
            $($n => vertices::<$n>($src, $count),)*
            s => Err(format!("byteStride {s} is not a multiple of 4 up to {MAX_STRIDE}")),
        }
    };
}

/// The decompressed bytes of the view that `m` describes, from its
/// compressed bytes `src`: `count * byteStride` bytes.
pub fn decode(m: &Meshopt, src: &[u8]) -> Result<Vec<u8>, String> {
    let out_len = m
        .count
        .checked_mul(m.byte_stride)
        .filter(|&n| n <= crate::import::max_input_bytes())
        .ok_or_else(|| {
            format!(
                "count {} x byteStride {} is too large",
                m.count, m.byte_stride
            )
        })?;
    let count = m.count as usize;
    let stride = m.byte_stride;
    let mut bytes = match m.mode.as_str() {
        "ATTRIBUTES" => {
            if stride == 0 || stride > MAX_STRIDE || !stride.is_multiple_of(4) {
                return Err(format!(
                    "byteStride {stride} is not a multiple of 4 up to {MAX_STRIDE}"
                ));
            }
            by_stride!(stride, src, count;
                4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64
                68 72 76 80 84 88 92 96 100 104 108 112 116 120 124 128
                132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192
                196 200 204 208 212 216 220 224 228 232 236 240 244 248 252 256)?
        }
        "TRIANGLES" | "INDICES" => {
            let tri = m.mode == "TRIANGLES";
            if tri && !count.is_multiple_of(3) {
                return Err(format!(
                    "TRIANGLES mode with count {count}, not a multiple of 3"
                ));
            }
            match stride {
                2 => {
                    let v: Vec<u16> = if tri {
                        meshopt::decode_index_buffer(src, count)
                    } else {
                        meshopt::decode_index_sequence(src, count)
                    }
                    .map_err(|e| e.to_string())?;
                    v.into_iter().flat_map(u16::to_le_bytes).collect()
                }
                4 => {
                    let v: Vec<u32> = if tri {
                        meshopt::decode_index_buffer(src, count)
                    } else {
                        meshopt::decode_index_sequence(src, count)
                    }
                    .map_err(|e| e.to_string())?;
                    v.into_iter().flat_map(u32::to_le_bytes).collect()
                }
                s => {
                    return Err(format!(
                        "{} mode with byteStride {s}, expected 2 or 4",
                        m.mode
                    ));
                }
            }
        }
        mode => return Err(format!("unknown mode {mode:?}")),
    };
    debug_assert_eq!(bytes.len() as u64, out_len);
    filter(m.filter.as_deref().unwrap_or("NONE"), stride, &mut bytes)?;
    Ok(bytes)
}

/// Applies a filter in place over the decoded bytes.
fn filter(name: &str, stride: u64, bytes: &mut Vec<u8>) -> Result<(), String> {
    match (name, stride) {
        ("NONE", _) => {}
        ("OCTAHEDRAL", 4) => {
            let mut v: Vec<[i8; 4]> = bytemuck::pod_collect_to_vec(bytes);
            meshopt::decode_filter_oct(&mut v);
            *bytes = bytemuck::cast_slice(&v).to_vec();
        }
        ("OCTAHEDRAL", 8) => {
            let mut v: Vec<[i16; 4]> = bytemuck::pod_collect_to_vec(bytes);
            meshopt::decode_filter_oct(&mut v);
            *bytes = bytemuck::cast_slice(&v).to_vec();
        }
        ("QUATERNION", 8) => {
            let mut v: Vec<[i16; 4]> = bytemuck::pod_collect_to_vec(bytes);
            meshopt::decode_filter_quat(&mut v);
            *bytes = bytemuck::cast_slice(&v).to_vec();
        }
        ("EXPONENTIAL", s) if s.is_multiple_of(4) => {
            // Each 32-bit component is decoded on its own.
            let mut v: Vec<[u32; 1]> = bytemuck::pod_collect_to_vec(bytes);
            meshopt::decode_filter_exp(&mut v);
            *bytes = bytemuck::cast_slice(&v).to_vec();
        }
        ("COLOR", 4) => {
            let mut v: Vec<[u8; 4]> = bytemuck::pod_collect_to_vec(bytes);
            meshopt::decode_filter_color(&mut v);
            *bytes = bytemuck::cast_slice(&v).to_vec();
        }
        ("COLOR", 8) => {
            let mut v: Vec<[u16; 4]> = bytemuck::pod_collect_to_vec(bytes);
            meshopt::decode_filter_color(&mut v);
            *bytes = bytemuck::cast_slice(&v).to_vec();
        }
        (f, s) => return Err(format!("filter {f} with byteStride {s} is not defined")),
    }
    Ok(())
}
