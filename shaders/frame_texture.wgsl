// Texture frame: camera RGB(A) is read with `textureLoad` from `src` (any float format:
// rgba32float, rgba16float, ...), corrected, and written with alpha to the write-only storage
// texture `dst`, whose format (TEXEL_FORMAT: rgba32float or rgba16float) is filled in by
// `nsrm::gpu::shader`. `src` and `dst` have the same size. Dispatch:
// (ceil(width / TILE_SIZE), ceil(height / TILE_SIZE), 1).

@group(0) @binding(1) var src: texture_2d<f32>;
@group(0) @binding(2) var dst: texture_storage_2d<TEXEL_FORMAT, write>;

@compute @workgroup_size(TILE_SIZE, TILE_SIZE, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(dst);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let xy = vec2<i32>(id.xy);
    let px = textureLoad(src, xy, 0);
    textureStore(dst, xy, vec4<f32>(correct(px.rgb), px.a));
}
