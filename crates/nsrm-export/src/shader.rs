//! Self-contained compute shaders with a model's matrix baked in (no uniform), in WGSL or
//! translated by naga to SPIR-V, GLSL, HLSL or MSL (`nsrm export-shader`).
//!
//! The shader corrects packed f32 pixels in place: one storage buffer, group 0 binding 1,
//! `R G B` or `R G B A` (alpha untouched); the pixel count is the bound range's length.
//! Entry point `main`, workgroup size 256. Dispatch G = ceil(pixels / 256) workgroups as
//! `(G, 1, 1)` if G ≤ 256, else `(256, ceil(G / 256), 1)`.

use nsrm::gpu::{validate_wgsl, GpuError, ENTRY_POINT};
use nsrm::{Layout, Model};

/// An output language.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ShaderLang {
    /// WGSL, the generated source itself.
    Wgsl,
    /// GLSL 450.
    Glsl,
    /// HLSL shader model 5.1.
    Hlsl,
    /// Metal Shading Language 2.0.
    Msl,
    /// SPIR-V 1.0 words (little-endian).
    Spirv,
}

impl ShaderLang {
    /// Every language, in the order `--lang` lists them.
    pub const ALL: [ShaderLang; 5] = [
        ShaderLang::Wgsl,
        ShaderLang::Glsl,
        ShaderLang::Hlsl,
        ShaderLang::Msl,
        ShaderLang::Spirv,
    ];

    /// `wgsl`, `glsl`, `hlsl`, `msl` or `spirv`.
    pub fn name(self) -> &'static str {
        match self {
            ShaderLang::Wgsl => "wgsl",
            ShaderLang::Glsl => "glsl",
            ShaderLang::Hlsl => "hlsl",
            ShaderLang::Msl => "msl",
            ShaderLang::Spirv => "spirv",
        }
    }

    /// Parses a name (case-insensitive; `spv` for SPIR-V, `metal` for MSL also taken).
    pub fn parse(s: &str) -> Option<ShaderLang> {
        match s.trim().to_ascii_lowercase().as_str() {
            "wgsl" => Some(ShaderLang::Wgsl),
            "glsl" => Some(ShaderLang::Glsl),
            "hlsl" => Some(ShaderLang::Hlsl),
            "msl" | "metal" => Some(ShaderLang::Msl),
            "spirv" | "spv" | "spir-v" => Some(ShaderLang::Spirv),
            _ => None,
        }
    }
}

fn err(lang: ShaderLang, e: impl std::fmt::Display) -> GpuError {
    GpuError::Export {
        lang: lang.name().into(),
        message: e.to_string(),
    }
}

