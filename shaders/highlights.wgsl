// Highlights that stay white: nsrm::model::highlights, operation for operation as
// `Highlights::map_f32` (the fast CPU path) computes it. With the clip levels `clip.xyz`
// (camera RGB; `clip.w` = 1 turns the policy on, 0 leaves every pixel as it is) and the
// brightest plausible neutral `neutral`: m = max_i x_i / clip_i, t = smoothstep(BLEND_FROM, 1, m)
// spelled out (the same formula in f32), x -> x·(1−t) + neutral·t. NaN or ±Inf in any channel:
// the pixel passes unchanged (the pixel policy holds).

const BLEND_FROM: f32 = 0.9;
const F32_MAX: f32 = 3.40282347e38;

fn highlights_with(x: vec3<f32>, clip: vec4<f32>, neutral: vec3<f32>) -> vec3<f32> {
    if (clip.w == 0.0) {
        return x;
    }
    // NaN fails every comparison, ±Inf the bound: both pass unchanged.
    if (!all(abs(x) <= vec3<f32>(F32_MAX))) {
        return x;
    }
    let m = max(max(x.x / clip.x, x.y / clip.y), x.z / clip.z);
    let u = clamp((m - BLEND_FROM) / (1.0 - BLEND_FROM), 0.0, 1.0);
    let t = u * u * (3.0 - 2.0 * u);
    if (t <= 0.0) {
        return x;
    }
    return x * (1.0 - t) + neutral * t;
}
