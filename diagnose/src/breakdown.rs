//! "Where": the nominal residual (measured − nominal model) broken down per experiment and per
//! frequency band — amplitude ratio and phase error of the displacement's main harmonic (the
//! fundamental; the second harmonic under a drive without DC bias, where the displacement, even in
//! M, repeats twice per current period and its fundamental is noise), DC level, harmonics,
//! ascending vs descending branch, near-reversal vs mid-branch, early vs late in the record — and
//! the plain-language summary of it.
//!
//! **Gap onset** (measured, never assumed). A frequency band *disagrees* when its systematic gap
//! (noise-corrected RMS, as a fraction of the band's measured displacement range) exceeds the
//! larger of `2 σ / range` (twice the white-noise level, so noise alone never makes a gap) and
//! 1 % of the motion (the size of difference a loop plot like the paper's Figure 6 shows). The
//! gap starts at the lowest band from which every higher band disagrees. Every band is judged on
//! its own data, whatever the parameters were identified on.
//!
//! **Drift** (a finding of its own, whatever the model): hysteresis returns to the same state
//! each time a quasi-static record revisits an extreme of its current after the other one
//! (wiping out), so a reading that differs there beyond `maglab_model::drift::DRIFT_LIMIT` of the
//! record's range is something that depends on time (the coil heating the rod, creep, a drifting
//! sensor) or friction, and masses fitted to that record absorb it. The same check warns in
//! `maglab identify`; here it covers the records being diagnosed.

use maglab_dataset::data::Measurement;
use maglab_model::drift::drift_warning;
use maglab_model::experiments::ExperimentInfo;
use maglab_model::residual::systematic;
use maglab_signal::{branches, spectrum};
use serde::Serialize;

/// Harmonic content of one order.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Harmonic {
    /// Order (2 = twice the fundamental).
    pub order: usize,
    /// Measured amplitude, m.
    pub measured_m: f64,
    /// Nominal model amplitude, m.
    pub model_m: f64,
}

/// One experiment's residual breakdown.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ExperimentBreakdown {
    /// File name.
    pub name: String,
    /// Fundamental of the current, Hz.
    pub fundamental_hz: f64,
    /// Current amplitude, A.
    pub amplitude_a: f64,
    /// RMS residual, m.
    pub rms_m: f64,
    /// RMS residual / measured displacement range of this experiment.
    pub relative_rms: f64,
    /// Noise-corrected systematic gap, m.
    pub systematic_m: f64,
    /// The harmonic of the current's fundamental that `amplitude_ratio` and `phase_error_deg`
    /// refer to: the largest of the model displacement's orders 1–4. 1 under a biased drive; 2
    /// under a drive without DC bias, where the displacement (even in M) repeats twice a period
    /// and its fundamental is noise.
    pub displacement_order: usize,
    /// |measured| / |model| displacement at `displacement_order`.
    pub amplitude_ratio: f64,
    /// Phase of measured minus model displacement at `displacement_order`, degrees (negative:
    /// the measurement lags).
    pub phase_error_deg: f64,
    /// Mean measured minus mean model, m.
    pub dc_error_m: f64,
    /// Orders 2..=4.
    pub harmonics: Vec<Harmonic>,
    /// RMS residual on the ascending / descending current branch, m.
    pub ascending_rms_m: f64,
    /// See above.
    pub descending_rms_m: f64,
    /// RMS residual near current reversals / mid-branch, m.
    pub near_reversal_rms_m: f64,
    /// See above.
    pub mid_branch_rms_m: f64,
    /// RMS residual in the first / last third of the scored record, m.
    pub early_rms_m: f64,
    /// See above.
    pub late_rms_m: f64,
}

