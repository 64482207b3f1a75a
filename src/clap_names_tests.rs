//! The `clap` feature's flag values are the library's own names: every value and alias clap
//! accepts for an enum is one its `parse` reads as the same variant, so the command line, the
//! model file, the studio and the bindings name each variant alike.

use clap::ValueEnum;

/// Every name and alias of every variant of `T` parses (`parse`) as that variant.
fn names_parse_back<T: ValueEnum + PartialEq + std::fmt::Debug>(parse: impl Fn(&str) -> Option<T>) {
    for v in T::value_variants() {
        let p = v.to_possible_value().expect("no variant is skipped");
        for n in p.get_name_and_aliases() {
            assert_eq!(parse(n).as_ref(), Some(v), "{n}");
        }
    }
}

#[test]
fn every_flag_value_is_the_library_s_name() {
    names_parse_back(crate::OutputSpace::parse);
    names_parse_back(|s| crate::Kind::parse(s).ok());
    names_parse_back(|s| crate::Normalise::parse(s).ok());
    names_parse_back(crate::HighlightMode::parse);
    names_parse_back(crate::Layout::parse);
    #[cfg(feature = "io")]
    {
        names_parse_back(crate::io::FileFormat::parse);
        names_parse_back(crate::io::ExrCompression::parse);
        names_parse_back(crate::io::Demosaic::parse);
    }
    #[cfg(feature = "gpu")]
    names_parse_back(crate::gpu::DeviceChoice::parse);
    #[cfg(feature = "export")]
    {
        names_parse_back(crate::export::Format::parse);
        names_parse_back(crate::export::nodes::Interpolation::parse);
    }
    #[cfg(feature = "chart")]
    names_parse_back(|s| crate::chart::ChartKind::parse(s).ok());
}

#[test]
fn every_variant_has_a_flag_value() {
    for (s, name) in crate::OutputSpace::ALL {
        assert_eq!(crate::OutputSpace::from_str(name, false), Ok(s));
    }
    for k in crate::Kind::ALL {
        assert_eq!(crate::Kind::from_str(k.name(), true), Ok(k));
    }
    #[cfg(feature = "io")]
    for (c, name) in crate::io::ExrCompression::ALL {
        assert_eq!(crate::io::ExrCompression::from_str(name, false), Ok(c));
    }
}
