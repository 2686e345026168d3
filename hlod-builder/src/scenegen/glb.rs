//! A streaming glTF 2.0 writer for generated scenes: `.glb`, or `.gltf` with
//! its geometry in one `.bin` beside it (the only form past GLB's 4 GiB).
//!
//! Each mesh becomes a glTF mesh with one primitive per distinct vertex colour
//! (a material with that base colour); each object a node referring to a mesh,
//! so meshes placed many times are instanced. Geometry goes to disk as it is
//! added ([`SceneStream::add_mesh`]); what stays in memory is a few dozen
//! bytes per primitive and per node, from which the JSON is written at the
//! end, element by element (no document tree), whatever the scene's size.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, Write};
use std::path::{Path, PathBuf};

use glam::Mat4;
use serde_json::json;

use crate::mesh::Mesh;

/// A node of the written scene.
#[derive(Clone, Debug)]
pub struct GlbObject {
    pub name: String,
    pub mesh: usize,
    pub transform: Mat4,
}

/// The largest GLB: its header stores the total length in 32 bits.
pub const GLB_MAX_BYTES: u64 = u32::MAX as u64;

/// Triangles of `mesh` grouped by colour (first vertex), in order of first
/// appearance; `None` when the mesh has one colour and is written whole.
fn colour_groups(mesh: &Mesh) -> Option<Vec<([u8; 4], Vec<usize>)>> {
    let mut groups: Vec<([u8; 4], Vec<usize>)> = Vec::new();
    for t in 0..mesh.tri_count() {
        let c = mesh.colors[mesh.indices[3 * t] as usize];
        match groups.iter_mut().find(|(k, _)| *k == c) {
            Some((_, v)) => v.push(t),
            None => groups.push((c, vec![t])),
        }
    }
    (groups.len() > 1).then_some(groups)
}

/// Calls `f` with each primitive of `mesh`: its colour and geometry.
fn for_each_part(mesh: &Mesh, mut f: impl FnMut([u8; 4], &Mesh)) {
    match colour_groups(mesh) {
        None => f(mesh.dominant_color(), mesh),
        Some(groups) => {
            for (color, tris) in groups {
                f(color, &mesh.subset(tris));
            }
        }
    }
}

fn pad4(n: u64) -> u64 {
    n.next_multiple_of(4)
}

/// Bytes `mesh` adds to the binary buffer.
pub fn bin_bytes(mesh: &Mesh) -> u64 {
    let mut n = 0;
    for_each_part(mesh, |_, p| {
        n += 2 * pad4(p.vertex_count() as u64 * 12) + pad4(p.indices.len() as u64 * 4);
    });
    n
}

/// What the JSON needs of one primitive.
#[derive(Clone, Copy, Debug)]
struct Prim {
    vertices: u32,
    indices: u32,
    min: [f32; 3],
    max: [f32; 3],
    material: u32,
}

/// What the JSON needs of one node.
#[derive(Clone, Debug)]
struct Node {
    name: Box<str>,
    mesh: u32,
    matrix: Option<Box<[f32; 16]>>,
}

/// Where the binary buffer goes while the scene is added.
#[derive(Debug)]
enum Bin {
    /// A `.gltf`'s `.bin`, written in place (a temporary file committed at the end).
    Beside(engine_cli::outfile::OutputFile, PathBuf),
    /// A temporary file copied into the `.glb` after the JSON.
    Staged(File),
}

/// A glTF scene being written: add meshes, then objects, then [`Self::finish`].
#[derive(Debug)]
pub struct SceneStream {
    target: PathBuf,
    inputs: Vec<PathBuf>,
    bin: Option<Bin>,
    sink: BufWriter<File>,
    bin_len: u64,
    prims: Vec<Prim>,
    /// Index of each mesh's first primitive, and one past the last.
    mesh_first: Vec<u32>,
    nodes: Vec<Node>,
    materials: BTreeMap<[u8; 4], u32>,
}

impl SceneStream {
    /// Starts writing `path` (`.gltf`: JSON and a `.bin` of the same stem;
    /// anything else: GLB), under the output policy: nothing appears at the
    /// target until [`Self::finish`] succeeds.
    pub fn create(path: &Path, inputs: &[&Path]) -> io::Result<Self> {
        let gltf = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
        let target = engine_cli::outfile::check_output(path, inputs)?;
        let (bin, file) = if gltf {
            let bin_path = target.with_extension("bin");
            let out = engine_cli::outfile::OutputFile::create(&bin_path, inputs)?;
            let f = out.file().try_clone()?;
            (Bin::Beside(out, bin_path), f)
        } else {
            let f = tempfile::tempfile_in(engine_cli::outfile::parent_dir(&target))?;
            (Bin::Staged(f.try_clone()?), f)
        };
        Ok(Self {
            target: path.to_path_buf(),
            inputs: inputs.iter().map(|p| p.to_path_buf()).collect(),
            bin: Some(bin),
            sink: BufWriter::with_capacity(1 << 20, file),
            bin_len: 0,
            prims: Vec::new(),
            mesh_first: vec![0],
            nodes: Vec::new(),
            materials: BTreeMap::new(),
        })
    }

