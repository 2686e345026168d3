// Composites the cached egui overlay (premultiplied alpha, same size as the
// frame) over the frame: one full-screen triangle, scissored by the caller to
// the overlay's area; blending is One / OneMinusSrcAlpha.

@group(0) @binding(0) var overlay: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // (-1,-1), (3,-1), (-1,3): covers the viewport.
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(overlay, vec2<i32>(pos.xy), 0);
}
