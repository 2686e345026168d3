//! Accessors read with explicit bounds checks: every component type, the
//! `normalized` flag (`KHR_mesh_quantization`), sparse substitution,
//! accessors without a buffer view (zeros), and buffer views decoded from
//! `EXT_meshopt_compression`. Errors name the glTF part (`accessors[3]`,
//! `bufferViews[2]`).

use super::doc::{Accessor, Doc};
use super::meshopt_view;

/// glTF component types.
pub const I8: u32 = 5120;
pub const U8: u32 = 5121;
pub const I16: u32 = 5122;
pub const U16: u32 = 5123;
pub const U32: u32 = 5125;
pub const F32: u32 = 5126;

/// Bytes of one component, `None` for an unknown type.
pub fn component_size(t: u32) -> Option<u64> {
    match t {
        I8 | U8 => Some(1),
        I16 | U16 => Some(2),
        U32 | F32 => Some(4),
        _ => None,
    }
}

pub fn component_name(t: u32) -> String {
    match t {
        I8 => "BYTE".into(),
        U8 => "UNSIGNED_BYTE".into(),
        I16 => "SHORT".into(),
        U16 => "UNSIGNED_SHORT".into(),
        U32 => "UNSIGNED_INT".into(),
        F32 => "FLOAT".into(),
        t => format!("component type {t}"),
    }
}

/// Components of an accessor type.
pub fn dimensions(kind: &str) -> Option<usize> {
    match kind {
        "SCALAR" => Some(1),
        "VEC2" => Some(2),
        "VEC3" => Some(3),
        "VEC4" => Some(4),
        _ => None,
    }
}

/// The bytes of one buffer: in memory, or a span of a file read when used
/// (a GLB's BIN chunk or an external `.bin`, opened lazily).
#[derive(Debug)]
pub enum BufData {
    Mem(Vec<u8>),
    File {
        file: std::fs::File,
        offset: u64,
        len: u64,
    },
}

impl BufData {
    pub fn len(&self) -> u64 {
        match self {
            BufData::Mem(v) => v.len() as u64,
            BufData::File { len, .. } => *len,
        }
    }

    /// Bytes `offset..offset + len`, which the caller has checked lie within.
    fn read(&self, offset: u64, len: u64) -> Result<Bytes<'_>, String> {
        match self {
            BufData::Mem(v) => Ok(Bytes::Slice(&v[offset as usize..(offset + len) as usize])),
            BufData::File {
                file, offset: at, ..
            } => {
                use std::os::unix::fs::FileExt;
                let mut out = Vec::new();
                out.try_reserve_exact(len as usize)
                    .map_err(|_| format!("cannot allocate {len} bytes"))?;
                out.resize(len as usize, 0);
                file.read_exact_at(&mut out, at + offset)
                    .map_err(|e| format!("cannot read {len} bytes at {}: {e}", at + offset))?;
                Ok(Bytes::Owned(out))
            }
        }
    }
}

/// Bytes of a buffer view: borrowed from memory, read from a file, or a
/// range of a decoded (meshopt) view shared through the cache.
#[derive(Debug)]
pub enum Bytes<'a> {
    Slice(&'a [u8]),
    Owned(Vec<u8>),
    Shared(std::sync::Arc<Vec<u8>>, usize, usize),
}

impl std::ops::Deref for Bytes<'_> {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Bytes::Slice(s) => s,
            Bytes::Owned(v) => v,
            Bytes::Shared(v, a, b) => &v[*a..*b],
        }
    }
}

type ViewCache = engine::evict::lru::LruMap<usize, std::sync::Arc<Vec<u8>>>;

/// Decoded meshopt buffer views, most recently used kept up to a byte limit
/// (a lazily opened scene decodes a view again after it was dropped).
#[derive(Debug)]
pub struct Decoded {
    /// The views by index, and their bytes in all.
    views: std::sync::Mutex<(ViewCache, u64)>,
    limit: u64,
}

impl Decoded {
    /// Keeps up to `limit` bytes of decoded views (`u64::MAX`: all).
    pub fn new(limit: u64) -> Self {
        Self {
            views: std::sync::Mutex::new((ViewCache::default(), 0)),
            limit,
        }
    }