    /// Bytes of geometry written so far.
    pub fn bin_len(&self) -> u64 {
        self.bin_len
    }

    /// Meshes added so far.
    pub fn mesh_count(&self) -> usize {
        self.mesh_first.len() - 1
    }

    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.sink.write_all(bytes)?;
        let pad = pad4(bytes.len() as u64) - bytes.len() as u64;
        self.sink.write_all(&[0u8; 3][..pad as usize])?;
        self.bin_len += pad4(bytes.len() as u64);
        Ok(())
    }

    /// Writes `mesh`'s geometry; returns its index for [`Self::add_object`].
    pub fn add_mesh(&mut self, mesh: &Mesh) -> io::Result<usize> {
        let mut result = Ok(());
        for_each_part(mesh, |color, part| {
            if result.is_err() {
                return;
            }
            let b = Mesh::bounds_of_all(part);
            let n = self.materials.len() as u32;
            let material = *self.materials.entry(color).or_insert(n);
            self.prims.push(Prim {
                vertices: part.vertex_count() as u32,
                indices: part.indices.len() as u32,
                min: b.min.to_array(),
                max: b.max.to_array(),
                material,
            });
            result = self
                .put(bytemuck::cast_slice(&part.positions))
                .and_then(|()| self.put(bytemuck::cast_slice(&part.normals)))
                .and_then(|()| self.put(bytemuck::cast_slice(&part.indices)));
        });
        result?;
        self.mesh_first.push(self.prims.len() as u32);
        Ok(self.mesh_count() - 1)
    }

    /// Places mesh `o.mesh` (added before) as a node.
    pub fn add_object(&mut self, o: &GlbObject) {
        debug_assert!(o.mesh < self.mesh_count(), "object before its mesh");
        self.nodes.push(Node {
            name: o.name.as_str().into(),
            mesh: o.mesh as u32,
            matrix: (o.transform != Mat4::IDENTITY).then(|| Box::new(o.transform.to_cols_array())),
        });
    }

    /// The JSON document: keys in sorted order, compact, as `serde_json`
    /// writes a whole document, but element by element.
    fn write_json(&self, w: &mut impl Write, uri: Option<&str>) -> io::Result<()> {
        let sep = |w: &mut dyn Write, i: usize| if i > 0 { w.write_all(b",") } else { Ok(()) };
        w.write_all(b"{\"accessors\":[")?;
        for (i, p) in self.prims.iter().enumerate() {
            sep(w, i)?;
            let v = 3 * i;
            serde_json::to_writer(
                &mut *w,
                &json!({"bufferView": v, "componentType": 5126, "count": p.vertices,
                "type": "VEC3", "min": p.min, "max": p.max}),
            )?;
            w.write_all(b",")?;
            serde_json::to_writer(
                &mut *w,
                &json!({"bufferView": v + 1, "componentType": 5126, "count": p.vertices, "type": "VEC3"}),
            )?;
            w.write_all(b",")?;
            serde_json::to_writer(
                &mut *w,
                &json!({"bufferView": v + 2, "componentType": 5125, "count": p.indices, "type": "SCALAR"}),
            )?;
        }
        w.write_all(b"],\"asset\":")?;
        serde_json::to_writer(
            &mut *w,
            &json!({"version": "2.0", "generator": "hlod-build gen"}),
        )?;
        w.write_all(b",\"bufferViews\":[")?;
        let mut offset = 0u64;
        for (i, p) in self.prims.iter().enumerate() {
            let lens = [
                u64::from(p.vertices) * 12,
                u64::from(p.vertices) * 12,
                u64::from(p.indices) * 4,
            ];
            for (k, (len, target)) in lens.into_iter().zip([34962, 34962, 34963]).enumerate() {
                sep(w, i + k)?;
                serde_json::to_writer(
                    &mut *w,
                    &json!({"buffer": 0, "byteOffset": offset, "byteLength": len, "target": target}),
                )?;
                offset += pad4(len);
            }
        }
        w.write_all(b"],\"buffers\":[")?;
        match uri {
            None => serde_json::to_writer(&mut *w, &json!({"byteLength": self.bin_len}))?,
            Some(u) => {
                serde_json::to_writer(&mut *w, &json!({"byteLength": self.bin_len, "uri": u}))?
            }
        }
        w.write_all(b"],\"materials\":[")?;
        let mut mats: Vec<(u32, [u8; 4])> = self.materials.iter().map(|(c, i)| (*i, *c)).collect();
        mats.sort_unstable();
        for (i, (_, c)) in mats.iter().enumerate() {
            sep(w, i)?;
            let f = c.map(|x| f64::from(x) / 255.0);
            // A translucent colour is blended (glTF ignores alpha otherwise).
            let mode = if c[3] < u8::MAX { "BLEND" } else { "OPAQUE" };
            serde_json::to_writer(
                &mut *w,
                &json!({"pbrMetallicRoughness": {"baseColorFactor": f, "metallicFactor": 0.0, "roughnessFactor": 0.8}, "alphaMode": mode}),
            )?;
        }
        w.write_all(b"],\"meshes\":[")?;
        for (m, pair) in self.mesh_first.windows(2).enumerate() {
            sep(w, m)?;
            w.write_all(b"{\"primitives\":[")?;
            for (k, p) in (pair[0]..pair[1]).enumerate() {
                sep(w, k)?;
                let a = 3 * p as usize;
                let material = self.prims[p as usize].material;
                serde_json::to_writer(
                    &mut *w,
                    &json!({"attributes": {"POSITION": a, "NORMAL": a + 1}, "indices": a + 2, "material": material}),
                )?;
            }
            w.write_all(b"]}")?;
        }
        w.write_all(b"],\"nodes\":[")?;
        for (i, n) in self.nodes.iter().enumerate() {
            sep(w, i)?;
            let mut v = json!({"name": &*n.name, "mesh": n.mesh});
            if let Some(m) = &n.matrix {
                v["matrix"] = json!(**m);
            }
            serde_json::to_writer(&mut *w, &v)?;
        }
        w.write_all(b"],\"scene\":0,\"scenes\":[{\"nodes\":[")?;
        for i in 0..self.nodes.len() {
            sep(w, i)?;
            write!(w, "{i}")?;
        }
        w.write_all(b"]}]}")
    }

    /// Writes the JSON and moves the files into place; returns the bytes
    /// written (`.gltf`: JSON and `.bin` together). A GLB past 4 GiB is an
    /// error naming the `.gltf` alternative, and leaves nothing behind.
    pub fn finish(mut self) -> io::Result<u64> {
        self.sink.flush()?;
        let inputs: Vec<&Path> = self.inputs.iter().map(PathBuf::as_path).collect();
        match self.bin.take().expect("finished once") {
            Bin::Beside(out, bin_path) => {
                let uri = bin_path
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                out.commit()?;
                let json_len = engine_cli::outfile::write_with(&self.target, &inputs, |w| {
                    let mut c = Counter(w, 0);
                    self.write_json(&mut c, Some(&uri))?;
                    Ok(c.1)
                });
                if json_len.is_err() {
                    let _ = std::fs::remove_file(&bin_path);
                }
                Ok(json_len? + self.bin_len)
            }
            Bin::Staged(mut file) => {
                let mut count = Counter(io::sink(), 0);
                self.write_json(&mut count, None)?;
                let js_len = pad4(count.1);
                let total = 12 + 8 + js_len + 8 + self.bin_len;
                if total > GLB_MAX_BYTES {
                    return Err(io::Error::other(format!(
                        "scene of {} exceeds GLB's limit of 4 GiB: write a .gltf instead \
                         (JSON and one .bin of any size)",
                        engine::limits::human(total)
                    )));
                }
                engine_cli::outfile::write_with(&self.target, &inputs, |w| {
                    w.write_all(b"glTF")?;
                    w.write_all(&2u32.to_le_bytes())?;
                    w.write_all(&(total as u32).to_le_bytes())?;
                    w.write_all(&(js_len as u32).to_le_bytes())?;
                    w.write_all(b"JSON")?;
                    self.write_json(w, None)?;
                    w.write_all(&b"   "[..(js_len - count.1) as usize])?;
                    w.write_all(&(self.bin_len as u32).to_le_bytes())?;
                    w.write_all(b"BIN\0")?;
                    file.rewind()?;
                    let copied = io::copy(&mut (&mut file).take(self.bin_len), w)?;
                    if copied != self.bin_len {
                        return Err(io::Error::new(
                            io::ErrorKind::UnexpectedEof,
                            "the staged geometry is shorter than written",
                        ));
                    }
                    Ok(total)
                })
            }
        }
    }
}

/// Counts the bytes written through it.
struct Counter<W>(W, u64);

impl<W: Write> Write for Counter<W> {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        let n = self.0.write(b)?;
        self.1 += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

/// Writes meshes and objects as one scene (see [`SceneStream`]), atomically.
pub fn write_glb(
    path: &Path,
    inputs: &[&Path],
    meshes: &[Mesh],
    objects: &[GlbObject],
) -> io::Result<u64> {
    let mut s = SceneStream::create(path, inputs)?;
    for m in meshes {
        s.add_mesh(m)?;
    }
    for o in objects {
        s.add_object(o);
    }
    s.finish()
}

/// Serialises meshes and objects to GLB bytes in memory (small scenes, tests).
pub fn to_glb(meshes: &[Mesh], objects: &[GlbObject]) -> io::Result<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("scene.glb");
    write_glb(&path, &[], meshes, objects)?;
    std::fs::read(&path)
}
