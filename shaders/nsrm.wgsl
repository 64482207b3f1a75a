// NSRM: R, G, B are first multiplied by the input gains (`model_gain()`, generated: 1, 1, 1
// unless the model is white-balanced); then with s = R+G+B, r = R/s, g = G/s, XYZ = s·(M·p(r, g)), p = every monomial in (r, g) of
// degree 0..order.
// Pixel policy (as nsrm::model's f64 reference): s <= 0 (black, or noise around black) gives
// (0, 0, 0); NaN / Inf propagate (`s <= 0` is false for NaN, so NaN flows on); negative
// channels are used as they are while s > 0; nothing is clamped.

fn correct(raw: vec3<f32>) -> vec3<f32> {
    let rgb = raw * model_gain();
    let s = rgb.x + rgb.y + rgb.z;
    if (s <= 0.0) {
        return vec3<f32>(0.0);
    }
    return s * model_terms(vec3<f32>(rgb.x / s, rgb.y / s, 0.0));
}
