// Sign-preserving per-channel roots, sign(x)·|x|^(1/d), for the generated `model_terms` of
// programs whose terms take roots (RPRM): it computes the roots it needs once per channel and
// builds every term from them (cbrt(R·G²) = cbrt(R)·cbrt(G)²), as nsrm::model::pixel's f64
// evaluator defines them. Not per kind: included wherever a term has a root.

fn sroot2(x: vec3<f32>) -> vec3<f32> {
    return sign(x) * sqrt(abs(x));
}

// Sign-preserving cube root. pow(0, 1/3) is 0 (the base is never negative here); one Newton
// step, y -= (y³ - a) / (3y²), makes it accurate on GPUs whose pow is coarse. The step is only
// taken where it cannot overflow or divide by zero, so 0, Inf and NaN pass through pow alone.
fn sroot3(x: vec3<f32>) -> vec3<f32> {
    let a = abs(x);
    let y0 = pow(a, vec3<f32>(1.0 / 3.0));
    let y1 = y0 - (y0 * y0 * y0 - a) / (3.0 * y0 * y0);
    // Two selects rather than `&` on bool vectors, which some translations reject.
    let y = select(y0, select(y0, y1, a < vec3<f32>(1e30)), a > vec3<f32>(1e-30));
    return sign(x) * y;
}

fn sroot4(x: vec3<f32>) -> vec3<f32> {
    return sign(x) * sqrt(sqrt(abs(x)));
}
