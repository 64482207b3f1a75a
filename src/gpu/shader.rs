//! WGSL generation: the model's pixel program ([`crate::model::pixel`], the one description of
//! what every apply path does with a pixel) printed as WGSL, between the hand-written sources in
//! `shaders/` that are not per kind (bindings and indexing, the root helpers).
//!
//! A shader is assembled from
//! 1. a generated header of constants (`CHANNELS`, `WORKGROUP_SIZE`, `ROW_GROUPS`, `TILE_SIZE`,
//!    `N_TERMS`),
//! 2. the model's coefficients: `shaders/model_uniform.wgsl` (a uniform the [`Corrector`]
//!    rewrites to swap models) or, for exported shaders, literals baked into the code,
//! 3. `shaders/roots.wgsl` (sign-preserving roots) where a term takes a root,
//! 4. the frame file (`shaders/frame_{buffer,in_place,texture}.wgsl`: bindings and `main`),
//! 5. the printed program: `fn correct(rgb) -> vec3<f32>`: first `fn highlights` (the model's
//!    highlight policy, `shaders/highlights.wgsl` with the uniform's parameters; exported,
//!    baked shaders have no clip level and keep the raw mapping), then one block per step of
//!    the program (input gains, NSRM's signal and black rule, the combine, the rescale), and
//! 6. the printed `fn model_terms(x) -> vec3<f32>`: `Σ_j M[:, j] · term_j(x)` over the term list,
//!    and, where the program has a gain step, `fn model_gain() -> vec3<f32>` (from the uniform,
//!    or baked).
//!
//! [`Corrector`]: super::Corrector

use super::GpuError;
use crate::frame::Layout;
use crate::model::highlights::Highlights;
use crate::model::pixel::{Program, Step};
use crate::model::{term_name, terms, Kind, Model, Term};
use std::fmt::Write as _;

/// Threads per workgroup of the buffer shaders (one pixel each).
pub(crate) const WORKGROUP_SIZE: u32 = 256;
/// Workgroups per dispatch row of the buffer shaders: a dispatch of `G` workgroups is
/// `(G, 1, 1)` when `G <= ROW_GROUPS`, else `(ROW_GROUPS, ceil(G / ROW_GROUPS), 1)`.
pub(crate) const ROW_GROUPS: u32 = 256;
/// Side of the square workgroup of the texture shader.
pub(crate) const TILE_SIZE: u32 = 16;
/// The entry point of every shader.
pub const ENTRY_POINT: &str = "main";

/// The hand-written WGSL sources, by file name: none of them per kind.
pub(crate) const SOURCES: [(&str, &str); 6] = [
    (
        "model_uniform.wgsl",
        include_str!("../../shaders/model_uniform.wgsl"),
    ),
    (
        "frame_buffer.wgsl",
        include_str!("../../shaders/frame_buffer.wgsl"),
    ),
    (
        "frame_in_place.wgsl",
        include_str!("../../shaders/frame_in_place.wgsl"),
    ),
    (
        "frame_texture.wgsl",
        include_str!("../../shaders/frame_texture.wgsl"),
    ),
    ("roots.wgsl", include_str!("../../shaders/roots.wgsl")),
    (
        "highlights.wgsl",
        include_str!("../../shaders/highlights.wgsl"),
    ),
];

fn source(name: &str) -> &'static str {
    SOURCES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
        .expect("every shader file is listed in SOURCES")
}

/// The format of the texture a texture-target [`Corrector`](super::Corrector) writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TexelFormat {
    /// `rgba32float`.
    Rgba32Float,
    /// `rgba16float`.
    Rgba16Float,
}

impl TexelFormat {
    /// The WGSL texel format name.
    pub(crate) fn wgsl(self) -> &'static str {
        match self {
            TexelFormat::Rgba32Float => "rgba32float",
            TexelFormat::Rgba16Float => "rgba16float",
        }
    }

    /// The wgpu texture format.
    pub fn texture_format(self) -> wgpu::TextureFormat {
        match self {
            TexelFormat::Rgba32Float => wgpu::TextureFormat::Rgba32Float,
            TexelFormat::Rgba16Float => wgpu::TextureFormat::Rgba16Float,
        }
    }

    /// The texel format of a wgpu format, if a corrector can write it.
    pub(crate) fn from_texture_format(f: wgpu::TextureFormat) -> Option<TexelFormat> {
        match f {
            wgpu::TextureFormat::Rgba32Float => Some(TexelFormat::Rgba32Float),
            wgpu::TextureFormat::Rgba16Float => Some(TexelFormat::Rgba16Float),
            _ => None,
        }
    }
}

