//! The reference Draco decoder (libdraco, through `draco/shim.cc`) as a safe
//! value: a decoded mesh owned here, freed on drop, read by copying its
//! faces and its attributes' values out. The only `unsafe` in the builder:
//! each call passes a pointer the shim documents, into a buffer sized here
//! from the mesh's own counts.
#![allow(unsafe_code)]

use std::ffi::{c_char, c_int, c_void};

unsafe extern "C" {
    fn hlod_draco_decode(
        data: *const u8,
        len: usize,
        out: *mut *mut c_void,
        err: *mut c_char,
        cap: usize,
    ) -> c_int;
    fn hlod_draco_free(m: *mut c_void);
    fn hlod_draco_num_faces(m: *const c_void) -> u32;
    fn hlod_draco_num_points(m: *const c_void) -> u32;
    fn hlod_draco_faces(m: *const c_void, out: *mut u32);
    fn hlod_draco_attribute(
        m: *const c_void,
        uid: u32,
        components: *mut c_int,
        data_type: *mut c_int,
        component_bytes: *mut c_int,
    ) -> c_int;
    fn hlod_draco_values(m: *const c_void, uid: u32, out: *mut u8) -> c_int;
}

/// A decoded Draco mesh.
#[derive(Debug)]
pub struct DracoMesh(std::ptr::NonNull<c_void>);

// The mesh is only read after decoding, and owned by this value alone.
unsafe impl Send for DracoMesh {}

impl Drop for DracoMesh {
    fn drop(&mut self) {
        // SAFETY: the pointer came from `hlod_draco_decode` and is freed once.
        unsafe { hlod_draco_free(self.0.as_ptr()) }
    }
}

/// An attribute's shape: components, Draco data type, bytes a component.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    pub components: usize,
    pub data_type: i32,
    pub component_bytes: usize,
}

/// Draco's `DataType` codes the importer reads.
pub const DT_INT8: i32 = 1;
pub const DT_UINT8: i32 = 2;
pub const DT_INT16: i32 = 3;
pub const DT_UINT16: i32 = 4;
pub const DT_UINT32: i32 = 6;
pub const DT_FLOAT32: i32 = 9;

impl DracoMesh {
    /// Decodes a Draco mesh stream; the error is the decoder's message.
    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut out = std::ptr::null_mut();
        let mut err = [0 as c_char; 256];
        // SAFETY: `bytes` is valid for its length, `out` and `err` are
        // writable for what the shim writes (a pointer; at most 256 bytes).
        let r = unsafe {
            hlod_draco_decode(
                bytes.as_ptr(),
                bytes.len(),
                &mut out,
                err.as_mut_ptr(),
                err.len(),
            )
        };
        match std::ptr::NonNull::new(out) {
            Some(m) if r == 0 => Ok(Self(m)),
            _ => {
                let msg: Vec<u8> = err
                    .iter()
                    .take_while(|&&c| c != 0)
                    .map(|&c| c as u8)
                    .collect();
                Err(String::from_utf8_lossy(&msg).into_owned())
            }
        }
    }

    pub fn num_faces(&self) -> usize {
        // SAFETY: a live mesh.
        unsafe { hlod_draco_num_faces(self.0.as_ptr()) as usize }
    }

    pub fn num_points(&self) -> usize {
        // SAFETY: a live mesh.
        unsafe { hlod_draco_num_points(self.0.as_ptr()) as usize }
    }

    /// The faces' point indices, three a face.
    pub fn faces(&self) -> Result<Vec<u32>, String> {
        let n = self.num_faces() * 3;
        let mut out = Vec::new();
        out.try_reserve_exact(n)
            .map_err(|_| format!("cannot allocate {n} face corners"))?;
        out.resize(n, 0);
        // SAFETY: `out` holds 3 × num_faces values, what the shim writes.
        unsafe { hlod_draco_faces(self.0.as_ptr(), out.as_mut_ptr()) };
        Ok(out)
    }

    /// The shape of the attribute of unique id `uid`, if the mesh has one.
    pub fn attribute(&self, uid: u32) -> Option<Shape> {
        let (mut c, mut t, mut b) = (0, 0, 0);
        // SAFETY: a live mesh; three writable ints.
        let found = unsafe { hlod_draco_attribute(self.0.as_ptr(), uid, &mut c, &mut t, &mut b) };
        (found != 0).then_some(Shape {
            components: usize::try_from(c).unwrap_or(0),
            data_type: t,
            component_bytes: usize::try_from(b).unwrap_or(0),
        })
    }

    /// Each point's value of attribute `uid`, its bytes as stored
    /// (`components × component_bytes` a point).
    pub fn values(&self, uid: u32, shape: Shape) -> Result<Vec<u8>, String> {
        if self.attribute(uid) != Some(shape) {
            return Err(format!("no attribute of unique id {uid}"));
        }
        let n = self
            .num_points()
            .checked_mul(shape.components)
            .and_then(|x| x.checked_mul(shape.component_bytes))
            .ok_or("too many values")?;
        let mut out = Vec::new();
        out.try_reserve_exact(n)
            .map_err(|_| format!("cannot allocate {n} bytes of values"))?;
        out.resize(n, 0);
        // SAFETY: `out` holds num_points × the attribute's stride bytes,
        // what the shim writes for this attribute (its shape checked above).
        let bad = unsafe { hlod_draco_values(self.0.as_ptr(), uid, out.as_mut_ptr()) };
        if bad != 0 {
            return Err("a point names a value the attribute does not have".into());
        }
        Ok(out)
    }
}
