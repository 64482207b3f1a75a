//! Simulate a camera from spectra, fit NSRM order 3, and correct one pixel.
//!
//! `cargo run --example 01_fit_nsrm`

use nsrm::{fit, Kind};
use nsrm::{simulate_named, Grid};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Camera RGB and CIE XYZ of the 190 rawtoaces patches under D65 (perfect white: G = 1, Y = 100).
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default())?;
    let model = fit(Kind::Nsrm, 3, &data)?;
    println!(
        "{} order {}: terms {:?}",
        model.kind(),
        model.order(),
        model.term_names()
    );
    let terms = model.matrix().len() / 3;
    for (name, row) in ["α", "β", "γ"]
        .iter()
        .zip(model.matrix().chunks_exact(terms))
    {
        println!("  {name}: {row:?}");
    }
    // Correct the first patch, and the same patch one stop brighter (NSRM scales exactly).
    let rgb = data.rgb[0];
    let xyz = model.apply_f64(rgb);
    let brighter = model.apply_f64([2.0 * rgb[0], 2.0 * rgb[1], 2.0 * rgb[2]]);
    println!(
        "{}: RGB {rgb:.4?} -> XYZ {xyz:.3?} (truth {:.3?})",
        data.labels[0], data.xyz[0]
    );
    println!("one stop brighter -> XYZ {brighter:.3?}");
    // The model file that `nsrm apply` reads.
    let path = std::env::temp_dir().join("nsrm-example-01.json");
    std::fs::write(&path, model.to_json())?;
    println!("model written to {}", path.display());
    Ok(())
}