    fn get_or_decode(
        &self,
        v: usize,
        decode: impl FnOnce() -> Result<Vec<u8>, String>,
    ) -> Result<std::sync::Arc<Vec<u8>>, String> {
        let lock = || self.views.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(hit) = lock().0.get(v) {
            return Ok(hit.clone());
        }
        let data = std::sync::Arc::new(decode()?);
        let mut g = lock();
        let (cache, bytes) = &mut *g;
        *bytes += data.len() as u64;
        if let Some(old) = cache.put(v, data.clone()) {
            *bytes -= old.len() as u64;
        }
        while *bytes > self.limit && cache.len() > 1 {
            if let Some((_, old)) = cache.pop_victim() {
                *bytes -= old.len() as u64;
            }
        }
        Ok(data)
    }
}

/// The buffers of a document and its decoded views.
#[derive(Debug)]
pub struct Buffers<'a> {
    pub doc: &'a Doc,
    data: &'a [BufData],
    decoded: &'a Decoded,
    /// Bytes the buffers hold or decode to: no accessor has more elements.
    capacity: u64,
}

impl Buffers<'_> {
    pub fn capacity(&self) -> u64 {
        self.capacity
    }
}

impl<'a> Buffers<'a> {
    pub fn new(doc: &'a Doc, data: &'a [BufData], decoded: &'a Decoded) -> Self {
        let capacity = data.iter().map(BufData::len).sum::<u64>()
            + doc
                .buffer_views
                .iter()
                .filter_map(|v| v.extensions.meshopt())
                .map(|m| m.count.saturating_mul(m.byte_stride))
                .fold(0u64, u64::saturating_add);
        Self::with_capacity(doc, data, decoded, capacity)
    }

    /// [`Self::new`] with the capacity computed before (it visits every view).
    pub fn with_capacity(
        doc: &'a Doc,
        data: &'a [BufData],
        decoded: &'a Decoded,
        capacity: u64,
    ) -> Self {
        Self {
            doc,
            data,
            decoded,
            capacity,
        }
    }

    /// Bytes `offset..offset + len` of buffer view `v` (decompressed when it
    /// is meshopt-compressed, else a range of its buffer, read only as far
    /// as asked); `None` for `len` means to the view's end.
    pub fn view(&self, v: usize, offset: u64, len: Option<u64>) -> Result<Bytes<'a>, String> {
        let views = &self.doc.buffer_views;
        let view = views
            .get(v)
            .ok_or_else(|| format!("bufferViews[{v}] does not exist ({} views)", views.len()))?;
        if let Some(m) = view.extensions.meshopt() {
            let data = self
                .decoded
                .get_or_decode(v, || {
                    let src = self.range(m.buffer, m.byte_offset, m.byte_length)?;
                    meshopt_view::decode(m, &src)
                })
                .map_err(|e| format!("bufferViews[{v}] (meshopt): {e}"))?;
            let total = data.len() as u64;
            let (a, b) = sub_range(offset, len, total).ok_or_else(|| {
                format!("bufferViews[{v}]: bytes {offset}+{len:?} out of its {total}")
            })?;
            return Ok(Bytes::Shared(data, a as usize, b as usize));
        }
        if self
            .doc
            .buffers
            .get(view.buffer)
            .is_some_and(|b| b.is_fallback())
        {
            return Err(format!(
                "bufferViews[{v}] refers to buffers[{}], a meshopt fallback without data, and is not compressed",
                view.buffer
            ));
        }
        // The whole view must lie in its buffer, whatever part is read.
        self.check_range(view.buffer, view.byte_offset, view.byte_length)
            .map_err(|e| format!("bufferViews[{v}]: {e}"))?;
        let (a, b) = sub_range(offset, len, view.byte_length).ok_or_else(|| {
            format!(
                "bufferViews[{v}]: bytes {offset}+{len:?} out of its {}",
                view.byte_length
            )
        })?;
        self.range(view.buffer, view.byte_offset + a, b - a)
            .map_err(|e| format!("bufferViews[{v}]: {e}"))
    }

    /// The byte length of view `v` (decoded, for a meshopt view).
    pub fn view_len(&self, v: usize) -> Result<u64, String> {
        let view = self
            .doc
            .buffer_views
            .get(v)
            .ok_or_else(|| format!("bufferViews[{v}] does not exist"))?;
        Ok(match view.extensions.meshopt() {
            Some(m) => m.count.saturating_mul(m.byte_stride),
            None => view.byte_length,
        })
    }

    fn check_range(&self, buffer: usize, offset: u64, len: u64) -> Result<(), String> {
        let b = self
            .data
            .get(buffer)
            .ok_or_else(|| format!("buffers[{buffer}] does not exist"))?;
        match offset.checked_add(len) {
            Some(e) if e <= b.len() => Ok(()),
            _ => Err(format!(
                "bytes {offset}+{len} out of range of buffers[{buffer}] ({} bytes)",
                b.len()
            )),
        }
    }

    fn range(&self, buffer: usize, offset: u64, len: u64) -> Result<Bytes<'a>, String> {
        self.check_range(buffer, offset, len)?;
        self.data[buffer].read(offset, len)
    }
}