/// The shader for `model` on `layout` in `lang`: UTF-8 text, or SPIR-V words (little-endian).
/// The WGSL is the generated source itself (comments kept); the others are naga's
/// translations of it: GLSL 450 (`#version 450`), HLSL shader model 5.1, MSL 2.0, SPIR-V 1.0.
///
/// The shader corrects packed f32 pixels in place: one storage buffer, group 0 binding 1,
/// `R G B` or `R G B A` (alpha untouched); the pixel count is the bound range's length.
/// Entry point `main`, workgroup size 256. Dispatch G = ceil(pixels / 256) workgroups as
/// `(G, 1, 1)` if G ≤ 256, else `(256, ceil(G / 256), 1)`.
///
/// ```
/// use nsrm_export::{export_shader, ShaderLang};
/// use nsrm::{Kind, Layout, Model};
/// let model = Model::from_matrix(Kind::Lrm, 1, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])?;
/// let glsl = export_shader(&model, Layout::Rgba, ShaderLang::Glsl)?;
/// assert!(String::from_utf8(glsl)?.starts_with("#version 450"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn export(model: &Model, layout: Layout, lang: ShaderLang) -> Result<Vec<u8>, GpuError> {
    let src = nsrm::gpu::baked_wgsl(model, layout);
    let (module, info) = validate_wgsl(&src)?;
    let stage = naga::ShaderStage::Compute;
    let out = match lang {
        ShaderLang::Wgsl => src.into_bytes(),
        ShaderLang::Spirv => {
            let options = naga::back::spv::Options {
                flags: naga::back::spv::WriterFlags::empty(),
                ..Default::default()
            };
            let words = naga::back::spv::write_vec(
                &module,
                &info,
                &options,
                Some(&naga::back::spv::PipelineOptions {
                    shader_stage: stage,
                    entry_point: ENTRY_POINT.into(),
                }),
            )
            .map_err(|e| err(lang, e))?;
            words.iter().flat_map(|w| w.to_le_bytes()).collect()
        }
        ShaderLang::Glsl => {
            let mut text = String::new();
            // The pixel buffer keeps its WGSL binding number: `layout(binding = 1)`.
            let binding_map = [(
                naga::ResourceBinding {
                    group: 0,
                    binding: 1,
                },
                1u8,
            )]
            .into_iter()
            .collect();
            let options = naga::back::glsl::Options {
                version: naga::back::glsl::Version::Desktop(450),
                writer_flags: naga::back::glsl::WriterFlags::empty(),
                binding_map,
                ..Default::default()
            };
            let pipeline = naga::back::glsl::PipelineOptions {
                shader_stage: stage,
                entry_point: ENTRY_POINT.into(),
                multiview: None,
            };
            naga::back::glsl::Writer::new(
                &mut text,
                &module,
                &info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .and_then(|mut w| w.write().map(|_| ()))
            .map_err(|e| err(lang, e))?;
            text.into_bytes()
        }
        ShaderLang::Hlsl => {
            let mut text = String::new();
            let options = naga::back::hlsl::Options::default();
            let pipeline = naga::back::hlsl::PipelineOptions {
                entry_point: Some((stage, ENTRY_POINT.into())),
            };
            naga::back::hlsl::Writer::new(&mut text, &options, &pipeline)
                .write(&module, &info, None)
                .map_err(|e| err(lang, e))?;
            text.into_bytes()
        }
        ShaderLang::Msl => {
            let options = naga::back::msl::Options {
                lang_version: (2, 0),
                ..Default::default()
            };
            let pipeline = naga::back::msl::PipelineOptions {
                entry_point: Some((stage, ENTRY_POINT.into())),
                ..Default::default()
            };
            let (text, _) = naga::back::msl::write_string(&module, &info, &options, &pipeline)
                .map_err(|e| err(lang, e))?;
            text.into_bytes()
        }
    };
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nsrm::Kind;

    fn validate(module: &naga::Module) {
        nsrm::gpu::validate_naga_module(module).unwrap();
    }

    #[test]
    fn every_language_translates_and_reads_back() {
        for kind in Kind::ALL {
            for order in [1u8, 3, 4] {
                let l = nsrm::pixel::terms(kind, kind.effective_order(order)).len();
                let matrix = (0..3 * l).map(|i| (i as f64 - 7.0) * 0.37).collect();
                let model = Model::from_matrix(kind, order, matrix).unwrap();
                for layout in [Layout::Rgb, Layout::Rgba] {
                    let what = format!("{kind} {order} {}", layout.name());
                    let wgsl = String::from_utf8(export(&model, layout, ShaderLang::Wgsl).unwrap())
                        .unwrap();
                    let (m, _) = validate_wgsl(&wgsl).unwrap();
                    assert!(
                        !m.global_variables
                            .iter()
                            .any(|(_, g)| g.space == naga::AddressSpace::Uniform),
                        "{what}: baked shaders have no uniform"
                    );
                    let spv = export(&model, layout, ShaderLang::Spirv).unwrap();
                    assert_eq!(
                        &spv[..4],
                        &0x0723_0203u32.to_le_bytes(),
                        "{what}: SPIR-V magic"
                    );
                    let m = naga::front::spv::parse_u8_slice(&spv, &Default::default())
                        .unwrap_or_else(|e| panic!("{what}: {e}"));
                    validate(&m);
                    assert_eq!(m.entry_points[0].name, ENTRY_POINT);
                    assert_eq!(m.entry_points[0].workgroup_size, [256, 1, 1]);
                    let glsl = String::from_utf8(export(&model, layout, ShaderLang::Glsl).unwrap())
                        .unwrap();
                    let m = naga::front::glsl::Frontend::default()
                        .parse(&naga::ShaderStage::Compute.into(), &glsl)
                        .unwrap_or_else(|e| panic!("{what}: {}\n{glsl}", e.emit_to_string(&glsl)));
                    validate(&m);
                    for lang in [ShaderLang::Hlsl, ShaderLang::Msl] {
                        let text =
                            String::from_utf8(export(&model, layout, lang).unwrap()).unwrap();
                        assert!(text.contains("main"), "{what} {lang:?}");
                        assert!(text.len() > 500, "{what} {lang:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn languages_parse() {
        for l in ShaderLang::ALL {
            assert_eq!(ShaderLang::parse(l.name()), Some(l));
        }
        assert_eq!(ShaderLang::parse("SPV"), Some(ShaderLang::Spirv));
        assert_eq!(ShaderLang::parse("cuda"), None);
    }
}
