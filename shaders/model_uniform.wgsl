// The model's 3×L matrix as a uniform: column j (the weights of term j for X, Y, Z) in
// `model.m[j].xyz`, 16-byte stride (naga rejects `array<f32, N>` in a uniform).
// `N_TERMS` is generated from `nsrm::model::terms(kind, order)`; `set_model` rewrites this buffer.
// After the matrix, `gain.xyz`: the input gains multiplied into R, G, B before the terms (NSRM
// only: 1, 1, 1 unless white-balanced; other kinds do not read it). Then the highlight policy
// (shaders/highlights.wgsl): `clip` (clip levels; `clip.w` 1 on, 0 off) and `neutral.xyz`.

struct ModelMatrix {
    m: array<vec4<f32>, N_TERMS>,
    gain: vec4<f32>,
    clip: vec4<f32>,
    neutral: vec4<f32>,
}

@group(0) @binding(0) var<uniform> model: ModelMatrix;