/// What a shader reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// Packed f32 storage buffers: `src` (read) → `dst` (written), or one buffer corrected in
    /// place (`in_place`).
    Buffer {
        /// RGB or RGBA packing of the buffers.
        layout: Layout,
        /// One buffer corrected in place (else `src` → `dst`).
        in_place: bool,
    },
    /// A float texture read with `textureLoad` → a write-only storage texture of `format`.
    Texture {
        /// The texel format of both textures.
        format: TexelFormat,
    },
}

impl Target {
    /// Every target the engine and the embedding API use.
    #[cfg(test)]
    pub(crate) const ALL: [Target; 6] = [
        Target::Buffer {
            layout: Layout::Rgb,
            in_place: false,
        },
        Target::Buffer {
            layout: Layout::Rgba,
            in_place: false,
        },
        Target::Buffer {
            layout: Layout::Rgb,
            in_place: true,
        },
        Target::Buffer {
            layout: Layout::Rgba,
            in_place: true,
        },
        Target::Texture {
            format: TexelFormat::Rgba32Float,
        },
        Target::Texture {
            format: TexelFormat::Rgba16Float,
        },
    ];

    /// The frame file this target uses.
    pub(crate) fn frame_file(self) -> &'static str {
        match self {
            Target::Buffer {
                in_place: false, ..
            } => "frame_buffer.wgsl",
            Target::Buffer { in_place: true, .. } => "frame_in_place.wgsl",
            Target::Texture { .. } => "frame_texture.wgsl",
        }
    }

    /// The workgroup size of the target's entry point.
    #[cfg(test)]
    pub(crate) fn workgroup_size(self) -> [u32; 3] {
        match self {
            Target::Buffer { .. } => [WORKGROUP_SIZE, 1, 1],
            Target::Texture { .. } => [TILE_SIZE, TILE_SIZE, 1],
        }
    }

    fn channels(self) -> u32 {
        match self {
            Target::Buffer { layout, .. } => layout.channels() as u32,
            Target::Texture { .. } => 4,
        }
    }

    fn describe(self) -> String {
        match self {
            Target::Buffer { layout, in_place } => format!(
                "{} f32 storage buffer{}",
                layout.name(),
                if in_place { ", in place" } else { "s" }
            ),
            Target::Texture { format } => format!("texture -> {} storage texture", format.wgsl()),
        }
    }
}

/// Where the matrix comes from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Coefficients<'a> {
    /// The uniform of `shaders/model_uniform.wgsl` (binding 0), rewritten to swap models.
    Uniform,
    /// Baked into the shader as constants (exported, self-contained shaders).
    Baked(&'a Model),
}

/// The WGSL literal of an f32 that reads back as the same f32.
fn f32_literal(v: f32) -> String {
    let s = format!("{v:?}");
    if s.contains(['.', 'e', 'E']) {
        format!("{s}f")
    } else {
        format!("{s}.0f")
    }
}

/// The matrix as `L` columns `(m[0][j], m[1][j], m[2][j], 0)` in f32, the layout of the uniform.
pub(crate) fn matrix_columns(model: &Model) -> Vec<[f32; 4]> {
    columns(model.matrix(), model.terms().len())
}

/// The columns of a row-major 3×`l` matrix, as [`matrix_columns`].
fn columns(matrix: &[f64], l: usize) -> Vec<[f32; 4]> {
    (0..l)
        .map(|j| {
            [
                matrix[j] as f32,
                matrix[l + j] as f32,
                matrix[2 * l + j] as f32,
                0.0,
            ]
        })
        .collect()
}

