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

mod findings;

use maglab_dataset::data::Measurement;
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
    /// The RMS residual by part of the record.
    #[serde(flatten)]
    pub parts: PartsRms,
}

/// The RMS residual in the parts of a record the breakdown compares, m (in `diagnosis.json`
/// as fields of the experiment or dataset they belong to).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct PartsRms {
    /// On the ascending / descending current branch.
    pub ascending_rms_m: f64,
    /// See above.
    pub descending_rms_m: f64,
    /// Near current reversals / mid-branch.
    pub near_reversal_rms_m: f64,
    /// See above.
    pub mid_branch_rms_m: f64,
    /// In the first / last third of the scored record.
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
    /// The RMS residual by part, pooled over the dataset.
    #[serde(flatten)]
    pub parts: PartsRms,
    /// Plain-language summary, one finding per sentence.
    pub summary: Vec<String>,
}

/// A running sum of squared residuals.
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

/// The residual's squares in the parts of a record the breakdown compares: the current's
/// ascending and descending branches, near a reversal and mid-branch, the first and the last
/// third of the scored samples.
#[derive(Default, Clone, Copy)]
struct Parts {
    ascending: Acc,
    descending: Acc,
    near_reversal: Acc,
    mid_branch: Acc,
    early: Acc,
    late: Acc,
}

impl Parts {
    fn rms(&self) -> PartsRms {
        PartsRms {
            ascending_rms_m: self.ascending.rms(),
            descending_rms_m: self.descending.rms(),
            near_reversal_rms_m: self.near_reversal.rms(),
            mid_branch_rms_m: self.mid_branch.rms(),
            early_rms_m: self.early.rms(),
            late_rms_m: self.late.rms(),
        }
    }

    fn merge(&mut self, o: Parts) {
        self.ascending.merge(o.ascending);
        self.descending.merge(o.descending);
        self.near_reversal.merge(o.near_reversal);
        self.mid_branch.merge(o.mid_branch);
        self.early.merge(o.early);
        self.late.merge(o.late);
    }
}

fn range_of(x: &[f64]) -> f64 {
    let (lo, hi) = x
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (hi - lo).max(0.0)
}

/// Breaks the nominal residual down (see the module docs): `nominal` the nominal model's
/// prediction of each of `measurements`, `noise_m` the white-noise level.
pub fn analyse(
    measurements: &[Measurement],
    nominal: &[Vec<f64>],
    infos: &[ExperimentInfo],
    noise_m: f64,
    rate_hz: f64,
) -> Where {
    let mut totals = Parts::default();
    let mut experiments = Vec::new();
    for ((m, y), info) in measurements.iter().zip(nominal).zip(infos) {
        let (experiment, parts) = experiment_breakdown(m, y, info, noise_m, rate_hz);
        totals.merge(parts);
        experiments.push(experiment);
    }
    let (mut bands, ranges) = band_summaries(measurements, nominal, infos, &experiments, noise_m);
    mark_disagreeing(&mut bands, &ranges, noise_m);
    let gap_start_hz = gap_start_hz(&bands);
    let mut w = Where {
        experiments,
        bands,
        gap_start_hz,
        parts: totals.rms(),
        summary: Vec::new(),
    };
    w.summary = findings::summarize(&w, noise_m);
    w.summary
        .extend(findings::drift_findings(measurements, infos));
    w
}

/// One experiment's breakdown (`y` the nominal prediction of `m`), and its residual's squares
/// by part for the dataset's totals.
fn experiment_breakdown(
    m: &Measurement,
    y: &[f64],
    info: &ExperimentInfo,
    noise_m: f64,
    rate_hz: f64,
) -> (ExperimentBreakdown, Parts) {
    let n = m.len();
    let s = info.settle_samples;
    let meas = &m.displacement_m;
    let parts = residual_parts(&m.current_a, meas, y, s);
    let mut all = Acc::default();
    for k in s..n {
        all.add(meas[k] - y[k]);
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
    let order = main_order(&model.iter().map(|c| c.norm()).collect::<Vec<f64>>());
    let (cm, cy) = (measured[order - 1], model[order - 1]);
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
    let experiment = ExperimentBreakdown {
        name: info.name.clone(),
        fundamental_hz: info.fundamental_hz,
        amplitude_a: info.amplitude_a,
        rms_m: rms,
        relative_rms: rms / range_of(&meas[s..]).max(1e-300),
        systematic_m: systematic(rms, noise_m),
        displacement_order: order,
        amplitude_ratio: cm.norm() / cy.norm().max(1e-300),
        phase_error_deg: (cm / cy).arg().to_degrees(),
        dc_error_m: dc,
        harmonics,
        parts: parts.rms(),
    };
    (experiment, parts)
}

/// The residual `meas − y` from sample `settle` on, by part of the record (the branches and
/// reversals of `current_a`).
fn residual_parts(current_a: &[f64], meas: &[f64], y: &[f64], settle: usize) -> Parts {
    let n = meas.len();
    let labels = branches::branch_labels(current_a);
    let third = (n - settle) / 3;
    let mut parts = Parts::default();
    for k in settle..n {
        let r = meas[k] - y[k];
        if labels.ascending[k] {
            parts.ascending.add(r);
        } else {
            parts.descending.add(r);
        }
        if labels.near_reversal[k] {
            parts.near_reversal.add(r);
        } else {
            parts.mid_branch.add(r);
        }
        if k < settle + third {
            parts.early.add(r);
        } else if k >= n - third {
            parts.late.add(r);
        }
    }
    parts
}

/// The displacement's main harmonic: the order whose model amplitude is the largest
/// (`model_m[o − 1]` the amplitude of order `o`).
fn main_order(model_m: &[f64]) -> usize {
    1 + (0..model_m.len())
        .max_by(|&a, &b| model_m[a].total_cmp(&model_m[b]))
        .unwrap_or(0)
}

/// One summary per frequency group of dynamic experiments, ascending, with the band's
/// measured displacement range (m) beside it.
fn band_summaries(
    measurements: &[Measurement],
    nominal: &[Vec<f64>],
    infos: &[ExperimentInfo],
    experiments: &[ExperimentBreakdown],
    noise_m: f64,
) -> (Vec<BandSummary>, Vec<f64>) {
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
    (bands, ranges)
}

/// The onset rule (module docs): a band disagrees when its systematic gap exceeds twice the
/// noise and 1 % of its motion (`ranges`, m).
fn mark_disagreeing(bands: &mut [BandSummary], ranges: &[f64], noise_m: f64) {
    for (b, range) in bands.iter_mut().zip(ranges) {
        b.disagrees = b.relative_gap > (2.0 * noise_m / range.max(1e-300)).max(0.01);
    }
}

/// The lowest band from which every higher band disagrees (`None`: the highest agrees).
fn gap_start_hz(bands: &[BandSummary]) -> Option<f64> {
    match bands.iter().rposition(|b| !b.disagrees) {
        None => bands.first().map(|b| b.frequency_hz),
        Some(last_ok) if last_ok + 1 < bands.len() => Some(bands[last_ok + 1].frequency_hz),
        Some(_) => None,
    }
}
