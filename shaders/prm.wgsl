// PRM: XYZ = M·p(R, G, B), p = every monomial of degree 1..order (no constant term).
// Pixel policy (as nsrm::model's f64 reference): NaN / Inf propagate, negative channels are
// used as they are, nothing is clamped (highlights extrapolate the polynomial).

fn correct(rgb: vec3<f32>) -> vec3<f32> {
    return model_terms(rgb);
}