/// The uniform's contents: the [`matrix_columns`], then the input gains `(g_R, g_G, g_B, 0)`
/// (`shaders/model_uniform.wgsl`'s `gain`), then the highlight policy's `clip` and `neutral`
/// ([`Highlights::uniform`]): `L + 3` × `vec4<f32>`.
pub(crate) fn uniform_data(model: &Model) -> Vec<[f32; 4]> {
    let mut v = uniform_data_of(model.matrix(), model.terms().len(), model.input_gains());
    let n = v.len();
    v[n - 2..].copy_from_slice(&Highlights::uniform(model.highlights()));
    v
}

/// [`uniform_data`] of a row-major 3×`l` matrix and input gains (any pixel program's), with no
/// highlight policy.
pub(crate) fn uniform_data_of(matrix: &[f64], l: usize, gains: [f64; 3]) -> Vec<[f32; 4]> {
    let mut v = columns(matrix, l);
    v.push([gains[0] as f32, gains[1] as f32, gains[2] as f32, 0.0]);
    v.extend(crate::model::highlights::uniform_off());
    v
}

/// The generated `fn highlights(x) -> vec3<f32>` that `correct` starts with: the policy of
/// `shaders/highlights.wgsl` with the uniform's parameters; in a baked shader the model's policy
/// as literals, or none where the model has none (an exported shader runs where no clip level is
/// known: the raw mapping is kept).
pub(crate) fn highlights_fn(coefficients: Coefficients<'_>) -> String {
    let body = match coefficients {
        Coefficients::Uniform => "highlights_with(x, model.clip, model.neutral.xyz)".to_string(),
        Coefficients::Baked(m) => match m.highlights() {
            None => "x".to_string(),
            Some(h) => {
                let [c, n] = Highlights::uniform(Some(h));
                let lit = |v: &[f32]| v.iter().map(|x| f32_literal(*x)).collect::<Vec<_>>();
                format!(
                    "highlights_with(x, vec4<f32>({}), vec3<f32>({}))",
                    lit(&c).join(", "),
                    lit(&n[..3]).join(", ")
                )
            }
        },
    };
    format!(
        "// The highlight policy (nsrm::model::highlights) before the pixel program.\nfn highlights(x: vec3<f32>) -> vec3<f32> {{\n    return {body};\n}}\n"
    )
}

/// Whether the shader carries `shaders/highlights.wgsl`: every uniform shader, and a baked one
/// whose model has a highlight policy.
fn has_highlights(coefficients: Coefficients<'_>) -> bool {
    match coefficients {
        Coefficients::Uniform => true,
        Coefficients::Baked(m) => m.highlights().is_some(),
    }
}

/// The generated `fn model_gain() -> vec3<f32>` of NSRM shaders: the input gains, read from the
/// uniform or baked in.
pub(crate) fn model_gain_fn(coefficients: Coefficients<'_>) -> String {
    let body = match coefficients {
        Coefficients::Uniform => "model.gain.xyz".to_string(),
        Coefficients::Baked(m) => {
            let g = m.input_gains();
            format!(
                "vec3<f32>({}, {}, {})",
                f32_literal(g[0] as f32),
                f32_literal(g[1] as f32),
                f32_literal(g[2] as f32)
            )
        }
    };
    format!(
        "// The input gains multiplied into R, G, B (1, 1, 1 unless white-balanced).\nfn model_gain() -> vec3<f32> {{\n    return {body};\n}}\n"
    )
}

/// The printed term expansion: `fn model_terms(x: vec3<f32>) -> vec3<f32>` returning
/// `Σ_j M[:, j] · term_j(x)` over the program's term list, with `x` the variables after the steps
/// before [`Step::Combine`] ((R, G, B), or (r, g, 0) after [`Step::Normalise`]).
///
/// Roots are computed once per channel (`q2 = sroot2(x)`, `q3 = sroot3(x)`, `q4 = sroot4(x)`,
/// from `shaders/roots.wgsl`) and shared by every term; each term is the product of its
/// channels' factors, as the f64 evaluator ([`crate::model::terms::expand`]) computes it.
pub(crate) fn model_terms_fn(program: &Program<'_>, coefficients: Coefficients<'_>) -> String {
    let list = program.terms;
    let cols = match coefficients {
        Coefficients::Uniform => None,
        Coefficients::Baked(m) => Some(matrix_columns(m)),
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// Printed from the term list of nsrm::model::terms ({:?}): {} terms.",
        program.kind,
        list.len()
    );
    let _ = writeln!(s, "fn model_terms(x: vec3<f32>) -> vec3<f32> {{");
    for root in 2..=4u8 {
        if list.iter().any(|t| t.root == root) {
            let _ = writeln!(s, "    let q{root} = sroot{root}(x);");
        }
    }
    let _ = writeln!(s, "    var acc = vec3<f32>(0.0);");
    for (j, t) in list.iter().enumerate() {
        let coef = match &cols {
            None => format!("model.m[{j}].xyz"),
            Some(c) => format!(
                "vec3<f32>({}, {}, {})",
                f32_literal(c[j][0]),
                f32_literal(c[j][1]),
                f32_literal(c[j][2])
            ),
        };
        let _ = writeln!(
            s,
            "    acc += {coef} * {}; // {}",
            term_expr(t),
            term_name(program.kind, t)
        );
    }
    let _ = writeln!(s, "    return acc;");
    let _ = writeln!(s, "}}");
    s
}