/// One frequency band (experiments whose fundamentals are within 5 %).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BandSummary {
    /// Mean fundamental, Hz.
    pub frequency_hz: f64,
    /// Pooled RMS residual, m.
    pub rms_m: f64,
    /// Noise-corrected systematic gap, m.
    pub systematic_m: f64,
    /// Systematic gap / measured displacement range of the band.
    pub relative_gap: f64,
    /// The largest `displacement_order` among the band's experiments.
    pub displacement_order: usize,
    /// Mean amplitude ratio of the displacement's main harmonic.
    pub amplitude_ratio: f64,
    /// Mean phase error of the displacement's main harmonic, degrees.
    pub phase_error_deg: f64,
    /// Disagrees by the gap-onset rule (module docs).
    pub disagrees: bool,
}

/// The "where" section of the diagnosis.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Where {
    /// Per experiment.
    pub experiments: Vec<ExperimentBreakdown>,
    /// Per frequency band, ascending frequency.
    pub bands: Vec<BandSummary>,
    /// Frequency from which every band disagrees, Hz (`None`: the highest band agrees).
    pub gap_start_hz: Option<f64>,
    /// Pooled over the dataset: ascending / descending branch RMS, m.
    pub ascending_rms_m: f64,
    /// See above.
    pub descending_rms_m: f64,
    /// Pooled near-reversal / mid-branch RMS, m.
    pub near_reversal_rms_m: f64,
    /// See above.
    pub mid_branch_rms_m: f64,
    /// Pooled early / late RMS, m.
    pub early_rms_m: f64,
    /// See above.
    pub late_rms_m: f64,
    /// Plain-language summary, one finding per sentence.
    pub summary: Vec<String>,
}

#[derive(Default, Clone, Copy)]
struct Acc {
    sum: f64,
    n: usize,
}

impl Acc {
    fn add(&mut self, r: f64) {
        self.sum += r * r;
        self.n += 1;
    }
    fn merge(&mut self, o: Acc) {
        self.sum += o.sum;
        self.n += o.n;
    }
    fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum / self.n as f64).sqrt()
        }
    }
}

fn range_of(x: &[f64]) -> f64 {
    let (lo, hi) = x
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (hi - lo).max(0.0)
}

