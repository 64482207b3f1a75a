//! The flag groups defined once for the commands that share them, and the one enum flag that is
//! the command line's own (`export-shader --lang`: the shader languages and DCTL). Every other
//! enum flag is the library's enum itself (its `clap` feature derives [`ValueEnum`] with the
//! names its `parse` takes).

use clap::ValueEnum;

/// `export-shader --lang`: a compute-shader language, or DaVinci Resolve's DCTL.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Lang {
    Wgsl,
    Glsl,
    Hlsl,
    #[value(alias = "metal")]
    Msl,
    #[value(alias = "spv", alias = "spir-v")]
    Spirv,
    Dctl,
}

impl Lang {
    /// The compute-shader language; `None` for DCTL.
    pub(crate) fn shader(self) -> Option<nsrm::export::shader::ShaderLang> {
        use nsrm::export::shader::ShaderLang as S;
        Some(match self {
            Lang::Wgsl => S::Wgsl,
            Lang::Glsl => S::Glsl,
            Lang::Hlsl => S::Hlsl,
            Lang::Msl => S::Msl,
            Lang::Spirv => S::Spirv,
            Lang::Dctl => return None,
        })
    }
}

/// `--kind`, defined once for `fit` and `terms` (`--model` names a model file everywhere; it is
/// kept as a hidden alias here, the old spelling).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct KindArg {
    /// Model kind: lrm, prm, rprm or nsrm.
    #[arg(long, alias = "model", value_enum, ignore_case = true, default_value_t = nsrm::Kind::Nsrm)]
    pub(crate) kind: nsrm::Kind,
}

/// `--device`, defined once for `apply` and `bench`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct DeviceArg {
    /// Where to run: `auto` (a hardware GPU if there is one, else the CPU path; a software
    /// rasteriser such as Mesa's lavapipe is slower than the CPU path and is used only by `gpu`
    /// or when named by --adapter / NSRM_ADAPTER; the choice and its reason are printed), `gpu`
    /// (any GPU adapter, or an error) or `cpu`.
    #[arg(long, value_enum, ignore_case = true, default_value_t = nsrm::gpu::DeviceChoice::Auto)]
    pub(crate) device: nsrm::gpu::DeviceChoice,
}

/// `--layout`, defined once for every command that takes it (one default: `rgb`, the layout of
/// the frames `apply` reads and writes).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct LayoutArg {
    /// Pixel layout of the buffer: packed f32 `rgb`, or `rgba` (alpha untouched).
    #[arg(long, value_enum, ignore_case = true, default_value_t = nsrm::Layout::Rgb)]
    pub(crate) layout: nsrm::Layout,
}

/// `--overwrite`, defined once for every command that writes files.
#[derive(Debug, Clone, Copy, clap::Args)]
pub(crate) struct OverwriteArg {
    /// Replace outputs that exist (an input is never written). Without it, a command refuses
    /// to replace a file and writes nothing.
    #[arg(long)]
    pub(crate) overwrite: bool,
}

/// `--output-space`, defined once for `apply`, `export` and `export-shader` (each folds it in
/// alike).
#[derive(Debug, Clone, Copy, clap::Args)]
pub(crate) struct OutputSpaceArg {
    /// The colour space of the output. Pixels are scene-linear with the training white at Y = 1:
    /// xyz as the model produces it (the training illuminant's white; D65-referred in an OCIO
    /// config), or linear-srgb, acescg or aces2065-1, whose white is 1, 1, 1 after Bradford
    /// adaptation from the training white. For OCIO: the scene reference.
    #[arg(long, value_enum, ignore_case = true, default_value_t = nsrm::OutputSpace::Xyz)]
    pub(crate) output_space: nsrm::OutputSpace,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shader_language_parses_as_the_library_parses_it() {
        for v in Lang::value_variants() {
            let p = v.to_possible_value().unwrap();
            for n in p.get_name_and_aliases() {
                assert_eq!(
                    nsrm::export::shader::ShaderLang::parse(n),
                    v.shader(),
                    "{n}"
                );
            }
        }
    }
}
