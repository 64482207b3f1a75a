//! A minimal OpenColorIO v2 config: the camera colour space (named from the model's provenance)
//! reaches the scene reference — the export's output space — through a `FileTransform` to the CLF
//! written beside the config; the other output spaces follow by matrices from
//! [`crate::colorimetry::output_matrix`], so each is what `nsrm apply --output-space` would write. Roles
//! `scene_linear`, `aces_interchange`, `cie_xyz_d65_interchange`, `default`, `data`; one sRGB
//! display with a `Standard` and a `Raw` view, so `Config::validate` passes.

use super::LutExport;
use crate::colorimetry::spaces::{self, OutputSpace};
use std::fmt::Write as _;

/// The OCIO colour-space name of an output space.
pub(crate) fn space_name(space: OutputSpace) -> &'static str {
    match space {
        OutputSpace::Xyz => "CIE-XYZ-D65",
        OutputSpace::LinearSrgb => "Linear Rec.709 (sRGB)",
        OutputSpace::Acescg => "ACEScg",
        OutputSpace::Aces2065_1 => "ACES2065-1",
    }
}

fn quote(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

fn matrix44(m: &spaces::Mat3) -> String {
    let r = |i: usize| format!("{}, {}, {}, 0", m[i][0], m[i][1], m[i][2]);
    format!("[{}, {}, {}, 0, 0, 0, 1]", r(0), r(1), r(2))
}

/// The config text; `clf_file` is the CLF's file name, resolved beside the config.
pub(crate) fn write(e: &LutExport, clf_file: &str) -> String {
    let w = e.model.white_xyz();
    let reference = e.space;
    let to_ref = crate::colorimetry::output_matrix(w, reference);
    let camera = super::camera_space_name(&e.model);
    let mut s = String::new();
    let _ = writeln!(s, "ocio_profile_version: 2");
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "description: {}",
        quote(&format!(
            "nsrm {}: {}. Scene reference: {} ({}), scene-linear, training white at Y = 1.",
            env!("CARGO_PKG_VERSION"),
            super::provenance_line(&e.model),
            space_name(reference),
            reference.interop_id()
        ))
    );
    let _ = writeln!(s, "search_path: \".\"");
    let _ = writeln!(s, "strictparsing: true");
    let _ = writeln!(s, "luma: [0.2126, 0.7152, 0.0722]");
    let _ = writeln!(s);
    let _ = writeln!(s, "roles:");
    let _ = writeln!(
        s,
        "  aces_interchange: {}",
        quote(space_name(OutputSpace::Aces2065_1))
    );
    let _ = writeln!(
        s,
        "  cie_xyz_d65_interchange: {}",
        quote(space_name(OutputSpace::Xyz))
    );
    let _ = writeln!(s, "  color_picking: \"sRGB Encoded Rec.709\"");
    let _ = writeln!(s, "  data: Raw");
    let _ = writeln!(s, "  default: {}", quote(space_name(reference)));
    let _ = writeln!(s, "  matte_paint: \"sRGB Encoded Rec.709\"");
    let _ = writeln!(s, "  rendering: {}", quote(space_name(reference)));
    let _ = writeln!(s, "  scene_linear: {}", quote(space_name(reference)));
    let _ = writeln!(s, "  texture_paint: \"sRGB Encoded Rec.709\"");
    let _ = writeln!(s);
    let _ = writeln!(s, "file_rules:");
    let _ = writeln!(
        s,
        "  - !<Rule> {{name: Default, colorspace: {}}}",
        quote(space_name(reference))
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "displays:");
    let _ = writeln!(s, "  sRGB:");
    let _ = writeln!(
        s,
        "    - !<View> {{name: Standard, colorspace: \"sRGB Encoded Rec.709\"}}"
    );
    let _ = writeln!(s, "    - !<View> {{name: Raw, colorspace: Raw}}");
    let _ = writeln!(s);
    let _ = writeln!(s, "active_displays: [sRGB]");
    let _ = writeln!(s, "active_views: [Standard, Raw]");
    let _ = writeln!(s);
    let _ = writeln!(s, "colorspaces:");
    // The camera: through the CLF to the reference.
    let _ = writeln!(s, "  - !<ColorSpace>");
    let _ = writeln!(s, "    name: {}", quote(&camera));
    let _ = writeln!(s, "    family: Input");
    let _ = writeln!(s, "    encoding: scene-linear");
    let _ = writeln!(
        s,
        "    description: {}",
        quote(&format!(
            "Linear camera RGB, not white-balanced (training white G = 1), {} model fitted by nsrm",
            e.model.kind()
        ))
    );
    let _ = writeln!(s, "    isdata: false");
    let _ = writeln!(
        s,
        "    to_scene_reference: !<FileTransform> {{src: {}, interpolation: tetrahedral}}",
        quote(clf_file)
    );
    for (space, _) in OutputSpace::ALL {
        let _ = writeln!(s);
        let _ = writeln!(s, "  - !<ColorSpace>");
        let _ = writeln!(s, "    name: {}", quote(space_name(space)));
        let _ = writeln!(s, "    family: Scene-linear");
        let _ = writeln!(s, "    encoding: scene-linear");
        let _ = writeln!(
            s,
            "    description: {}",
            quote(&format!(
                "{} ({}), training white at Y = 1",
                space_name(space),
                space.interop_id()
            ))
        );
        let _ = writeln!(s, "    isdata: false");
        if space != reference {
            // reference → space: (space's output matrix) · (reference's)^-1.
            let m = spaces::mul(
                &crate::colorimetry::output_matrix(w, space),
                &spaces::invert(&to_ref),
            );
            let _ = writeln!(
                s,
                "    from_scene_reference: !<MatrixTransform> {{matrix: {}}}",
                matrix44(&m)
            );
        }
    }
    // The display encoding: linear Rec.709 with the sRGB transfer function.
    let to_709 = spaces::mul(
        &crate::colorimetry::output_matrix(w, OutputSpace::LinearSrgb),
        &spaces::invert(&to_ref),
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "  - !<ColorSpace>");
    let _ = writeln!(s, "    name: \"sRGB Encoded Rec.709\"");
    let _ = writeln!(s, "    family: Display");
    let _ = writeln!(s, "    encoding: sdr-video");
    let _ = writeln!(
        s,
        "    description: \"Rec.709 primaries, sRGB transfer function (no tone mapping)\""
    );
    let _ = writeln!(s, "    isdata: false");
    let _ = writeln!(s, "    from_scene_reference: !<GroupTransform>");
    let _ = writeln!(s, "      children:");
    let _ = writeln!(
        s,
        "        - !<MatrixTransform> {{matrix: {}}}",
        matrix44(&to_709)
    );
    let _ = writeln!(
        s,
        "        - !<ExponentWithLinearTransform> {{gamma: [2.4, 2.4, 2.4, 1], offset: [0.055, 0.055, 0.055, 0], direction: inverse}}"
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "  - !<ColorSpace>");
    let _ = writeln!(s, "    name: Raw");
    let _ = writeln!(s, "    family: Utility");
    let _ = writeln!(s, "    encoding: data");
    let _ = writeln!(s, "    isdata: true");
    s
}