/// Breaks the nominal residual down (see the module docs).
pub fn analyse(
    measurements: &[Measurement],
    nominal: &[Vec<f64>],
    infos: &[ExperimentInfo],
    noise_m: f64,
    rate_hz: f64,
) -> Where {
    let mut totals = [Acc::default(); 6];
    let mut experiments = Vec::new();
    for ((m, y), info) in measurements.iter().zip(nominal).zip(infos) {
        let n = m.len();
        let s = info.settle_samples;
        let meas = &m.displacement_m;
        let labels = branches::branch_labels(&m.current_a);
        let mut acc = [Acc::default(); 6];
        let mut all = Acc::default();
        let third = (n - s) / 3;
        for k in s..n {
            let r = meas[k] - y[k];
            all.add(r);
            acc[if labels.ascending[k] { 0 } else { 1 }].add(r);
            acc[if labels.near_reversal[k] { 2 } else { 3 }].add(r);
            if k < s + third {
                acc[4].add(r);
            } else if k >= n - third {
                acc[5].add(r);
            }
        }
        for (t, a) in totals.iter_mut().zip(acc) {
            t.merge(a);
        }
        let window = spectrum::whole_periods(s, n, info.fundamental_hz, rate_hz);
        let at_order = |x: &[f64], order: usize| {
            spectrum::fourier_coefficient(
                x,
                window.clone(),
                order as f64 * info.fundamental_hz,
                rate_hz,
            )
        };
        // Orders 1-4 of both signals, once: the main harmonic's ratio and phase and the
        // harmonics table come from them.
        let measured: Vec<_> = (1..=4).map(|o| at_order(meas, o)).collect();
        let model: Vec<_> = (1..=4).map(|o| at_order(y, o)).collect();
        let order = 1
            + (0..4)
                .max_by(|&a, &b| model[a].norm().total_cmp(&model[b].norm()))
                .unwrap_or(0);
        let (cm, cy) = (measured[order - 1], model[order - 1]);
        let ratio = cm.norm() / cy.norm().max(1e-300);
        let phase = (cm / cy).arg().to_degrees();
        let len = window.len() as f64;
        let dc = window.clone().map(|k| meas[k] - y[k]).sum::<f64>() / len;
        let harmonics = (2..=4)
            .map(|order| Harmonic {
                order,
                measured_m: measured[order - 1].norm(),
                model_m: model[order - 1].norm(),
            })
            .collect();
        let rms = all.rms();
        experiments.push(ExperimentBreakdown {
            name: info.name.clone(),
            fundamental_hz: info.fundamental_hz,
            amplitude_a: info.amplitude_a,
            rms_m: rms,
            relative_rms: rms / range_of(&meas[s..]).max(1e-300),
            systematic_m: systematic(rms, noise_m),
            displacement_order: order,
            amplitude_ratio: ratio,
            phase_error_deg: phase,
            dc_error_m: dc,
            harmonics,
            ascending_rms_m: acc[0].rms(),
            descending_rms_m: acc[1].rms(),
            near_reversal_rms_m: acc[2].rms(),
            mid_branch_rms_m: acc[3].rms(),
            early_rms_m: acc[4].rms(),
            late_rms_m: acc[5].rms(),
        });
    }
    // Bands.
    let groups = infos.iter().map(|i| i.frequency_group).max().unwrap_or(0) + 1;
    let mut bands = Vec::new();
    let mut ranges = Vec::new();
    for g in 0..groups {
        let members: Vec<usize> = (0..infos.len())
            .filter(|&k| !infos[k].quasi_static && infos[k].frequency_group == g)
            .collect();
        if members.is_empty() {
            continue;
        }
        let count = members.len() as f64;
        let mut acc = Acc::default();
        let mut range: f64 = 0.0;
        for &k in &members {
            let s = infos[k].settle_samples;
            for (a, b) in measurements[k].displacement_m[s..]
                .iter()
                .zip(&nominal[k][s..])
            {
                acc.add(a - b);
            }
            range = range.max(range_of(&measurements[k].displacement_m[s..]));
        }
        let rms = acc.rms();
        let sys = systematic(rms, noise_m);
        // The ratio and phase are averaged over the experiments at the band's order (a band may
        // mix biased and unbiased drives; phases of different orders do not average).
        let order = members
            .iter()
            .map(|&k| experiments[k].displacement_order)
            .max()
            .unwrap_or(1);
        let at_order: Vec<&ExperimentBreakdown> = members
            .iter()
            .map(|&k| &experiments[k])
            .filter(|e| e.displacement_order == order)
            .collect();
        let n_at_order = at_order.len().max(1) as f64;
        bands.push(BandSummary {
            frequency_hz: members
                .iter()
                .map(|&k| infos[k].fundamental_hz)
                .sum::<f64>()
                / count,
            rms_m: rms,
            systematic_m: sys,
            relative_gap: sys / range.max(1e-300),
            displacement_order: order,
            amplitude_ratio: at_order.iter().map(|e| e.amplitude_ratio).sum::<f64>() / n_at_order,
            phase_error_deg: at_order.iter().map(|e| e.phase_error_deg).sum::<f64>() / n_at_order,
            disagrees: false,
        });
        ranges.push(range);
    }
    // Onset rule (module docs).
    for (b, range) in bands.iter_mut().zip(&ranges) {
        b.disagrees = b.relative_gap > (2.0 * noise_m / range.max(1e-300)).max(0.01);
    }
    let gap_start_hz = match bands.iter().rposition(|b| !b.disagrees) {
        None => bands.first().map(|b| b.frequency_hz),
        Some(last_ok) if last_ok + 1 < bands.len() => Some(bands[last_ok + 1].frequency_hz),
        Some(_) => None,
    };
    let mut w = Where {
        experiments,
        bands,
        gap_start_hz,
        ascending_rms_m: totals[0].rms(),
        descending_rms_m: totals[1].rms(),
        near_reversal_rms_m: totals[2].rms(),
        mid_branch_rms_m: totals[3].rms(),
        early_rms_m: totals[4].rms(),
        late_rms_m: totals[5].rms(),
        summary: Vec::new(),
    };
    w.summary = summarize(&w, noise_m);
    w.summary.extend(drift_findings(measurements, infos));
    w
}

