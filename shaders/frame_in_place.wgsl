// Storage-buffer frame, corrected in place: packed `R G B` (CHANNELS = 3) or `R G B A`
// (CHANNELS = 4) f32 pixels in `pixels`, overwritten with the model's output; alpha is not
// touched.
//
// The pixel count is the length of the `pixels` binding. Dispatch: with
// G = ceil(pixels / WORKGROUP_SIZE) workgroups, (G, 1, 1) if G <= ROW_GROUPS, else
// (ROW_GROUPS, ceil(G / ROW_GROUPS), 1): no dimension exceeds 65535.

@group(0) @binding(1) var<storage, read_write> pixels: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let pixel = (wg.y * ROW_GROUPS + wg.x) * WORKGROUP_SIZE + li;
    if (pixel >= arrayLength(&pixels) / CHANNELS) {
        return;
    }
    let b = pixel * CHANNELS;
    let out = correct(vec3<f32>(pixels[b], pixels[b + 1u], pixels[b + 2u]));
    pixels[b] = out.x;
    pixels[b + 1u] = out.y;
    pixels[b + 2u] = out.z;
}
