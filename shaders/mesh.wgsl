// Object-rep shading: quantised positions expanded over each rep's box,
// per-vertex colour (or a debug tint), headlight Lambert. Two passes: the
// opaque pass (fs_main) draws the fragments whose colour is opaque and
// writes depth; the translucent pass (fs_translucent, alpha blending, no
// depth write) draws the others (glass, translucent materials) over it.
// Both discard what a section plane cuts away; the opaque pass caps the cut.
// X-rayed elements are drawn by the translucent pass with records of their
// own (fade direction 3): a pale, mostly transparent blue over the rest,
// writing no depth, so they hide nothing.
//
// Vertex layout (16 bytes, see engine::format::rep::PackedVertex):
//   location 0: position unorm16x4 over the rep's quantisation box
//   location 1: normal snorm8x4 (w unused; a zero normal means "use the face")
//   location 2: colour unorm8x4
// Per draw: `draws[instance_index]` (the renderer issues each rep as one
// instance whose index selects its record).

struct Globals {
    view_proj: mat4x4<f32>,
    // xyz: eye position in world space.
    eye: vec4<f32>,
    // Section planes (engine::section): a fragment with
    // dot(plane.xyz, world) + plane.w < 0 is cut away.
    planes: array<vec4<f32>, 8>,
    // x: how many of `planes` are in use.
    section: vec4<u32>,
};

struct DrawData {
    // xyz: world position of quantised 0; w: a fade's progress t in [0, 1].
    quant_min: vec4<f32>,
    // xyz: world size of one unorm16 step times 65535; w: the fade's
    // direction (0 opaque, 1 fading in, 2 fading out), or 3: x-rayed.
    quant_extent: vec4<f32>,
    // rgb: debug tint; a: how much of it replaces the vertex colour.
    tint: vec4<f32>,
    // Rows of the affine map that places a shared payload (an instanced
    // mesh's level stored once) in the world; the identity otherwise.
    place: array<vec4<f32>, 3>,
};

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var<storage, read> draws: array<DrawData>;

struct VsIn {
    @location(0) position: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) color: vec4<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    // x: fade progress, y: direction (see DrawData).
    @location(3) @interpolate(flat) fade: vec2<f32>,
};

// The 4x4 ordered-dither threshold of a pixel, in (0, 1) (the same table
// as engine::render::dither_threshold).
fn dither_threshold(pixel: vec2<u32>) -> f32 {
    var bayer = array<u32, 16>(0u, 8u, 2u, 10u, 12u, 4u, 14u, 6u, 3u, 11u, 1u, 9u, 15u, 7u, 13u, 5u);
    let k = (pixel.y & 3u) * 4u + (pixel.x & 3u);
    return (f32(bayer[k]) + 0.5) / 16.0;
}

@vertex
fn vs_main(v: VsIn, @builtin(instance_index) draw: u32) -> VsOut {
    let d = draws[draw];
    let local = vec4<f32>(d.quant_min.xyz + v.position.xyz * d.quant_extent.xyz, 1.0);
    let world = vec3<f32>(dot(d.place[0], local), dot(d.place[1], local), dot(d.place[2], local));
    // Normals by the cofactors of the linear part (the inverse transpose
    // up to scale; the headlight is two-sided, so its sign does not matter).
    let c0 = vec3<f32>(d.place[0].x, d.place[1].x, d.place[2].x);
    let c1 = vec3<f32>(d.place[0].y, d.place[1].y, d.place[2].y);
    let c2 = vec3<f32>(d.place[0].z, d.place[1].z, d.place[2].z);
    let n = v.normal.x * cross(c1, c2) + v.normal.y * cross(c2, c0) + v.normal.z * cross(c0, c1);
    let len = length(n);
    var out: VsOut;
    out.clip = globals.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    // A zero normal stays zero (the fragment then uses the face's).
    out.normal = select(vec3<f32>(0.0), n / len, len > 1e-30);
    out.color = vec4<f32>(mix(v.color.rgb, d.tint.rgb, d.tint.a), v.color.a);
    if d.quant_extent.w > 2.5 {
        out.color = vec4<f32>(mix(out.color.rgb, XRAY_RGB, 0.6), XRAY_ALPHA);
    }
    out.fade = vec2<f32>(d.quant_min.w, d.quant_extent.w);
    return out;
}

// A fragment at least this opaque is drawn by the opaque pass.
const OPAQUE: f32 = 0.995;
// An x-rayed element's colour and opacity.
const XRAY_RGB: vec3<f32> = vec3<f32>(0.55, 0.75, 1.0);
const XRAY_ALPHA: f32 = 0.2;

// The headlit colour of a fragment, with its alpha.
fn shade(in: VsOut) -> vec4<f32> {
    // Derivatives in uniform control flow; the face normal stands in for a
    // zero vertex normal.
    let face = cross(dpdx(in.world), dpdy(in.world));
    let n = normalize(select(in.normal, face, dot(in.normal, in.normal) < 1e-6));
    let to_eye = normalize(globals.eye.xyz - in.world);
    // Headlight: two-sided, so that open CAD surfaces read from both sides.
    let lambert = abs(dot(n, to_eye));
    return vec4<f32>(in.color.rgb * (0.2 + 0.8 * lambert), in.color.a);
}

// Screen-door fade: a rep fading in by t keeps the pixels whose threshold
// is below t, one fading out the others.
fn faded_out(in: VsOut) -> bool {
    let threshold = dither_threshold(vec2<u32>(in.clip.xy));
    let fading_in = in.fade.y > 0.5 && in.fade.y < 1.5;
    let fading_out = in.fade.y > 1.5 && in.fade.y < 2.5;
    return (fading_in && threshold >= in.fade.x) || (fading_out && threshold < in.fade.x);
}

// Whether a section plane cuts the point away.
fn cut_away(world: vec3<f32>) -> bool {
    let n = min(globals.section.x, 8u);
    for (var i = 0u; i < n; i++) {
        let q = globals.planes[i];
        if dot(q.xyz, world) + q.w < 0.0 {
            return true;
        }
    }
    return false;
}

// The opaque pass. Under a section, a back face seen through the cut is
// the inside of a cut solid: it is drawn flat and dark, a cap over the
// cut (open surfaces seen from behind take it too while a section is on).
@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let c = shade(in);
    if faded_out(in) || in.color.a < OPAQUE || cut_away(in.world) {
        discard;
    }
    if globals.section.x > 0u && !front {
        return vec4<f32>(in.color.rgb * 0.35, 1.0);
    }
    return vec4<f32>(c.rgb, 1.0);
}

@fragment
fn fs_translucent(in: VsOut) -> @location(0) vec4<f32> {
    let c = shade(in);
    if faded_out(in) || in.color.a >= OPAQUE || cut_away(in.world) {
        discard;
    }
    return c;
}
