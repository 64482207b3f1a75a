// LRM: XYZ = M·(R, G, B).
// Pixel policy (as nsrm::model's f64 reference): NaN / Inf propagate, negative channels are
// used as they are, nothing is clamped.

fn correct(rgb: vec3<f32>) -> vec3<f32> {
    return model_terms(rgb);
}