/// The printed pixel program: `fn correct(rgb: vec3<f32>) -> vec3<f32>`, one block per
/// [`Step`], in the program's order (every step is spelled here; a new one does not compile
/// until it is).
pub(crate) fn correct_fn(program: &Program<'_>) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// The pixel program of nsrm::model::pixel ({:?}): {}.",
        program.kind,
        program
            .steps
            .iter()
            .map(|st| format!("{st:?}"))
            .collect::<Vec<_>>()
            .join(" -> ")
    );
    let _ = writeln!(
        s,
        "// NaN / Inf propagate, negative channels are used as they are, nothing is clamped."
    );
    let _ = writeln!(s, "fn correct(rgb: vec3<f32>) -> vec3<f32> {{");
    let _ = writeln!(s, "    var x = highlights(rgb);");
    let _ = writeln!(s, "    var y = vec3<f32>(0.0);");
    for step in program.steps {
        let _ = writeln!(s, "    // {:?}: {}", step, step.describe());
        match step {
            Step::Gain => {
                let _ = writeln!(s, "    x = x * model_gain();");
            }
            Step::Normalise => {
                let _ = writeln!(s, "    let s = x.x + x.y + x.z;");
                let _ = writeln!(s, "    if (s <= 0.0) {{");
                let _ = writeln!(s, "        return vec3<f32>(0.0);");
                let _ = writeln!(s, "    }}");
                let _ = writeln!(s, "    x = vec3<f32>(x.x / s, x.y / s, 0.0);");
            }
            Step::Combine => {
                let _ = writeln!(s, "    y = model_terms(x);");
            }
            Step::Rescale => {
                let _ = writeln!(s, "    y = s * y;");
            }
        }
    }
    let _ = writeln!(s, "    return y;");
    let _ = writeln!(s, "}}");
    s
}

/// The WGSL expression of one term over `x` and the per-channel roots `q2`, `q3`, `q4`: the
/// product of the factors of [`crate::model::terms::term_factors`].
fn term_expr(t: &Term) -> String {
    let factors: Vec<String> = crate::model::terms::term_factors(t)
        .into_iter()
        .map(|(c, root)| {
            let comp = ["x", "y", "z"][c];
            match root {
                1 => format!("x.{comp}"),
                r => format!("q{r}.{comp}"),
            }
        })
        .collect();
    if factors.is_empty() {
        "1.0".into()
    } else {
        format!("({})", factors.join(" * "))
    }
}

/// The complete WGSL source of the correction shader for `kind` at `order`, `target`, with the
/// matrix from `coefficients`. The entry point is [`ENTRY_POINT`].
pub(crate) fn wgsl(
    kind: Kind,
    order: u8,
    target: Target,
    coefficients: Coefficients<'_>,
) -> String {
    let order = kind.effective_order(order);
    let list = terms(kind, order);
    wgsl_program(&Program::new(kind, &list), order, target, coefficients)
}

