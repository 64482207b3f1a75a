//! The training set's data: the patches (labels, camera RGB, XYZ, whites) and where they came
//! from. `spectral` simulates it, `chart` reads it from a photographed chart, and `training`
//! (which re-exports these types) reads and writes its CSV file and selects patches.

use serde::{Deserialize, Serialize};

/// Where a training set came from; written into model files.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// `spectral` (simulated from spectra) or `measured` (a user's CSV).
    pub source: String,
    /// The camera's sensitivities (simulated data: a built-in name or a file).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub camera: Option<String>,
    /// The illuminant (simulated data).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub illuminant: Option<String>,
    /// The reflectances (simulated data).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub reflectances: Option<String>,
    /// The wavelength grid, `start:end:step` nm (simulated data).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub grid: Option<String>,
    /// The `--patches` selection, if one was applied.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub patches: Option<String>,
    /// Patches read from a photographed chart (`--capture`).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub capture: Option<CaptureProvenance>,
}

/// Where patches read from a chart capture came from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CaptureProvenance {
    /// The frame's file name.
    pub frame: String,
    /// SHA-256 of the frame file's bytes (hex).
    pub sha256: String,
    /// `cc24` or `sg`.
    pub chart: String,
    /// The reference values (a built-in name or a file).
    pub reference: String,
    /// `corners` or `detected`.
    pub located: String,
    /// Excluded patches with their flags, e.g. `19 white 9.5 (clipped)`.
    pub excluded: Vec<String>,
    /// How camera RGB was normalised before fitting.
    pub exposure_normalisation: String,
    /// Camera G of the perfect white implied by the neutral patches (median of 100 G / Y).
    pub white_g: f64,
    /// Flat-field compensation: `none`, `flat frame` or `neutral patches`, and the estimated
    /// non-uniformity of the light (max/min over the chart).
    pub flat: String,
    /// The estimated non-uniformity of the light (max/min over the chart).
    pub light_nonuniformity: f64,
    /// Median ΔE00 of the patches against the reference after the best 3×3 linear map.
    pub reference_match_de00: f64,
    /// How the frame's values were decoded: `linear`, or display-referred (sRGB decoded, the
    /// camera's tone curve still in them). Empty in files written before it was recorded.
    #[serde(default)]
    pub encoding: String,
    /// The camera (`make model`) of a camera raw frame, as the file records it; absent for
    /// EXR / TIFF frames and in files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<String>,
    /// The chromaticity of the light the chart was shot under, estimated from the chart's
    /// neutral patches through the raw file's own colour matrices (the DNG `NeutralToXY`
    /// iteration); absent without them (EXR, TIFF, JPEG frames).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_xy: Option<[f64; 2]>,
    /// That light's correlated colour temperature (K).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_cct: Option<f64>,
    /// The patches the model was fitted on (camera RGB, reference XYZ, their white), so that an
    /// export needs no other file; in the order of the model's `patch_labels`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training: Option<CapturedPatches>,
}

/// The training patches of a model fitted on a chart capture, carried in its file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CapturedPatches {
    /// Linear camera RGB, one per patch.
    pub rgb: Vec<[f64; 3]>,
    /// Reference XYZ (relative to `white_xyz`), one per patch.
    pub xyz: Vec<[f64; 3]>,
    /// The white the XYZ are relative to (the Lab white of the fit).
    pub white_xyz: [f64; 3],
}

/// Patches with camera RGB and reference XYZ, and the reference white (for Lab).
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingSet {
    /// The patch labels, one per patch.
    pub labels: Vec<String>,
    /// Linear camera RGB (perfect white: G = 1 for simulated data).
    pub rgb: Vec<[f64; 3]>,
    /// CIE XYZ (perfect white: Y = 100 for simulated data).
    pub xyz: Vec<[f64; 3]>,
    /// XYZ of the perfect white under the illuminant: the Lab reference white.
    pub white_xyz: [f64; 3],
    /// Camera RGB of the perfect white under the illuminant (same scale as `rgb`), when known:
    /// simulated data always has it; measured data does not (name a neutral patch instead).
    /// White-balanced NSRM and `--preserve-white` use it.
    pub white_rgb: Option<[f64; 3]>,
    /// Where the patches came from (written into model files).
    pub provenance: Provenance,
}

impl TrainingSet {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.labels.len()
    }

    /// Whether there are no patches.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }

    /// Records the patches themselves in a capture's provenance (a no-op for other sets), so
    /// that a model fitted on them carries them: call it on the set as fitted (after patch
    /// selection and any adaptation).
    pub fn record_patches(&mut self) {
        if let Some(c) = self.provenance.capture.as_mut() {
            c.training = Some(CapturedPatches {
                rgb: self.rgb.clone(),
                xyz: self.xyz.clone(),
                white_xyz: self.white_xyz,
            });
        }
    }

    /// The training set a model file carries (see [`TrainingSet::record_patches`]): `None`
    /// unless its capture provenance holds one patch per label.
    pub fn recorded(provenance: &Provenance, labels: &[String]) -> Option<TrainingSet> {
        let t = provenance.capture.as_ref()?.training.as_ref()?;
        let ok = t.rgb.len() == labels.len()
            && t.xyz.len() == labels.len()
            && !labels.is_empty()
            && t.rgb.iter().chain(&t.xyz).flatten().all(|v| v.is_finite())
            && t.white_xyz.iter().all(|v| v.is_finite() && *v > 0.0);
        ok.then(|| TrainingSet {
            labels: labels.to_vec(),
            rgb: t.rgb.clone(),
            xyz: t.xyz.clone(),
            white_xyz: t.white_xyz,
            white_rgb: None,
            provenance: provenance.clone(),
        })
    }
}