/// The quasi-static records that read one state differently on their returns to it (module
/// docs), one finding each.
fn drift_findings(measurements: &[Measurement], infos: &[ExperimentInfo]) -> Vec<String> {
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

/// The plain-language findings.
fn summarize(w: &Where, noise_m: f64) -> Vec<String> {
    let mut out = Vec::new();
    let (Some(first), Some(last)) = (w.bands.first(), w.bands.last()) else {
        return out;
    };
    match w.gap_start_hz {
        Some(f) if f <= first.frequency_hz => out.push(format!(
            "The model disagrees at every frequency tested ({:.0}-{:.0} Hz): the systematic gap is \
             {:.1} % of the motion at {:.0} Hz and {:.1} % at {:.0} Hz.",
            first.frequency_hz,
            last.frequency_hz,
            100.0 * first.relative_gap,
            first.frequency_hz,
            100.0 * last.relative_gap,
            last.frequency_hz
        )),
        Some(f) => out.push(format!(
            "The gap starts at about {f:.0} Hz: up to {:.0} Hz the model agrees within max(2x noise, \
             1 % of the motion); at {:.0} Hz the systematic gap is {:.1} % of the motion.",
            w.bands.iter().filter(|b| b.frequency_hz < f).map(|b| b.frequency_hz).fold(0.0, f64::max),
            last.frequency_hz,
            100.0 * last.relative_gap
        )),
        None => {
            let worst = w.bands.iter().max_by(|a, b| a.relative_gap.total_cmp(&b.relative_gap));
            let worst = worst.unwrap_or(first);
            if worst.disagrees {
                out.push(format!(
                    "The model disagrees only in some bands (worst {:.0} Hz, gap {:.1} % of the \
                     motion) and agrees at the highest frequency tested.",
                    worst.frequency_hz,
                    100.0 * worst.relative_gap
                ));
            } else {
                out.push(format!(
                    "The model agrees in every band within max(2x noise, 1 % of the motion) \
                     (noise level {:.2e} m).",
                    noise_m
                ));
            }
        }
    }
    // Which harmonic the phase and amplitude figures are of (`displacement_order`).
    let doubled = w.bands.iter().filter(|b| b.displacement_order == 2).count();
    let harmonic = if w.bands.iter().all(|b| b.displacement_order == 1) {
        "the fundamental"
    } else {
        out.push(format!(
            "In {doubled} of {} bands the drive has no DC bias: the displacement, even in M, \
             repeats twice per current period, and the phase and amplitude below are those of its \
             largest harmonic there (the second).",
            w.bands.len()
        ));
        "the displacement's main harmonic"
    };
    // Phase.
    let phases: Vec<f64> = w.bands.iter().map(|b| b.phase_error_deg).collect();
    let max_phase = phases
        .iter()
        .cloned()
        .fold(0.0f64, |m, p| if p.abs() > m.abs() { p } else { m });
    if max_phase.abs() >= 2.0 {
        let at = w
            .bands
            .iter()
            .find(|b| b.phase_error_deg == max_phase)
            .map(|b| b.frequency_hz)
            .unwrap_or(0.0);
        out.push(format!(
            "Phase error of {harmonic} grows from {:+.1} deg at {:.0} Hz to {:+.1} deg at {:.0} Hz \
             (largest {:+.1} deg at {:.0} Hz; negative = the measurement lags the model).",
            first.phase_error_deg, first.frequency_hz, last.phase_error_deg, last.frequency_hz, max_phase, at
        ));
    } else {
        out.push(format!(
            "The phase of {harmonic} agrees within 2 deg in every band."
        ));
    }
    // Amplitude.
    let ratios: Vec<f64> = w.bands.iter().map(|b| b.amplitude_ratio).collect();
    let (rlo, rhi) = ratios
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &r| (a.min(r), b.max(r)));
    if rlo >= 0.98 && rhi <= 1.02 {
        out.push(format!(
            "The amplitude of {harmonic} agrees within 2 % in every band."
        ));
    } else {
        out.push(format!(
            "The amplitude of {harmonic} is off: measured/model from {:.3} to {:.3} \
             ({:.3} at {:.0} Hz, {:.3} at {:.0} Hz).",
            rlo,
            rhi,
            first.amplitude_ratio,
            first.frequency_hz,
            last.amplitude_ratio,
            last.frequency_hz
        ));
    }
    // DC level.
    // Each experiment's DC error as a fraction of its own displacement range.
    let worst_dc = w
        .experiments
        .iter()
        .map(|e| {
            let relative = e.dc_error_m.abs() / (e.rms_m / e.relative_rms.max(1e-300)).max(1e-300);
            (relative, e)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match worst_dc {
        Some((relative, e)) if relative >= 0.01 => out.push(format!(
            "The DC level is off by up to {:.1} % of an experiment's own motion ({}: {:+.3e} m).",
            100.0 * relative,
            e.name,
            e.dc_error_m
        )),
        _ => out.push("The DC level agrees (within 1 % of the motion in every experiment).".into()),
    }
    // Harmonics.
    let mut worst_h = (0.0f64, 0usize, 0.0f64);
    for e in &w.experiments {
        for h in &e.harmonics {
            let d = (h.measured_m - h.model_m).abs();
            if d > worst_h.0 {
                worst_h = (d, h.order, e.fundamental_hz);
            }
        }
    }
    if worst_h.0 > 2.0 * noise_m {
        out.push(format!(
            "Harmonics differ: the largest difference is in harmonic {} at {:.0} Hz ({:.2e} m).",
            worst_h.1, worst_h.2, worst_h.0
        ));
    }
    // Branches.
    let branch = |a: f64, b: f64| a / b.max(1e-300);
    let asc = branch(w.ascending_rms_m, w.descending_rms_m);
    if !(0.67..=1.5).contains(&asc) {
        out.push(format!(
            "The residual is larger on the {} branch ({:.2e} m vs {:.2e} m).",
            if asc > 1.0 { "ascending" } else { "descending" },
            w.ascending_rms_m.max(w.descending_rms_m),
            w.ascending_rms_m.min(w.descending_rms_m)
        ));
    } else {
        out.push("Ascending and descending branches are equally affected.".into());
    }
    let rev = branch(w.near_reversal_rms_m, w.mid_branch_rms_m);
    if rev > 1.3 {
        out.push(format!(
            "The residual concentrates near current reversals ({:.2e} m vs {:.2e} m mid-branch).",
            w.near_reversal_rms_m, w.mid_branch_rms_m
        ));
    } else if rev < 0.77 {
        out.push(format!(
            "The residual is largest mid-branch ({:.2e} m vs {:.2e} m near reversals).",
            w.mid_branch_rms_m, w.near_reversal_rms_m
        ));
    }
    let late = branch(w.late_rms_m, w.early_rms_m);
    if !(0.67..=1.5).contains(&late) {
        out.push(format!(
            "The residual {} during each record (last third {:.2e} m vs first third {:.2e} m): \
             a slow drift.",
            if late > 1.0 { "grows" } else { "shrinks" },
            w.late_rms_m,
            w.early_rms_m
        ));
    } else {
        out.push("Early and late parts of each record agree equally (no drift).".into());
    }
    out
}
