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
    pub(crate) fn shader(self) -> Option<nsrm_export::shader::ShaderLang> {
        use nsrm_export::shader::ShaderLang as S;
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

/// `--max-pixels`, defined once for every command that reads frames.
#[derive(Debug, Clone, Copy, clap::Args)]
pub(crate) struct MaxPixelsArg {
    /// Most pixels a frame may have (width × height): a file whose header claims more is
    /// refused before anything is allocated; flat frames and the studio's uploads are held to it
    /// too. Default 268435456 (16384 × 16384).
    #[arg(long, value_name = "N", default_value_t = nsrm_io::DEFAULT_MAX_PIXELS,
          value_parser = clap::value_parser!(u64).range(1..))]
    pub(crate) max_pixels: u64,
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

    // The library's enums are the flag values (its `clap` feature): every value and alias clap
    // accepts is one the enum's `parse` reads as the same variant, so the command line, the model
    // file, the studio and the bindings name each variant alike.
    /// Every name and alias of every variant of `T` parses (`parse`) as that variant.
    fn names_parse_back<T: ValueEnum + PartialEq + std::fmt::Debug>(
        parse: impl Fn(&str) -> Option<T>,
    ) {
        for v in T::value_variants() {
            let p = v.to_possible_value().expect("no variant is skipped");
            for n in p.get_name_and_aliases() {
                assert_eq!(parse(n).as_ref(), Some(v), "{n}");
            }
        }
    }

    #[test]
    fn every_flag_value_is_the_library_s_name() {
        names_parse_back(nsrm::OutputSpace::parse);
        names_parse_back(|s| nsrm::Kind::parse(s).ok());
        names_parse_back(|s| nsrm::Normalise::parse(s).ok());
        names_parse_back(nsrm::HighlightMode::parse);
        names_parse_back(nsrm::Layout::parse);
        {
            names_parse_back(nsrm_io::FileFormat::parse);
            names_parse_back(nsrm_io::ExrCompression::parse);
            names_parse_back(nsrm_io::Demosaic::parse);
        }
        names_parse_back(nsrm::gpu::DeviceChoice::parse);
        {
            names_parse_back(nsrm_export::Format::parse);
            names_parse_back(nsrm_export::nodes::Interpolation::parse);
        }
        names_parse_back(|s| nsrm_chart::ChartKind::parse(s).ok());
    }

    #[test]
    fn every_variant_has_a_flag_value() {
        for (s, name) in nsrm::OutputSpace::ALL {
            assert_eq!(nsrm::OutputSpace::from_str(name, false), Ok(s));
        }
        for k in nsrm::Kind::ALL {
            assert_eq!(nsrm::Kind::from_str(k.name(), true), Ok(k));
        }
        for (c, name) in nsrm_io::ExrCompression::ALL {
            assert_eq!(nsrm_io::ExrCompression::from_str(name, false), Ok(c));
        }
    }

    #[test]
    fn every_shader_language_parses_as_the_library_parses_it() {
        for v in Lang::value_variants() {
            let p = v.to_possible_value().unwrap();
            for n in p.get_name_and_aliases() {
                assert_eq!(nsrm_export::shader::ShaderLang::parse(n), v.shader(), "{n}");
            }
        }
    }
}
