//! PLY, OBJ and STL input (issue 43): the bunny written in each format
//! (PLY as ASCII and as binary of both byte orders, with normals and
//! colours; OBJ with a material library and two groups; STL binary and
//! ASCII) imports to the glTF's triangles and bounds, builds, and reads
//! back; bad files fail with one error naming the file.

use std::fmt::Write as _;

use e2e_tests::data_dir;
use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::import::{self, Imported};

/// The bunny as the glTF importer reads it: positions, indices.
fn bunny() -> (Vec<[f32; 3]>, Vec<u32>) {
    let imp = import::load(&data_dir().join("bunny.glb")).unwrap();
    let m = imp.meshes.into_iter().flatten().next().unwrap();
    (m.positions, m.indices)
}

fn ply(p: &[[f32; 3]], i: &[u32], encoding: &str) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat {encoding} 1.0\ncomment the bunny\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        p.len(),
        i.len() / 3
    )
    .into_bytes();
    let big = encoding == "binary_big_endian";
    let f = |v: f32| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let n = |v: u32| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    for v in p {
        if encoding == "ascii" {
            writeln!(
                DisplayBytes(&mut out),
                "{} {} {} 0 1 0 200 180 160",
                v[0],
                v[1],
                v[2]
            )
            .unwrap();
        } else {
            for c in v.iter().chain(&[0.0, 1.0, 0.0]) {
                out.extend(f(*c));
            }
            out.extend([200, 180, 160]);
        }
    }
    for t in i.chunks_exact(3) {
        if encoding == "ascii" {
            writeln!(DisplayBytes(&mut out), "3 {} {} {}", t[0], t[1], t[2]).unwrap();
        } else {
            out.push(3);
            for &k in t {
                out.extend(n(k));
            }
        }
    }
    out
}

/// `write!` into a byte vector.
struct DisplayBytes<'a>(&'a mut Vec<u8>);

impl std::fmt::Write for DisplayBytes<'_> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.extend_from_slice(s.as_bytes());
        Ok(())
    }
}

/// The bunny as OBJ in two groups (the first half of its triangles red).
fn obj(p: &[[f32; 3]], i: &[u32]) -> String {
    let mut s = String::from("mtllib bunny.mtl\n");
    for v in p {
        writeln!(s, "v {} {} {}", v[0], v[1], v[2]).unwrap();
    }
    let half = i.len() / 6 * 3;
    for (name, mtl, tris) in [("ears", "red", &i[..half]), ("body", "grey", &i[half..])] {
        writeln!(s, "g {name}\nusemtl {mtl}").unwrap();
        for t in tris.chunks_exact(3) {
            writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
        }
    }
    s
}