/// [`wgsl`] for any pixel program (the printer itself): `order` is for the header comment only.
pub(crate) fn wgsl_program(
    program: &Program<'_>,
    order: u8,
    target: Target,
    coefficients: Coefficients<'_>,
) -> String {
    let kind = program.kind;
    let n_terms = program.terms.len();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// nsrm: {kind} order {order} ({n_terms} terms) colour correction, {}.",
        target.describe()
    );
    let _ = writeln!(
        s,
        "// Assembled by nsrm::gpu::shader: the pixel program of nsrm::model::pixel printed as WGSL, with shaders/*.wgsl."
    );
    if let Coefficients::Baked(m) = coefficients {
        let _ = writeln!(
            s,
            "// Self-contained: the fitted matrix is baked in (white XYZ {:?}).",
            m.white_xyz()
        );
        if !m.has_unit_gains() {
            let _ = writeln!(
                s,
                "// White-balanced NSRM: R, G, B are multiplied by the input gains {:?} first.",
                m.input_gains()
            );
        }
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "const CHANNELS: u32 = {}u;", target.channels());
    let _ = writeln!(s, "const WORKGROUP_SIZE: u32 = {WORKGROUP_SIZE}u;");
    let _ = writeln!(s, "const ROW_GROUPS: u32 = {ROW_GROUPS}u;");
    let _ = writeln!(s, "const TILE_SIZE: u32 = {TILE_SIZE}u;");
    let _ = writeln!(s, "const N_TERMS: u32 = {n_terms}u;");
    let _ = writeln!(s);
    if let Coefficients::Uniform = coefficients {
        let _ = writeln!(s, "// ---- shaders/model_uniform.wgsl");
        s.push_str(source("model_uniform.wgsl"));
        let _ = writeln!(s);
    }
    if has_highlights(coefficients) {
        let _ = writeln!(s, "// ---- shaders/highlights.wgsl");
        s.push_str(source("highlights.wgsl"));
        let _ = writeln!(s);
    }
    if !program.roots().is_empty() {
        let _ = writeln!(s, "// ---- shaders/roots.wgsl");
        s.push_str(source("roots.wgsl"));
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "// ---- shaders/{}", target.frame_file());
    let frame = source(target.frame_file());
    match target {
        Target::Texture { format } => s.push_str(&frame.replace("TEXEL_FORMAT", format.wgsl())),
        Target::Buffer { .. } => s.push_str(frame),
    }
    let _ = writeln!(s);
    s.push_str(&highlights_fn(coefficients));
    s.push_str(&correct_fn(program));
    let _ = writeln!(s);
    s.push_str(&model_terms_fn(program, coefficients));
    if program.has(Step::Gain) {
        s.push_str(&model_gain_fn(coefficients));
    }
    s
}

/// The self-contained WGSL source of `model`'s correction on `layout` (the matrix as constants,
/// no uniform): packed f32 pixels corrected in place in one storage buffer, group 0 binding 1;
/// entry point [`ENTRY_POINT`], workgroup size 256. What `nsrm-export` bakes and translates.
pub fn baked_wgsl(model: &Model, layout: crate::Layout) -> String {
    wgsl(
        model.kind(),
        model.order(),
        Target::Buffer {
            layout,
            in_place: true,
        },
        Coefficients::Baked(model),
    )
}

/// Parses and validates WGSL with naga (all validation flags, default capabilities).
pub fn validate(src: &str) -> Result<(naga::Module, naga::valid::ModuleInfo), GpuError> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| GpuError::Shader {
        stage: "WGSL parse",
        message: e.emit_to_string(src),
    })?;
    let info = validate_module(&module).map_err(|e| GpuError::Shader {
        stage: "WGSL validation",
        message: e.emit_to_string(src),
    })?;
    Ok((module, info))
}

