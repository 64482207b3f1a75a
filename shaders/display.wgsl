// Display pass of the embedding example (examples/embed.rs): draws the corrected
// XYZ texture to an 8-bit target as sRGB. A full-screen triangle; the fragment shader converts
// XYZ → linear sRGB with the uniform's rows (XYZ scaled so the white has Y = 1, Bradford-adapted
// to D65), clamps to [0, 1] and applies the sRGB transfer function. The target is a plain
// (non-sRGB) rgba8unorm texture, so the encoding here is the one stored.

struct Display {
    rows: array<vec4<f32>, 3>,
}

@group(0) @binding(0) var<uniform> display: Display;
@group(0) @binding(1) var corrected: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let x = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    let hi = 1.055 * pow(x, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, 12.92 * x, x <= vec3<f32>(0.0031308));
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let xyz = textureLoad(corrected, vec2<i32>(pos.xy), 0).xyz;
    let rgb = vec3<f32>(
        dot(display.rows[0].xyz, xyz),
        dot(display.rows[1].xyz, xyz),
        dot(display.rows[2].xyz, xyz),
    );
    return vec4<f32>(srgb_encode(rgb), 1.0);
}
