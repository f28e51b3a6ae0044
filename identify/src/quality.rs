//! Whether an identification describes the data it came from: the checks `maglab identify` runs
//! on its own result before it writes the file, and the warnings it prints and records in the
//! file's provenance (`provenance.warnings`).
//!
//! An identification always produces a file (the least-squares fits have a solution whatever the
//! data), so a file is no evidence that the model fits. These checks compare the identified
//! model's residual on the data it was fitted to with what a rod that the model describes leaves.
//! Measured on the bench plant's blind suite (seed 1, 32 cases, identified case by case with
//! `lab/tests/identified_suite.rs`): without an effect the reversal sweep's displacement NRMSE is
//! 0.1–0.3 % and the sines fitted for `R_eddy`, `ξ`, `f0` leave 1.0–2.0 % RMS NRMSE (largest
//! single experiment 2.9 %); with creep, stick-slip, thermal drift or a sensor nonlinearity the
//! sweep's NRMSE was 10–78 %. With these limits the 4 cases without an effect got no warning,
//! all 8 out-of-library cases and 12 of the 20 library-effect cases got one; the other 8 (sensor
//! lags, loads, a ΔE, reversible magnetization) were absorbed by the identified file so fully
//! that it fits its data — only `maglab diagnose`'s held-out band can show them. On seed 2 one
//! noise-only case was warned, rightly: its experiments continue one another undocumented, the
//! identification took them as starting from positive saturation, and its constants came out
//! 20–40 % off (R_eddy 40.5 Ω for 70). A warning does
//! not stop the identification (the
//! file may still be the best available); it says the model does not describe the data, so the
//! file should not be trusted before `maglab diagnose` has said why.

use crate::masses::{FileReport, StartFrom};

/// A quasi-static record's displacement NRMSE above this is warned about (the model's own
/// records stay below 1 %).
pub const QUASI_STATIC_NRMSE_LIMIT: f64 = 0.02;

/// The RMS NRMSE over the fitted dynamic experiments above this is warned about (2 % without an
/// effect: noise and the model's resolution).
pub const DYNAMIC_NRMSE_LIMIT: f64 = 0.05;

/// The sum of the Preisach masses outside this range of `M_s` is warned about: the weights are
/// meant to saturate the loop at `±M_s` (a reversible part may add to it, up to about a third on
/// the bench plant).
pub const MASS_SUM_RANGE: [f64; 2] = [0.5, 1.5];

/// What the masses are checked against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Masses {
    /// A rod the coil saturates: the masses sum to about `M_s` ([`MASS_SUM_RANGE`]).
    Saturating {
        /// Σ w, A/m.
        sum_a_per_m: f64,
    },
    /// A grid around the reach: the masses cover what the coil switches, the offset the rest;
    /// only `|M_off| + Σ w` beyond `M_s` is wrong.
    Reach {
        /// Σ w, A/m.
        sum_a_per_m: f64,
        /// `M_off`, A/m.
        offset_a_per_m: f64,
    },
}

/// One dynamic experiment's fit, as far as the checks need it.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicResidual {
    /// File name.
    pub file: String,
    /// Fundamental, Hz.
    pub frequency_hz: f64,
    /// NRMSE of the final fit over its steady-state window.
    pub nrmse: f64,
}

/// What a missed quasi-static record's warning adds about its start state: an estimated start
/// may be the miss (the memory outside a loop sets an offset of `M`, so a wrong start misses the
/// whole record).
fn start_caveat(start_from: StartFrom) -> &'static str {
    match start_from {
        StartFrom::Given | StartFrom::Documented => "",
        StartFrom::Estimated => {
            ", or its start state, which dataset.json does not document and was estimated \
             (document it)"
        }
        StartFrom::EstimatedForPrevious => {
            ", or its start state: dataset.json documents it `previous`, but a quasi-static \
             record is not continued from the records before it, so its start was estimated \
             without the memory they left (record it from a documented reset: demagnetized or a \
             saturation)"
        }
    }
}