/// `offset..offset + len` (or to `total`) when it lies within `total`.
fn sub_range(offset: u64, len: Option<u64>, total: u64) -> Option<(u64, u64)> {
    let end = match len {
        Some(l) => offset.checked_add(l)?,
        None => total,
    };
    (offset <= end && end <= total).then_some((offset, end))
}

/// The value of one component as `f32`, normalized to [0, 1] or [-1, 1]
/// when the accessor says so.
pub(crate) fn component_f32(t: u32, normalized: bool, b: &[u8]) -> f32 {
    match (t, normalized) {
        (F32, _) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        (I8, false) => f32::from(b[0] as i8),
        (I8, true) => (f32::from(b[0] as i8) / 127.0).max(-1.0),
        (U8, false) => f32::from(b[0]),
        (U8, true) => f32::from(b[0]) / 255.0,
        (I16, false) => f32::from(i16::from_le_bytes([b[0], b[1]])),
        (I16, true) => (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0),
        (U16, false) => f32::from(u16::from_le_bytes([b[0], b[1]])),
        (U16, true) => f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
        (U32, false) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
        (U32, true) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32 / u32::MAX as f32,
        _ => f32::NAN,
    }
}

fn component_u32(t: u32, b: &[u8]) -> u32 {
    match t {
        U8 => u32::from(b[0]),
        U16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

/// The bytes `count` elements of `elem` bytes, `stride` apart, span from
/// `offset`, when they fit in `total` bytes.
fn element_span(
    total: u64,
    offset: u64,
    stride: u64,
    elem: u64,
    count: u64,
) -> Result<u64, String> {
    let span = match count {
        0 => Some(0),
        n => stride.checked_mul(n - 1).and_then(|x| x.checked_add(elem)),
    };
    match span {
        Some(s) if stride >= elem && offset.checked_add(s).is_some_and(|e| e <= total) => Ok(s),
        _ => Err(format!(
            "out of range: {count} elements of {elem} bytes, stride {stride}, from byte \
             {offset}, do not fit in its {total} bytes"
        )),
    }
}

/// Calls `f(i, bytes)` for each of `count` elements of `elem` bytes at
/// `offset` in `bytes`, `stride` apart; checks the range first.
fn each_element(
    bytes: &[u8],
    offset: u64,
    stride: u64,
    elem: u64,
    count: u64,
    mut f: impl FnMut(usize, &[u8]),
) -> Result<(), String> {
    element_span(bytes.len() as u64, offset, stride, elem, count)?;
    for i in 0..count as usize {
        let at = offset as usize + i * stride as usize;
        f(i, &bytes[at..at + elem as usize]);
    }
    Ok(())
}

/// The most elements one accessor may have: what fits in the buffers'
/// bytes (a view-less accessor of zeros is bounded the same way).
fn check_count(acc: &Accessor, bufs: &Buffers) -> Result<usize, String> {
    if acc.count > bufs.capacity.max(1 << 20) {
        return Err(format!(
            "count {} is more than its file's buffers could hold",
            acc.count
        ));
    }
    Ok(acc.count as usize)
}

/// Reads accessor `a` as `N`-component float vectors.
pub fn read_f32<const N: usize>(bufs: &Buffers, a: usize) -> Result<Vec<[f32; N]>, String> {
    read(bufs, a, N, component_f32, 0.0).map_err(|e| format!("accessors[{a}]: {e}"))
}

/// Reads accessor `a` as unsigned scalar indices.
pub fn read_indices(bufs: &Buffers, a: usize) -> Result<Vec<u32>, String> {
    let acc = accessor(bufs.doc, a)?;
    if !matches!(acc.component_type, U8 | U16 | U32) {
        return Err(format!(
            "accessors[{a}]: indices of type {}, expected an unsigned integer",
            component_name(acc.component_type)
        ));
    }
    let v: Vec<[u32; 1]> = read(bufs, a, 1, |t, _, b| component_u32(t, b), 0)
        .map_err(|e| format!("accessors[{a}]: {e}"))?;
    Ok(v.into_iter().map(|[i]| i).collect())
}

/// The accessor's component type and dimension, for choosing how to read it.
pub fn shape(doc: &Doc, a: usize) -> Result<(u32, Option<usize>), String> {
    let acc = accessor(doc, a)?;
    Ok((acc.component_type, dimensions(&acc.kind)))
}

fn accessor(doc: &Doc, a: usize) -> Result<&Accessor, String> {
    doc.accessors.get(a).ok_or_else(|| {
        format!(
            "accessors[{a}] does not exist ({} accessors)",
            doc.accessors.len()
        )
    })
}

fn read<T: Copy, const N: usize>(
    bufs: &Buffers,
    a: usize,
    dims: usize,
    conv: impl Fn(u32, bool, &[u8]) -> T,
    zero: T,
) -> Result<Vec<[T; N]>, String> {
    let acc = accessor(bufs.doc, a)?;
    let csize = component_size(acc.component_type)
        .ok_or_else(|| format!("unknown {}", component_name(acc.component_type)))?;
    if dimensions(&acc.kind) != Some(dims) {
        return Err(format!("type {:?}, expected {dims} components", acc.kind));
    }
    let count = check_count(acc, bufs)?;
    let elem = csize * dims as u64;
    let t = acc.component_type;
    let decode = |b: &[u8]| -> [T; N] {
        std::array::from_fn(|k| conv(t, acc.normalized, &b[k * csize as usize..]))
    };
    let mut out: Vec<[T; N]> = Vec::new();
    out.try_reserve_exact(count)
        .map_err(|_| format!("cannot allocate {count} elements"))?;
    match acc.buffer_view {
        Some(v) => {
            // The view's own range first (its error before the accessor's).
            bufs.view(v, 0, Some(0))?;
            let view = bufs
                .doc
                .buffer_views
                .get(v)
                .ok_or_else(|| format!("bufferViews[{v}] does not exist"))?;
            // Vertex attributes are 4-byte aligned; an unstrided view is tight.
            let stride = view
                .extensions
                .meshopt()
                .map(|m| m.byte_stride)
                .or(view.byte_stride)
                .unwrap_or(elem);
            // Then only the accessor's span of it is read.
            let span = bufs
                .view_len(v)
                .and_then(|total| element_span(total, acc.byte_offset, stride, elem, count as u64));
            let span = span.map_err(|e| format!("bufferViews[{v}]: {e}"))?;
            let bytes = bufs.view(v, acc.byte_offset, Some(span))?;
            each_element(&bytes, 0, stride, elem, count as u64, |_, b| {
                out.push(decode(b))
            })
            .map_err(|e| format!("bufferViews[{v}]: {e}"))?;
        }
        None => out.resize(count, [zero; N]),
    }
    if let Some(s) = &acc.sparse {
        if s.count > count as u64 {
            return Err(format!("sparse.count {} exceeds count {count}", s.count));
        }
        let it = &s.indices;
        let isize = match it.component_type {
            U8 | U16 | U32 => component_size(it.component_type).unwrap_or(4),
            t => return Err(format!("sparse.indices of type {}", component_name(t))),
        };
        let mut idx = Vec::with_capacity(s.count as usize);
        let ibytes = bufs.view(it.buffer_view, 0, None)?;
        each_element(&ibytes, it.byte_offset, isize, isize, s.count, |_, b| {
            idx.push(component_u32(it.component_type, b))
        })
        .map_err(|e| format!("sparse.indices: {e}"))?;
        let vbytes = bufs.view(s.values.buffer_view, 0, None)?;
        let mut bad = None;
        each_element(
            &vbytes,
            s.values.byte_offset,
            elem,
            elem,
            s.count,
            |i, b| match out.get_mut(idx[i] as usize) {
                Some(slot) => *slot = decode(b),
                None => bad = Some(idx[i]),
            },
        )
        .map_err(|e| format!("sparse.values: {e}"))?;
        if let Some(i) = bad {
            return Err(format!("sparse index {i} out of range of count {count}"));
        }
    }
    Ok(out)
}
