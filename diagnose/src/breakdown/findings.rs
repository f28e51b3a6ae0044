//! The "where" breakdown in words: one finding per sentence, each from one part of
//! [`Where`]. The limits below decide only how a finding is worded (agrees / is off, which
//! branch is larger), never a verdict; each is about the smallest difference the loop and Bode
//! plots of the report show at a glance.

use super::{BandSummary, Where};
use maglab_dataset::data::Measurement;
use maglab_model::drift::drift_warning;
use maglab_model::experiments::ExperimentInfo;
use std::ops::RangeInclusive;

/// A phase error of the displacement's main harmonic below this in every band agrees, degrees.
const PHASE_AGREES_DEG: f64 = 2.0;

/// Measured/model amplitude ratios of the main harmonic within this range agree (±2 %).
const AMPLITUDE_AGREES: RangeInclusive<f64> = 0.98..=1.02;

/// A DC error below this share of an experiment's own motion agrees.
const DC_AGREES_SHARE: f64 = 0.01;

/// A harmonic's measured and model amplitudes differ when they are apart by more than this
/// many noise σ.
const HARMONIC_NOISE_FACTOR: f64 = 2.0;

/// Ratios of two parts' RMS residuals (ascending/descending branch, late/early third) within
/// this range count as equal: about 1.5× either way.
const PARTS_EQUAL: RangeInclusive<f64> = 0.67..=1.5;

/// The residual concentrates near current reversals when their RMS is above this many times
/// the mid-branch one, and mid-branch when below [`MID_BRANCH_RATIO`].
const NEAR_REVERSAL_RATIO: f64 = 1.3;

/// See [`NEAR_REVERSAL_RATIO`] (about its inverse).
const MID_BRANCH_RATIO: f64 = 0.77;

/// The plain-language findings of `w` (`noise_m` the white-noise level), in the report's order:
/// where the gap starts, which harmonic the figures are of, phase, amplitude, DC level,
/// harmonics, branches, reversals, drift within a record.
pub(super) fn summarize(w: &Where, noise_m: f64) -> Vec<String> {
    let (Some(first), Some(last)) = (w.bands.first(), w.bands.last()) else {
        return Vec::new();
    };
    let mut out = vec![onset(w, first, last, noise_m)];
    let harmonic = match unbiased_bands(w) {
        Some(finding) => {
            out.push(finding);
            "the displacement's main harmonic"
        }
        None => "the fundamental",
    };
    out.push(phase(w, first, last, harmonic));
    out.push(amplitude(w, first, last, harmonic));
    out.push(dc_level(w));
    out.extend(harmonics(w, noise_m));
    out.extend(record_parts(w));
    out
}

/// Where the gap starts (the onset rule of the module docs of [`super`]).
fn onset(w: &Where, first: &BandSummary, last: &BandSummary, noise_m: f64) -> String {
    match w.gap_start_hz {
        Some(f) if f <= first.frequency_hz => format!(
            "The model disagrees at every frequency tested ({:.0}-{:.0} Hz): the systematic gap is \
             {:.1} % of the motion at {:.0} Hz and {:.1} % at {:.0} Hz.",
            first.frequency_hz,
            last.frequency_hz,
            100.0 * first.relative_gap,
            first.frequency_hz,
            100.0 * last.relative_gap,
            last.frequency_hz
        ),
        Some(f) => format!(
            "The gap starts at about {f:.0} Hz: up to {:.0} Hz the model agrees within max(2x noise, \
             1 % of the motion); at {:.0} Hz the systematic gap is {:.1} % of the motion.",
            w.bands
                .iter()
                .filter(|b| b.frequency_hz < f)
                .map(|b| b.frequency_hz)
                .fold(0.0, f64::max),
            last.frequency_hz,
            100.0 * last.relative_gap
        ),
        None => {
            let worst = w
                .bands
                .iter()
                .max_by(|a, b| a.relative_gap.total_cmp(&b.relative_gap))
                .unwrap_or(first);
            if worst.disagrees {
                format!(
                    "The model disagrees only in some bands (worst {:.0} Hz, gap {:.1} % of the \
                     motion) and agrees at the highest frequency tested.",
                    worst.frequency_hz,
                    100.0 * worst.relative_gap
                )
            } else {
                format!(
                    "The model agrees in every band within max(2x noise, 1 % of the motion) \
                     (noise level {noise_m:.2e} m)."
                )
            }
        }
    }
}

/// When some bands are driven without DC bias, which harmonic the phase and amplitude figures
/// are of there (`displacement_order`); `None` when every band's is the fundamental.
fn unbiased_bands(w: &Where) -> Option<String> {
    if w.bands.iter().all(|b| b.displacement_order == 1) {
        return None;
    }
    let doubled = w.bands.iter().filter(|b| b.displacement_order == 2).count();
    Some(format!(
        "In {doubled} of {} bands the drive has no DC bias: the displacement, even in M, \
         repeats twice per current period, and the phase and amplitude below are those of its \
         largest harmonic there (the second).",
        w.bands.len()
    ))
}

