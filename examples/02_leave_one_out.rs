//! The paper's experiment as library calls: leave-one-out CIEDE2000 of every model.
//!
//! `cargo run --release --example 02_leave_one_out [REFLECTANCES.csv PATCHES]`, e.g.
//! `… ../shared/data/colorchecker_sg_140.csv B2:M9` for the ColorChecker SG's inner 96 patches.

use nsrm::Kind;
use nsrm::{evaluate, Protocol};
use nsrm::{simulate_named, Grid};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let refl = args.first().map(String::as_str).unwrap_or("rawtoaces-190");
    let patches = args.get(1).map(String::as_str).unwrap_or("all");
    for ill in ["D65", "TL865", "LED-B5"] {
        let data = simulate_named("nikon-d5100", ill, refl, &Grid::default())?.select(patches)?;
        for kind in Kind::ALL {
            let r = evaluate(kind, 3, &data, Protocol::LeaveOneOut, ill)?;
            println!(
                "{ill:7} {kind:5} {:2} terms  mean {:.2}  median {:.2}  max {:.2}",
                r.terms, r.stats.mean, r.stats.median, r.stats.max
            );
        }
    }
    Ok(())
}
