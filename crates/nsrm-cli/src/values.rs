//! The command line's enum flags as clap [`ValueEnum`]s: each mirrors a library enum (the
//! library does not depend on clap), names its values as the library's `parse` does, and converts
//! with `From`. clap checks the value, lists the possible ones in `--help` and in its error
//! (exit status 2). A test checks every name and alias against the library's own parser.

use clap::ValueEnum;

macro_rules! value_enum {
    ($(#[$meta:meta])* $name:ident => $lib:ty, $parse:expr,
     { $($var:ident = $value:literal $(| $alias:literal)*),+ $(,)? }) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
        pub(crate) enum $name {
            $(#[value(name = $value $(, alias = $alias)*)] $var),+
        }

        impl From<$name> for $lib {
            fn from(v: $name) -> $lib {
                match v {
                    $($name::$var => <$lib>::$var),+
                }
            }
        }

        impl $name {
            /// Every name and alias with the value the library's parser gives it.
            #[cfg(test)]
            fn check() {
                let parse: fn(&str) -> Option<$lib> = $parse;
                $(
                    for n in [$value $(, $alias)*] {
                        assert_eq!(parse(n), Some(<$lib>::from($name::$var)), "{n}");
                    }
                )+
            }
        }
    };
}

value_enum!(
    /// `--output-space`.
    Space => nsrm::OutputSpace,
    nsrm::OutputSpace::parse,
    { Xyz = "xyz", LinearSrgb = "linear-srgb", Acescg = "acescg", Aces2065_1 = "aces2065-1" }
);

value_enum!(
    /// `--kind` (one model kind).
    ModelKind => nsrm::Kind,
    |s| nsrm::Kind::parse(s).ok(),
    { Lrm = "lrm", Prm = "prm", Rprm = "rprm", Nsrm = "nsrm" }
);

value_enum!(
    /// `--normalise`.
    Normalise => nsrm::Normalise,
    |s| nsrm::Normalise::parse(s).ok(),
    { Raw = "raw", WhiteBalanced = "white-balanced" | "wb" }
);

value_enum!(
    /// `apply --format`.
    FileFormat => nsrm::io::FileFormat,
    nsrm::io::FileFormat::parse,
    { Exr = "exr" | "openexr", Tiff = "tiff" | "tif" }
);

value_enum!(
    /// `--demosaic` (camera raw inputs).
    Demosaic => nsrm::io::raw::Demosaic,
    nsrm::io::raw::Demosaic::parse,
    { Half = "half", Bilinear = "bilinear", Mhc = "mhc" | "malvar" }
);

value_enum!(
    /// `--highlights` (apply, calibrate).
    Highlights => nsrm::HighlightMode,
    nsrm::HighlightMode::parse,
    { Clip = "clip", Keep = "keep" }
);

value_enum!(
    /// `apply --compression`.
    Compression => nsrm::io::ExrCompression,
    nsrm::io::ExrCompression::parse,
    { Keep = "keep", None = "none", Rle = "rle", Zips = "zips", Zip = "zip", Piz = "piz" }
);

value_enum!(
    /// `--device` (apply, bench).
    Device => nsrm::gpu::DeviceChoice,
    nsrm::gpu::DeviceChoice::parse,
    { Auto = "auto", Gpu = "gpu", Cpu = "cpu" }
);

value_enum!(
    /// `export --format`.
    ExportFormat => nsrm::export::Format,
    nsrm::export::Format::parse,
    { Clf = "clf", Cube = "cube", Ocio = "ocio", Dcp = "dcp", Icc = "icc" }
);

value_enum!(
    /// `export --interpolation`.
    Interpolation => nsrm::export::nodes::Interpolation,
    nsrm::export::nodes::Interpolation::parse,
    { Tetrahedral = "tetrahedral", Trilinear = "trilinear" | "linear" }
);

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

value_enum!(
    /// `--layout` (export-shader, bench).
    Layout => nsrm::Layout,
    nsrm::Layout::parse,
    { Rgb = "rgb", Rgba = "rgba" }
);

/// `--kind`, defined once for `fit` and `terms` (`--model` names a model file everywhere; it is
/// kept as a hidden alias here, the old spelling).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct KindArg {
    /// Model kind: lrm, prm, rprm or nsrm.
    #[arg(long, alias = "model", value_enum, ignore_case = true, default_value_t = ModelKind::Nsrm)]
    pub(crate) kind: ModelKind,
}

/// `--device`, defined once for `apply` and `bench`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct DeviceArg {
    /// Where to run: `auto` (a hardware GPU if there is one, else the CPU path; a software
    /// rasteriser such as Mesa's lavapipe is slower than the CPU path and is used only by `gpu`
    /// or when named by --adapter / NSRM_ADAPTER; the choice and its reason are printed), `gpu`
    /// (any GPU adapter, or an error) or `cpu`.
    #[arg(long, value_enum, ignore_case = true, default_value_t = Device::Auto)]
    pub(crate) device: Device,
}

/// `--layout`, defined once for every command that takes it (one default: `rgb`, the layout of
/// the frames `apply` reads and writes).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct LayoutArg {
    /// Pixel layout of the buffer: packed f32 `rgb`, or `rgba` (alpha untouched).
    #[arg(long, value_enum, ignore_case = true, default_value_t = Layout::Rgb)]
    pub(crate) layout: Layout,
}

value_enum!(
    /// `--chart`.
    Chart => nsrm::chart::ChartKind,
    |s| nsrm::chart::ChartKind::parse(s).ok(),
    { Cc24 = "cc24", Sg = "sg" }
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_value_parses_as_the_library_parses_it() {
        Space::check();
        ModelKind::check();
        Normalise::check();
        Demosaic::check();
        FileFormat::check();
        Compression::check();
        Highlights::check();
        Device::check();
        ExportFormat::check();
        Interpolation::check();
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
        Layout::check();
        Chart::check();
    }

    #[test]
    fn every_library_value_has_a_flag_value() {
        use nsrm::OutputSpace;
        for (s, name) in OutputSpace::ALL {
            assert_eq!(OutputSpace::from(Space::from_str(name, false).unwrap()), s);
        }
        for k in nsrm::Kind::ALL {
            let v = ModelKind::from_str(k.name(), true).unwrap();
            assert_eq!(nsrm::Kind::from(v), k);
        }
        for (c, name) in nsrm::io::ExrCompression::ALL {
            assert_eq!(
                nsrm::io::ExrCompression::from(Compression::from_str(name, false).unwrap()),
                c
            );
        }
    }
}