/// The phase error of `harmonic` over the bands.
fn phase(w: &Where, first: &BandSummary, last: &BandSummary, harmonic: &str) -> String {
    let largest_deg = w
        .bands
        .iter()
        .map(|b| b.phase_error_deg)
        .fold(0.0f64, |m, p| if p.abs() > m.abs() { p } else { m });
    if largest_deg.abs() < PHASE_AGREES_DEG {
        return format!("The phase of {harmonic} agrees within 2 deg in every band.");
    }
    let at_hz = w
        .bands
        .iter()
        .find(|b| b.phase_error_deg == largest_deg)
        .map_or(0.0, |b| b.frequency_hz);
    format!(
        "Phase error of {harmonic} grows from {:+.1} deg at {:.0} Hz to {:+.1} deg at {:.0} Hz \
         (largest {largest_deg:+.1} deg at {at_hz:.0} Hz; negative = the measurement lags the model).",
        first.phase_error_deg, first.frequency_hz, last.phase_error_deg, last.frequency_hz
    )
}

/// The amplitude ratio of `harmonic` over the bands.
fn amplitude(w: &Where, first: &BandSummary, last: &BandSummary, harmonic: &str) -> String {
    let (lowest, highest) = w.bands.iter().fold((f64::MAX, f64::MIN), |(a, b), band| {
        (a.min(band.amplitude_ratio), b.max(band.amplitude_ratio))
    });
    if lowest >= *AMPLITUDE_AGREES.start() && highest <= *AMPLITUDE_AGREES.end() {
        return format!("The amplitude of {harmonic} agrees within 2 % in every band.");
    }
    format!(
        "The amplitude of {harmonic} is off: measured/model from {lowest:.3} to {highest:.3} \
         ({:.3} at {:.0} Hz, {:.3} at {:.0} Hz).",
        first.amplitude_ratio, first.frequency_hz, last.amplitude_ratio, last.frequency_hz
    )
}

/// The worst experiment's DC error, as a share of its own displacement range.
fn dc_level(w: &Where) -> String {
    let worst = w
        .experiments
        .iter()
        .map(|e| {
            let range_m = (e.rms_m / e.relative_rms.max(1e-300)).max(1e-300);
            (e.dc_error_m.abs() / range_m, e)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match worst {
        Some((share, e)) if share >= DC_AGREES_SHARE => format!(
            "The DC level is off by up to {:.1} % of an experiment's own motion ({}: {:+.3e} m).",
            100.0 * share,
            e.name,
            e.dc_error_m
        ),
        _ => "The DC level agrees (within 1 % of the motion in every experiment).".into(),
    }
}

/// The largest difference between a measured and a model harmonic (orders 2–4), when above
/// the noise.
fn harmonics(w: &Where, noise_m: f64) -> Option<String> {
    let mut worst = (0.0f64, 0usize, 0.0f64);
    for e in &w.experiments {
        for h in &e.harmonics {
            let d = (h.measured_m - h.model_m).abs();
            if d > worst.0 {
                worst = (d, h.order, e.fundamental_hz);
            }
        }
    }
    let (difference_m, order, at_hz) = worst;
    (difference_m > HARMONIC_NOISE_FACTOR * noise_m).then(|| {
        format!(
            "Harmonics differ: the largest difference is in harmonic {order} at {at_hz:.0} Hz \
             ({difference_m:.2e} m)."
        )
    })
}

/// Where in the records the residual is: ascending or descending branch, near reversals or
/// mid-branch, early or late.
fn record_parts(w: &Where) -> Vec<String> {
    let p = &w.parts;
    let ratio = |a: f64, b: f64| a / b.max(1e-300);
    let mut out = Vec::new();
    let ascending = ratio(p.ascending_rms_m, p.descending_rms_m);
    out.push(if PARTS_EQUAL.contains(&ascending) {
        "Ascending and descending branches are equally affected.".into()
    } else {
        format!(
            "The residual is larger on the {} branch ({:.2e} m vs {:.2e} m).",
            if ascending > 1.0 {
                "ascending"
            } else {
                "descending"
            },
            p.ascending_rms_m.max(p.descending_rms_m),
            p.ascending_rms_m.min(p.descending_rms_m)
        )
    });
    let reversal = ratio(p.near_reversal_rms_m, p.mid_branch_rms_m);
    if reversal > NEAR_REVERSAL_RATIO {
        out.push(format!(
            "The residual concentrates near current reversals ({:.2e} m vs {:.2e} m mid-branch).",
            p.near_reversal_rms_m, p.mid_branch_rms_m
        ));
    } else if reversal < MID_BRANCH_RATIO {
        out.push(format!(
            "The residual is largest mid-branch ({:.2e} m vs {:.2e} m near reversals).",
            p.mid_branch_rms_m, p.near_reversal_rms_m
        ));
    }
    let late = ratio(p.late_rms_m, p.early_rms_m);
    out.push(if PARTS_EQUAL.contains(&late) {
        "Early and late parts of each record agree equally (no drift).".into()
    } else {
        format!(
            "The residual {} during each record (last third {:.2e} m vs first third {:.2e} m): \
             a slow drift.",
            if late > 1.0 { "grows" } else { "shrinks" },
            p.late_rms_m,
            p.early_rms_m
        )
    });
    out
}

/// The quasi-static records that read one state differently on their returns to it (module
/// docs of [`super`]), one finding each.
pub(super) fn drift_findings(
    measurements: &[Measurement],
    infos: &[ExperimentInfo],
) -> Vec<String> {
    measurements
        .iter()
        .zip(infos)
        .filter(|(_, info)| info.quasi_static)
        .filter_map(|(m, info)| {
            drift_warning(&info.name, &m.t_s, &m.current_a, &m.displacement_m)
                .map(|w| format!("Drift in a quasi-static record: {w}."))
        })
        .collect()
}