fn stl_binary(p: &[[f32; 3]], i: &[u32]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend(((i.len() / 3) as u32).to_le_bytes());
    for t in i.chunks_exact(3) {
        b.extend([0u8; 12]);
        for &k in t {
            for c in p[k as usize] {
                b.extend(c.to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    b
}

fn stl_ascii(p: &[[f32; 3]], i: &[u32]) -> String {
    let mut s = String::from("solid bunny\n");
    for t in i.chunks_exact(3) {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for &k in t {
            let v = p[k as usize];
            writeln!(s, "vertex {} {} {}", v[0], v[1], v[2]).unwrap();
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid bunny\n");
    s
}

fn tris_and_box(imp: &Imported) -> (u64, glam::Vec3, glam::Vec3) {
    let mut lo = glam::Vec3::splat(f32::INFINITY);
    let mut hi = -lo;
    for m in imp.meshes.iter().flatten() {
        let b = m.bounds();
        lo = lo.min(b.min);
        hi = hi.max(b.max);
    }
    (imp.instanced_triangles(), lo, hi)
}

#[test]
fn the_bunny_in_every_format_imports_as_the_gltf_and_builds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (p, i) = bunny();
    let want = tris_and_box(&import::load(&data_dir().join("bunny.glb")).unwrap());
    std::fs::write(
        d.join("bunny.mtl"),
        "newmtl red\nKd 1 0 0\nnewmtl grey\nKd 0.5 0.5 0.5\n",
    )
    .unwrap();
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("ascii.ply", ply(&p, &i, "ascii")),
        ("le.ply", ply(&p, &i, "binary_little_endian")),
        ("be.ply", ply(&p, &i, "binary_big_endian")),
        ("bunny.obj", obj(&p, &i).into_bytes()),
        ("binary.stl", stl_binary(&p, &i)),
        ("ascii.stl", stl_ascii(&p, &i).into_bytes()),
    ];
    for (name, bytes) in files {
        let path = d.join(name);
        std::fs::write(&path, bytes).unwrap();
        let imp = import::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let (tris, lo, hi) = tris_and_box(&imp);
        assert_eq!(tris, want.0, "{name}: triangles");
        // ASCII writes shortest round-trip decimals: the same floats.
        assert!(
            (lo - want.1).abs().max_element() < 1e-6,
            "{name}: {lo} {}",
            want.1
        );
        assert!(
            (hi - want.2).abs().max_element() < 1e-6,
            "{name}: {hi} {}",
            want.2
        );
        if name.ends_with(".ply") {
            let m = imp.meshes.iter().flatten().next().unwrap();
            assert_eq!(m.colors[0], [200, 180, 160, 255], "{name}: colours");
        }
        if name == "bunny.obj" {
            let names: Vec<&str> = imp.instances.iter().map(|x| x.name.as_str()).collect();
            assert_eq!(names, ["ears", "body"]);
            let m = imp.meshes[0].as_ref().unwrap();
            assert_eq!(m.colors[0], [255, 0, 0, 255], "Kd of the group's material");
        }
        let out = d.join(format!("{name}.hlod"));
        let stats = build_file(&path, &out, &BuildParams::default(), false).unwrap();
        assert_eq!(stats.input_triangles, want.0, "{name}");
        engine::SceneFile::open(&out)
            .unwrap()
            .verify_all_reps()
            .unwrap();
    }
}

#[test]
fn bad_mesh_files_fail_with_one_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (p, i) = bunny();
    let le = ply(&p, &i, "binary_little_endian");
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("cut.ply", le[..le.len() - 100].to_vec(), "PLY element face"),
        (
            "header.ply",
            b"ply\nformat ascii 1.0\nelement vertex x\n".to_vec(),
            "PLY header",
        ),
        (
            "points.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n".to_vec(),
            "point cloud",
        ),
        ("cut.stl", stl_binary(&p, &i)[..5000].to_vec(), "STL"),
        (
            "bad.obj",
            b"v 0 0 0\nv 1 0 0\nv 1 x 0\nf 1 2 3\n".to_vec(),
            "line 3",
        ),
        ("utf16.obj", b"\xFF\xFEv\x00 \x000\x00".to_vec(), "UTF-16"),
        (
            "empty.obj",
            b"# nothing\n".to_vec(),
            "no renderable triangles",
        ),
    ];
    for (name, bytes, needle) in cases {
        let path = d.join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = build_file(&path, &d.join("o.hlod"), &BuildParams::default(), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name) && e.contains(needle), "{name}: {e}");
        assert!(!d.join("o.hlod").exists());
    }
    // A scan far from the origin keeps millimetres (read in f64).
    let far = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
               property double z\nelement face 1\nproperty list uchar int vertex_indices\n\
               end_header\n3500000.25 7.5 0\n3500001.25 7.5 0\n3500000.25 7.501 0\n3 0 1 2\n";
    let path = d.join("far.ply");
    std::fs::write(&path, far).unwrap();
    let imp = import::load(&path).unwrap();
    assert!(imp.origin[0] > 3_000_000.0, "{:?}", imp.origin);
    let m = imp.meshes.iter().flatten().next().unwrap();
    let x0 = imp.origin[0] + f64::from(m.positions[0][0]);
    assert!((x0 - 3_500_000.25).abs() < 1e-3, "{x0}");
    let dy = f64::from(m.positions[2][1]) - f64::from(m.positions[0][1]);
    assert!((dy - 0.001).abs() < 1e-4, "{dy}");
}
