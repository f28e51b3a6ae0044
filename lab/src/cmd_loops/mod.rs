//! `maglab loops`: the hysteresis loops of the Preisach operator `M = Γ[H]` (paper Section 2)
//! for one parameter set, traced with the no_std core exactly as the firmware evaluates it.
//!
//! Starting from the demagnetized state (the staircase along `α = -β`) it traces
//! * the initial magnetization curve, from the centre of the field range up to `h_max`;
//! * the major loop between `h_min` and `h_max` (saturating at `±Σw`, `= ±M_s` for the default
//!   measure);
//! * symmetric minor loops `±A` around the centre, each from a fresh demagnetized state (first
//!   `+A`, then `-A`, then the recorded cycle `-A → +A → -A`); by the wiping-out property the
//!   recorded cycle closes exactly and each lies inside the loops of larger amplitude;
//! * a biased minor loop like the controller drives: the magnetization band that the static model
//!   (6), `y = l_m λ_s M² / M_s²`, maps onto the trajectory's displacement band
//!   `[displacement_min_m, displacement_max_m]`, reached from the demagnetized state with the
//!   core's exact inverse (up to `M_hi`, down to `M_lo`) and then cycled.
//!
//! It prints `M` on the branches at a few fields, and per loop the coercive fields (exact inverse
//! `Γ⁻¹(0)` on each branch), the remanences (`M` at the centre field), the hysteresis loss
//! `μ0 ∮ H dM` and the closure error; it plots `M` against `H` (`loops.png/.svg`) and the static
//! model's displacement `y` against the current `I = H / c0` (`displacement.png/.svg`, the
//! butterfly curve).

mod plot;
mod report;
mod trace;

use trace::{trace, LoopSet};

use crate::params_io;
use anyhow::Result;
use clap::Parser;
use std::path::PathBuf;

/// Arguments of `maglab loops`.
#[derive(Debug, Parser)]
pub struct Args {
    /// Parameter file (JSON, see docs/params.md); default: the parameters baked into this build.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Directory for loops.png/.svg and displacement.png/.svg.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Amplitudes of the symmetric minor loops around the centre of the field range, kA/m,
    /// comma-separated. Default: 2/3, 2/5 and 1/5 of the half-range.
    #[arg(long, value_name = "KA_PER_M", value_delimiter = ',', num_args = 1..)]
    amplitudes: Vec<f64>,
    /// Samples per monotone branch.
    #[arg(long, default_value_t = 400, value_parser = clap::value_parser!(u32).range(10..=100_000))]
    points: u32,
}

/// Default minor-loop amplitudes as fractions of the half-range `(h_max - h_min) / 2`.
const DEFAULT_AMPLITUDE_FRACTIONS: [f64; 3] = [2.0 / 3.0, 2.0 / 5.0, 1.0 / 5.0];
/// Runs `maglab loops`.
pub fn run(args: &Args) -> Result<()> {
    let loaded = params_io::load(args.params.as_deref())?;
    let measure = loaded.measure();
    let grid = &loaded.params.preisach;
    let half_range = 0.5 * f64::from(grid.h_max_a_per_m - grid.h_min_a_per_m);
    let amplitudes_a_per_m: Vec<f64> = if args.amplitudes.is_empty() {
        DEFAULT_AMPLITUDE_FRACTIONS
            .iter()
            .map(|f| f * half_range)
            .collect()
    } else {
        args.amplitudes.iter().map(|a| a * 1e3).collect()
    };
    let set = trace(&loaded, &measure, &amplitudes_a_per_m, args.points as usize)?;
    report::print_report(&loaded, &measure, &set)?;
    let files = plot::plot(&loaded, &set, &args.out)?;
    println!();
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
