//! The vocabulary the rooms' errors share to say what a failure is about, so that a front end
//! can tell the caller's usage mistakes (a malformed or contradictory request: a bad grid or
//! patch spec, an unknown kind, chart or shard, outputs that would collide, a LUT size out of
//! range) from failures of the data, the files or the device, and can name the parameter at
//! fault in its own spelling. Nothing here knows about flags, and nothing here knows the rooms:
//! each error type says for itself, beside its definition, whether it is a usage error (an
//! `is_usage` method) and, where it is about one parameter, which (a `concern` method returning a
//! [`Concern`]). Messages name parameters in words ("the exposure", "the corners").

/// A parameter of a request that an error can be about, named for what it is (the option
/// structs' fields), not for any front end's spelling of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Param {
    /// The most pixels a frame may have (`nsrm_io::Limits::max_pixels`).
    MaxPixels,
    /// The EXR layer holding the camera RGB (`nsrm_io::ReadOptions::layer`).
    Layer,
    /// A rendered chart's exposure (`nsrm_chart::ChartOptions::exposure`).
    Exposure,
    /// A rendered chart's noise (`nsrm_chart::ChartOptions::noise`).
    Noise,
    /// A rendered chart's patch size (`nsrm_chart::ChartOptions::patch_size`).
    PatchSize,
    /// A rendered chart's gap between patches (`nsrm_chart::ChartOptions::gap`).
    Gap,
    /// A rendered chart's columns (`nsrm_chart::ChartOptions::columns`).
    Columns,
    /// The four corners of a photographed chart (`nsrm_chart::ReadingOptions::corners`).
    Corners,
    /// The flat-field frame of a chart capture (`nsrm_chart::FlatField::Frame`).
    Flat,
    /// The reference white of Lab reference values (`nsrm_chart::Reference::load`).
    ReferenceWhite,
    /// The reflectance spectra of a chart (`nsrm_chart::ChartColours::simulate`).
    Reflectances,
    /// A capture's white (clipping) level (`nsrm_chart::ReadingOptions::white_level`).
    WhiteLevel,
    /// The neutral patch a fit takes its white from (`model::White::Patch`).
    WhitePatch,
}

/// How an error concerns a [`Param`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Concern {
    /// The value given for the parameter is malformed, out of range, or does not fit the data.
    Value(Param),
    /// The request failed without the parameter (or with its current value); giving it is the
    /// way out.
    Remedy(Param),
}