/// The warnings for an identification: `files` are the quasi-static records' reports,
/// `mass_sum_a_per_m` the sum of the identified masses, `saturation_a_per_m` `M_s`, `dynamic` the
/// final fit's residual per dynamic experiment and `fitted_up_to_hz` the highest fundamental the
/// fit used (the experiments above it are predicted, not fitted, and are not judged here: the
/// diagnosis holds them out). Empty when everything is within the limits.
pub fn warnings(
    files: &[FileReport],
    masses: Masses,
    saturation_a_per_m: f64,
    dynamic: &[DynamicResidual],
    fitted_up_to_hz: Option<f64>,
) -> Vec<String> {
    let mut out = Vec::new();
    for f in files {
        if let Some(nrmse) = f
            .nrmse_displacement
            .filter(|e| *e > QUASI_STATIC_NRMSE_LIMIT)
        {
            let above = f.above_stroke as f64 / (f.samples.max(1)) as f64;
            out.push(format!(
                "{}: the identified Preisach model misses the quasi-static displacement by {:.1} % \
                 NRMSE (limit {:.0} %; {:.0} % of the samples lie above the file's full stroke): \
                 something other than rate-independent hysteresis moves the rod during the sweep \
                 (drift, creep, friction, a sensor nonlinearity), or the base file's stroke \
                 constants do not match this rod{}",
                f.file,
                100.0 * nrmse,
                100.0 * QUASI_STATIC_NRMSE_LIMIT,
                100.0 * above,
                start_caveat(f.start_from)
            ));
        }
    }
    match masses {
        Masses::Saturating { sum_a_per_m } => {
            let ratio = sum_a_per_m / saturation_a_per_m;
            if !(MASS_SUM_RANGE[0]..=MASS_SUM_RANGE[1]).contains(&ratio) {
                out.push(format!(
                    "the identified masses sum to {:.2} x M_s (expected {}-{}): the loop of the \
                     file does not saturate where the data do",
                    ratio, MASS_SUM_RANGE[0], MASS_SUM_RANGE[1]
                ));
            }
        }
        Masses::Reach {
            sum_a_per_m,
            offset_a_per_m,
        } => {
            let ratio = (sum_a_per_m + offset_a_per_m.abs()) / saturation_a_per_m;
            if ratio > MASS_SUM_RANGE[1] {
                out.push(format!(
                    "the model's magnetization reaches {:.2} x M_s (|offset| + sum of masses; at \
                     most {} expected): the file's M_s or stroke constants do not match this rod",
                    ratio, MASS_SUM_RANGE[1]
                ));
            }
        }
    }
    let fitted: Vec<&DynamicResidual> = dynamic
        .iter()
        .filter(|d| fitted_up_to_hz.is_none_or(|hz| d.frequency_hz <= hz * 1.01))
        .collect();
    if !fitted.is_empty() {
        let rms =
            (fitted.iter().map(|d| d.nrmse * d.nrmse).sum::<f64>() / fitted.len() as f64).sqrt();
        if rms > DYNAMIC_NRMSE_LIMIT {
            let worst = fitted
                .iter()
                .max_by(|a, b| a.nrmse.total_cmp(&b.nrmse))
                .expect("not empty");
            out.push(format!(
                "the dynamic model with the identified R_eddy, xi, f0 misses the sines it was \
                 fitted to by {:.1} % RMS NRMSE (limit {:.0} %; worst {} at {:.0} Hz, {:.1} %): \
                 an effect the model lacks is in these data, or a start state estimated for \
                 experiments that dataset.json does not document is wrong (document them), and \
                 the identified constants have absorbed what they could of it; run `maglab \
                 diagnose` on the same folder before using the file",
                100.0 * rms,
                100.0 * DYNAMIC_NRMSE_LIMIT,
                worst.file,
                worst.frequency_hz,
                100.0 * worst.nrmse
            ));
        }
    }
    out
}

/// The dynamic constants in the order of the `[f64; 3]` arrays below.
pub const DYNAMIC_CONSTANT_NAMES: [&str; 3] = ["R_eddy", "xi", "f0"];

/// A constant this close to an end of its search range (a factor) is at that end.
pub const AT_BOUND: f64 = 1.01;

/// Whether `value` lies at an end of the search `centre` ×/÷ `factor` (within [`AT_BOUND`]):
/// `Some(true)` the upper end, `Some(false)` the lower, `None` inside.
pub fn at_search_bound(value: f64, centre: f64, factor: f64) -> Option<bool> {
    if value <= centre / factor * AT_BOUND {
        Some(false)
    } else if value >= centre * factor / AT_BOUND {
        Some(true)
    } else {
        None
    }
}

/// The warnings for identified dynamic constants that lie at an end of their search range:
/// `identified` and `centre` are `[R_eddy Ω, ξ, f0 Hz]` (the identified values and the base
/// file's, which centre the search), `factors` how far the search reaches on each side.
///
/// The fit stopped there because the sines ask for a value beyond it: either the base file's
/// value is far from this rod's, or the constant has absorbed an effect the model lacks (a lag —
/// the sensor's, the amplifier's, a load's — reads as a lower resonance and slower eddy
/// currents). Measured on the bench plant's identified suite (seeds 1–4, 128 folders identified
/// from a datasheet's base: `cargo run --release -p maglab-identify --example bound_scan --
/// FOLDERS`): no constant at a bound in the 16 cases without an effect, in 2 of the 32 with an
/// out-of-library effect, 20 of the 67 with library effects (lags; of them 14 diagnosed wrong
/// afterwards) and 7 of the 13 with thermal drift.
pub fn search_bound_warnings(
    identified: [f64; 3],
    centre: [f64; 3],
    factors: [f64; 3],
) -> Vec<String> {
    const UNITS: [&str; 3] = ["ohm", "", "Hz"];
    let mut out = Vec::new();
    for k in 0..3 {
        let (value, c, f) = (identified[k], centre[k], factors[k]);
        let (name, unit) = (DYNAMIC_CONSTANT_NAMES[k], UNITS[k]);
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        let end = match at_search_bound(value, c, f) {
            Some(false) => Some(("lower", c / f, "/")),
            Some(true) => Some(("upper", c * f, "x")),
            None => None,
        };
        if let Some((side, bound, op)) = end {
            out.push(format!(
                "{name} = {value:.4}{unit} lies at the {side} end of the identification's search \
                 ({c:.4}{unit} {op} {f} = {bound:.4}{unit}, from the base file): the sines ask for \
                 a value beyond it. Either the base file's {name} is far from this rod's (identify \
                 again with a closer one), or {name} has absorbed an effect the model lacks (a \
                 sensor, amplifier or load lag reads as a lower f0 and R_eddy); run `maglab \
                 diagnose` on the same folder before using the file"
            ));
        }
    }
    out
}