/// Validates a naga module (from any front end) with the flags every shader here is held to:
/// all validation flags, default capabilities.
pub fn validate_module(
    module: &naga::Module,
) -> Result<naga::valid::ModuleInfo, Box<naga::WithSpan<naga::valid::ValidationError>>> {
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(module)
    .map_err(Box::new)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::MAX_ORDER;

    fn model(kind: Kind, order: u8) -> Model {
        let l = terms(kind, kind.effective_order(order)).len();
        let matrix = (0..3 * l).map(|i| 0.5 + i as f64 * 0.25).collect();
        let m = Model::from_matrix(kind, order, matrix).unwrap();
        if kind == Kind::Nsrm {
            // Non-unit input gains (white-balanced NSRM), baked as literals.
            m.with_input_gains([1.5, 1.0, 0.75]).unwrap()
        } else {
            m
        }
    }

    #[test]
    fn every_generated_variant_validates_with_naga() {
        let mut seen_files = std::collections::HashSet::new();
        for kind in Kind::ALL {
            for order in 1..=MAX_ORDER {
                let m = model(kind, order);
                for target in Target::ALL {
                    for coef in [Coefficients::Uniform, Coefficients::Baked(&m)] {
                        let src = wgsl(kind, order, target, coef);
                        let (module, _) = validate(&src).unwrap_or_else(|e| {
                            panic!("{kind} {order} {target:?}: {e}\n{src}");
                        });
                        assert_eq!(module.entry_points.len(), 1);
                        let ep = &module.entry_points[0];
                        assert_eq!(ep.name, ENTRY_POINT);
                        assert_eq!(ep.stage, naga::ShaderStage::Compute);
                        assert_eq!(ep.workgroup_size, target.workgroup_size());
                        for (name, text) in SOURCES {
                            if src.contains(text.trim())
                                || (name == "frame_texture.wgsl"
                                    && matches!(target, Target::Texture { .. }))
                            {
                                seen_files.insert(name);
                            }
                        }
                        let uniform = module
                            .global_variables
                            .iter()
                            .any(|(_, g)| g.space == naga::AddressSpace::Uniform);
                        assert_eq!(uniform, matches!(coef, Coefficients::Uniform));
                    }
                }
            }
        }
        // Every hand-written file took part in some validated variant.
        assert_eq!(seen_files.len(), SOURCES.len(), "{seen_files:?}");
    }

    fn terms_fn(kind: Kind, order: u8) -> String {
        let list = terms(kind, order);
        model_terms_fn(&Program::new(kind, &list), Coefficients::Uniform)
    }

    #[test]
    fn generated_expansion_follows_the_term_table() {
        let src = terms_fn(Kind::Rprm, 3);
        assert!(src.contains("let q2 = sroot2(x);"));
        assert!(src.contains("let q3 = sroot3(x);"));
        assert!(!src.contains("sroot4"));
        assert!(src.contains("acc += model.m[6].xyz * (q3.x * q3.y * q3.y); // cbrt(R*G^2)"));
        assert_eq!(src.matches("acc +=").count(), 13);
        let src = terms_fn(Kind::Nsrm, 2);
        assert!(src.contains("acc += model.m[0].xyz * 1.0; // 1"));
        assert!(src.contains("acc += model.m[5].xyz * (x.x * x.y); // r*g"));
        for (kind, counts) in [
            (Kind::Prm, [3, 9, 19, 34]),
            (Kind::Rprm, [3, 6, 13, 22]),
            (Kind::Nsrm, [3, 6, 10, 15]),
        ] {
            for (o, n) in (1..=4).zip(counts) {
                let src = terms_fn(kind, o);
                assert_eq!(src.matches("acc +=").count(), n, "{kind} {o}");
            }
        }
    }

    /// The printer follows the program it is given, not the kind: the steps of one kind over the
    /// terms of another print (and validate) as those steps, in that order.
    #[test]
    fn the_printed_correct_follows_the_program_steps() {
        let nsrm = terms(Kind::Nsrm, 3);
        let prm = terms(Kind::Prm, 2);
        let rprm = terms(Kind::Rprm, 4);
        let cases: [(&Program, &[&str]); 4] = [
            (
                &Program::new(Kind::Nsrm, &nsrm),
                &[
                    "x = x * model_gain();",
                    "if (s <= 0.0) {",
                    "y = model_terms(x);",
                    "y = s * y;",
                ],
            ),
            (&Program::new(Kind::Prm, &prm), &["y = model_terms(x);"]),
            (
                // NSRM's terms without its gain and rescale.
                &Program::custom(Kind::Nsrm, &[Step::Normalise, Step::Combine], &nsrm).unwrap(),
                &["if (s <= 0.0) {", "y = model_terms(x);"],
            ),
            (
                // RPRM's terms behind a gain step.
                &Program::custom(Kind::Rprm, &[Step::Gain, Step::Combine], &rprm).unwrap(),
                &["x = x * model_gain();", "y = model_terms(x);"],
            ),
        ];
        let all = [
            "x = x * model_gain();",
            "if (s <= 0.0) {",
            "y = model_terms(x);",
            "y = s * y;",
        ];
        for (program, want) in cases {
            let src = wgsl_program(program, 3, Target::ALL[0], Coefficients::Uniform);
            validate(&src).unwrap_or_else(|e| panic!("{program:?}: {e}\n{src}"));
            let correct = correct_fn(program);
            let mut last = 0;
            for line in want {
                let at = correct
                    .find(line)
                    .unwrap_or_else(|| panic!("{line} missing: {correct}"));
                assert!(at >= last, "{line} out of order: {correct}");
                last = at;
            }
            for line in all.iter().filter(|l| !want.contains(l)) {
                assert!(!correct.contains(line), "{line} printed: {correct}");
            }
            assert_eq!(src.contains("fn model_gain()"), program.has(Step::Gain));
            assert_eq!(src.contains("fn sroot3("), !program.roots().is_empty());
            assert_eq!(src.matches("acc +=").count(), program.terms.len());
        }
    }

    #[test]
    fn baked_literals_round_trip_in_f32() {
        for v in [1.0f32, -0.0, 0.1, 1e-7, 3.4e38, -123456.79, 1e20] {
            let lit = f32_literal(v);
            let back: f32 = lit.trim_end_matches('f').parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{lit}");
        }
        let m = model(Kind::Lrm, 1);
        let src = wgsl(
            Kind::Lrm,
            1,
            Target::Buffer {
                layout: Layout::Rgb,
                in_place: true,
            },
            Coefficients::Baked(&m),
        );
        assert!(src.contains("vec3<f32>(0.5f, 1.25f, 2.0f)"), "{src}");
        assert!(!src.contains("model_gain"), "{src}");
        let m = model(Kind::Nsrm, 2);
        let src = wgsl(Kind::Nsrm, 2, Target::ALL[0], Coefficients::Baked(&m));
        assert!(
            src.contains("return vec3<f32>(1.5f, 1.0f, 0.75f);"),
            "{src}"
        );
        let src = wgsl(Kind::Nsrm, 2, Target::ALL[0], Coefficients::Uniform);
        assert!(src.contains("return model.gain.xyz;"), "{src}");
        assert_eq!(uniform_data(&m).len(), m.len_terms() + 3);
        assert_eq!(uniform_data(&m)[m.len_terms()], [1.5, 1.0, 0.75, 0.0]);
    }

    /// A baked shader carries the model's highlight policy as literals (and validates); without
    /// one, `highlights` returns the pixel as it is; a uniform shader reads the policy from the
    /// uniform, which holds it after the gains.
    #[test]
    fn baked_shaders_carry_the_highlight_policy() {
        let plain = model(Kind::Nsrm, 2);
        let src = wgsl(Kind::Nsrm, 2, Target::ALL[0], Coefficients::Baked(&plain));
        assert!(src.contains("    return x;\n"), "{src}");
        assert!(!src.contains("fn highlights_with"), "{src}");
        let m = crate::fit(Kind::Nsrm, 2, crate::kit::training())
            .unwrap()
            .with_highlights(Some([1.0; 3]))
            .unwrap();
        let n = m.highlights().unwrap().neutral().map(|v| v as f32);
        for target in Target::ALL {
            let src = wgsl(Kind::Nsrm, 2, target, Coefficients::Baked(&m));
            validate(&src).unwrap_or_else(|e| panic!("{e}\n{src}"));
            let want = format!(
                "highlights_with(x, vec4<f32>(1.0f, 1.0f, 1.0f, 1.0f), vec3<f32>({}, {}, {}))",
                f32_literal(n[0]),
                f32_literal(n[1]),
                f32_literal(n[2])
            );
            assert!(src.contains(&want), "{want}\n{src}");
        }
        let u = uniform_data(&m);
        let l = m.len_terms();
        assert_eq!(u[l + 1], [1.0, 1.0, 1.0, 1.0]);
        assert_eq!(&u[l + 2][..3], &n[..]);
        assert_eq!(uniform_data(&plain)[plain.len_terms() + 1][3], 0.0);
    }
}
