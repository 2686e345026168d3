//! Smooth LOD switches on the GPU (wgpu, lavapipe without one): the mesh
//! shader's screen-door dither for a rep fading in by `t` and the one
//! fading out by `t` cover each pixel of the opaque rep exactly once, and
//! `t` of them fade in.

use std::sync::Arc;

use engine::SceneFile;
use engine::camera::{Pose, View};
use engine::image::RgbaImage;
use engine::render::{DrawStyle, Fade, Renderer, dither_threshold};
use engine_gpu::{Colouring, GpuRenderer, RendererConfig};
use glam::Vec3;
use hlod_builder::build::{BuildParams, build_file};

const W: u32 = 256;
const H: u32 = 192;

#[test]
fn a_fade_in_and_its_fade_out_cover_the_opaque_rep_exactly_once() {
    let glb = e2e_tests::data_dir().join("2CylinderEngine/2CylinderEngine.gltf");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.hlod");
    build_file(&glb, &path, &BuildParams::default(), false).unwrap();
    let scene = SceneFile::open(&path).unwrap();
    let skel = scene.skeleton().clone();
    // The root's finest rep: the whole engine on the screen.
    let root = &skel.nodes[0];
    let rep = root.first_rep + root.rep_count - 1;
    let rec = skel.reps[rep as usize];
    let stored = scene.read_rep_bytes(rep).unwrap();
    let payload: Arc<[u8]> =
        Arc::from(&*engine::format::expand_payload(&stored, rep, &rec).unwrap());
    let Some(ctx) =
        e2e_tests::gpu_or_skip("a_fade_in_and_its_fade_out_cover_the_opaque_rep_exactly_once")
    else {
        return;
    };
    let mut r = GpuRenderer::new(
        ctx,
        RendererConfig {
            colouring: Colouring::Object,
            ..RendererConfig::headless(W, H, 256 << 20)
        },
    )
    .unwrap();
    let (min, max) = (Vec3::from(root.bbox_min), Vec3::from(root.bbox_max));
    let c = (min + max) * 0.5;
    let view = View {
        pose: Pose::look_at(
            c + Vec3::new(1.0, 0.6, 0.8) * (max - min).length() * 0.7,
            c,
            50.0,
        ),
        width_px: W,
        height_px: H,
        near: 0.01,
        far: 1e4,
        section: engine::section::Section::NONE,
    };
    let mut shot = |fade: Fade| -> RgbaImage {
        r.capture_next_frame();
        r.begin_frame(&view);
        r.draw(
            rep,
            &rec,
            &payload,
            DrawStyle {
                fade,
                ..DrawStyle::default()
            },
        );
        r.end_frame();
        r.take_capture().expect("captured frame")
    };
    let opaque = shot(Fade::Opaque);
    let bg = opaque.pixel(0, 0);
    let covered = |img: &RgbaImage, x: u32, y: u32| img.pixel(x, y)[..3] != bg[..3];
    let solid = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| covered(&opaque, x, y))
        .count();
    assert!(
        solid > (W * H / 25) as usize,
        "the rep covers {solid} pixels"
    );
    for t in [0.0, 0.25, 0.5, 0.8125, 1.0] {
        let (fin, fout) = (shot(Fade::In(t)), shot(Fade::Out(t)));
        let mut kept_in = 0;
        for y in 0..H {
            for x in 0..W {
                let (a, b) = (covered(&fin, x, y), covered(&fout, x, y));
                if covered(&opaque, x, y) {
                    assert!(
                        a != b,
                        "t {t}: pixel ({x}, {y}) drawn by {} of the two",
                        u8::from(a) + u8::from(b)
                    );
                    // The shader's threshold is the CPU's.
                    assert_eq!(a, dither_threshold(x, y) < t, "t {t}: pixel ({x}, {y})");
                    // Each keeps the opaque rep's colour where it draws.
                    let kept = if a { &fin } else { &fout };
                    assert_eq!(kept.pixel(x, y), opaque.pixel(x, y));
                    kept_in += usize::from(a);
                } else {
                    assert!(!a && !b, "t {t}: pixel ({x}, {y}) drawn outside the rep");
                }
            }
        }
        let share = kept_in as f64 / solid as f64;
        assert!(
            (share - f64::from(t)).abs() < 0.05,
            "t {t}: {share:.3} fades in"
        );
    }
}
