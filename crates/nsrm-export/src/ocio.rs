//! A minimal OpenColorIO v2 config: the camera colour space (named from the model's provenance)
//! reaches the scene reference — the export's output space — through a `FileTransform` to the CLF
//! written beside the config; the other output spaces follow by matrices from
//! [`nsrm::output_matrix`], so each is what `nsrm apply --output-space` would write. Roles
//! `scene_linear`, `aces_interchange`, `cie_xyz_d65_interchange`, `default`, `data`; one sRGB
//! display with a `Standard` and a `Raw` view, so `Config::validate` passes.

use super::LutExport;
use crate::spaces;
use nsrm::OutputSpace;
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

/// The config text; `clf_file` is the CLF's file name, resolved beside the config. Its parts:
/// the header up to the colour spaces (`header`), the camera space (`camera_space`), the
/// output spaces (`scene_linear_spaces`), and the display encoding and `Raw`
/// (`display_spaces`).
pub(crate) fn write(e: &LutExport, clf_file: &str) -> String {
    let w = e.model.white_xyz();
    let reference = e.space;
    let description = format!(
        "nsrm {}: {}. Scene reference: {} ({}), scene-linear, training white at Y = 1.",
        env!("CARGO_PKG_VERSION"),
        super::provenance_line(&e.model),
        space_name(reference),
        reference.interop_id()
    );
    let camera_description = format!(
        "Linear camera RGB, not white-balanced (training white G = 1), {} model fitted by nsrm",
        e.model.kind()
    );
    let mut s = String::new();
    header(&mut s, &description, reference);
    camera_space(
        &mut s,
        &super::camera_space_name(&e.model),
        &camera_description,
        clf_file,
    );
    scene_linear_spaces(&mut s, w, reference);
    display_spaces(&mut s, w, reference);
    s
}

/// The config up to its colour spaces: version, description, roles (the scene-linear ones are
/// `reference`), the file rule, the sRGB display and its views.
fn header(s: &mut String, description: &str, reference: OutputSpace) {
    let _ = writeln!(s, "ocio_profile_version: 2");
    let _ = writeln!(s);
    let _ = writeln!(s, "description: {}", quote(description));
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
}

/// The camera's colour space `name`: through the CLF `clf_file` to the scene reference.
fn camera_space(s: &mut String, name: &str, description: &str, clf_file: &str) {
    let _ = writeln!(s, "  - !<ColorSpace>");
    let _ = writeln!(s, "    name: {}", quote(name));
    let _ = writeln!(s, "    family: Input");
    let _ = writeln!(s, "    encoding: scene-linear");
    let _ = writeln!(s, "    description: {}", quote(description));
    let _ = writeln!(s, "    isdata: false");
    let _ = writeln!(
        s,
        "    to_scene_reference: !<FileTransform> {{src: {}, interpolation: tetrahedral}}",
        quote(clf_file)
    );
}

/// The matrix taking `reference` to `space` for training white `w`: (space's output matrix) ·
/// (reference's)^-1.
fn reference_to(w: [f64; 3], reference: OutputSpace, space: OutputSpace) -> spaces::Mat3 {
    spaces::mul(
        &nsrm::output_matrix(w, space),
        &spaces::invert(&nsrm::output_matrix(w, reference)),
    )
}

/// Every output space, each but `reference` by a matrix from it.
fn scene_linear_spaces(s: &mut String, w: [f64; 3], reference: OutputSpace) {
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
            let _ = writeln!(
                s,
                "    from_scene_reference: !<MatrixTransform> {{matrix: {}}}",
                matrix44(&reference_to(w, reference, space))
            );
        }
    }
}

/// The display encoding (linear Rec.709 with the sRGB transfer function, from `reference`) and
/// `Raw` (data).
fn display_spaces(s: &mut String, w: [f64; 3], reference: OutputSpace) {
    let to_709 = reference_to(w, reference, OutputSpace::LinearSrgb);
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
}

#[cfg(test)]
mod tests {
    use super::*;

    const D65: [f64; 3] = [95.047, 100.0, 108.883];

    #[test]
    fn the_reference_names_the_scene_linear_roles() {
        let mut s = String::new();
        header(&mut s, "a \"quoted\" line", OutputSpace::Acescg);
        assert!(
            s.contains("description: \"a \\\"quoted\\\" line\"\n"),
            "{s}"
        );
        assert!(s.contains("  scene_linear: \"ACEScg\"\n"));
        assert!(s.contains("  aces_interchange: \"ACES2065-1\"\n"));
        assert!(s.ends_with("colorspaces:\n"));
        let mut c = String::new();
        camera_space(&mut c, "cam", "d", "m.clf");
        assert!(
            c.contains("{src: \"m.clf\", interpolation: tetrahedral}"),
            "{c}"
        );
    }

    #[test]
    fn every_space_but_the_reference_has_a_matrix_from_it() {
        let mut s = String::new();
        scene_linear_spaces(&mut s, D65, OutputSpace::Xyz);
        assert_eq!(s.matches("!<ColorSpace>").count(), OutputSpace::ALL.len());
        assert_eq!(
            s.matches("from_scene_reference").count(),
            OutputSpace::ALL.len() - 1
        );
        // The reference to itself is the identity; to another space and back too.
        let id = reference_to(D65, OutputSpace::Acescg, OutputSpace::Acescg);
        let there = reference_to(D65, OutputSpace::Acescg, OutputSpace::LinearSrgb);
        let back = reference_to(D65, OutputSpace::LinearSrgb, OutputSpace::Acescg);
        let round = spaces::mul(&back, &there);
        for i in 0..3 {
            for j in 0..3 {
                let e = f64::from(u8::from(i == j));
                assert!((id[i][j] - e).abs() < 1e-12 && (round[i][j] - e).abs() < 1e-12);
            }
        }
        let mut d = String::new();
        display_spaces(&mut d, D65, OutputSpace::LinearSrgb);
        assert_eq!(d.matches("!<ColorSpace>").count(), 2);
        assert!(d.contains("direction: inverse}"), "{d}");
        assert!(d.ends_with("    isdata: true\n"), "{d}");
    }
}
