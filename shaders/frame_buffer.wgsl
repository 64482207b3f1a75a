// Storage-buffer frame, separate input and output: packed `R G B` (CHANNELS = 3) or
// `R G B A` (CHANNELS = 4) f32 pixels are read from `src`, corrected by `correct` (the model
// kind's file) and written to `dst`; alpha is copied bit for bit.
//
// The pixel count is the length of the `dst` binding. Dispatch: with
// G = ceil(pixels / WORKGROUP_SIZE) workgroups, (G, 1, 1) if G <= ROW_GROUPS, else
// (ROW_GROUPS, ceil(G / ROW_GROUPS), 1): no dimension exceeds 65535.

@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var<storage, read_write> dst: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let pixel = (wg.y * ROW_GROUPS + wg.x) * WORKGROUP_SIZE + li;
    if (pixel >= arrayLength(&dst) / CHANNELS) {
        return;
    }
    let b = pixel * CHANNELS;
    let out = correct(vec3<f32>(src[b], src[b + 1u], src[b + 2u]));
    dst[b] = out.x;
    dst[b + 1u] = out.y;
    dst[b + 2u] = out.z;
    if (CHANNELS == 4u) {
        dst[b + 3u] = src[b + 3u];
    }
}
