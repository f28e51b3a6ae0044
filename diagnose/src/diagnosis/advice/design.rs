//! The dataset's dynamic design as the advice reads it (its fundamentals, amplitudes, biases and
//! quasi-static loops) and, for each [`Recording`], the `maglab excite` command that writes it on
//! this rig: at the dataset's own amplitude and bias, a second bias where the current limit leaves
//! room, frequencies through the resonance as far as the sampling resolves.

use super::{Recording, Rig};
use maglab_dataset::records::MIN_SAMPLES_PER_PERIOD;
use maglab_model::experiments::ExperimentInfo;

/// Two dynamic records count as at different biases when their mean currents differ by more
/// than this share of the larger amplitude (a bias the loops of both do not share).
const DISTINCT_BIAS_SHARE: f64 = 0.5;

/// The dataset's dynamic design, as far as the advice needs it.
#[doc(hidden)]
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// Distinct fundamentals of the dynamic records, Hz, ascending.
    frequencies_hz: Vec<f64>,
    /// Distinct amplitudes, A, ascending.
    amplitudes_a: Vec<f64>,
    /// Distinct biases, A, ascending.
    biases_a: Vec<f64>,
    /// Amplitudes of the quasi-static records with a loop (not the reversal sweep), A.
    quasi_static_amplitudes_a: Vec<f64>,
    rig: Rig,
}

/// Appends `v` unless a value within `tolerance` (relative) is already there.
pub(super) fn push_distinct(values: &mut Vec<f64>, v: f64, tolerance: f64) {
    if !values
        .iter()
        .any(|&x| (x - v).abs() <= tolerance * x.abs().max(v.abs()))
    {
        values.push(v);
    }
}

impl Design {
    /// The design of a dataset whose experiments are `infos`.
    pub fn of(infos: &[ExperimentInfo], rig: Rig) -> Design {
        let mut d = Design {
            frequencies_hz: Vec::new(),
            amplitudes_a: Vec::new(),
            biases_a: Vec::new(),
            quasi_static_amplitudes_a: Vec::new(),
            rig,
        };
        for e in infos {
            if e.quasi_static {
                push_distinct(&mut d.quasi_static_amplitudes_a, e.amplitude_a, 0.1);
                continue;
            }
            push_distinct(&mut d.frequencies_hz, e.fundamental_hz, 0.05);
            push_distinct(&mut d.amplitudes_a, e.amplitude_a, 0.1);
            let distinct = d.biases_a.iter().all(|&b| {
                (b - e.bias_a).abs() > DISTINCT_BIAS_SHARE * e.amplitude_a.max(f64::MIN_POSITIVE)
            });
            if distinct {
                d.biases_a.push(e.bias_a);
            }
        }
        for v in [
            &mut d.frequencies_hz,
            &mut d.amplitudes_a,
            &mut d.biases_a,
            &mut d.quasi_static_amplitudes_a,
        ] {
            v.sort_by(f64::total_cmp);
        }
        d
    }

    /// The smallest dynamic amplitude (the loops most sensitive to the rod's state), A.
    fn amplitude_a(&self) -> f64 {
        self.amplitudes_a.first().copied().unwrap_or(0.3)
    }

    /// The dataset's (first) bias, A.
    fn bias_a(&self) -> f64 {
        self.biases_a.first().copied().unwrap_or(0.8)
    }

    /// A second bias: halfway between the dataset's and the highest the current limit allows
    /// with the smallest amplitude, or below the dataset's when that leaves no room.
    pub fn second_bias_a(&self) -> f64 {
        let (a, b) = (self.amplitude_a(), self.bias_a());
        let highest = 0.9 * self.rig.current_limit_a - a;
        let up = 0.5 * (b + highest);
        if up - b > DISTINCT_BIAS_SHARE * a {
            up
        } else {
            (b - 2.0 * a).max(a)
        }
    }

    /// Whether the dataset already holds `recording`.
    pub(super) fn holds(&self, recording: Recording) -> bool {
        let two_biases = self.biases_a.len() >= 2;
        match recording {
            Recording::CoilCurrent => self.rig.coil_current_measured,
            Recording::ThermalSoak | Recording::MeasuredLoops => false,
            Recording::QuasiStaticLoops => self.amplitudes_a.iter().all(|&a| {
                self.quasi_static_amplitudes_a
                    .iter()
                    .any(|&q| (q - a).abs() <= 0.2 * a)
            }),
            Recording::SecondBias => two_biases,
            Recording::ThroughResonance => {
                // Up to the advised sweep's top, or within a step of it (a quarter).
                let top = self.through_resonance_hz().last().copied().unwrap_or(0.0);
                two_biases && self.frequencies_hz.last().is_some_and(|&f| f >= top / 1.2)
            }
        }
    }

    /// The frequencies of the sweep through the resonance, Hz: 0.5 to 2.5 times the rig's f0
    /// (below the peak, the peak, above it; the range's lower part lies within it), then on up
    /// to 2.5 times the highest resonance the rig's range allows (`f0 · factor`) in steps of a
    /// quarter, so that the peak is passed wherever in the range it lies; as far as the
    /// sampling resolves (`maglab_dataset::records`), the last one at that limit when the
    /// range reaches past it (none closer than a tenth to the one below).
    fn through_resonance_hz(&self) -> Vec<f64> {
        let highest = self.rig.sample_rate_hz / MIN_SAMPLES_PER_PERIOD;
        let f0 = self.rig.resonance_hz;
        let high_f0 = f0 * self.rig.resonance_factor.max(1.0);
        let mut freqs: Vec<f64> = [0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5]
            .iter()
            .map(|k| k * f0)
            .collect();
        // A frequency within a tenth of the one below it adds no point of the response.
        let apart = |f: f64, below: f64| f >= 1.1 * below;
        while let Some(&last) = freqs.last() {
            let next = (1.25 * last).min(2.5 * high_f0);
            if !apart(next, last) {
                break;
            }
            freqs.push(next);
        }
        let cut = freqs.iter().any(|&f| f > highest);
        let mut freqs: Vec<f64> = freqs
            .into_iter()
            .filter(|&f| f <= highest)
            .map(round3)
            .collect();
        if cut && freqs.last().is_some_and(|&f| apart(highest, f)) {
            freqs.push(round3(highest));
        }
        freqs.dedup();
        freqs
    }

    /// The command that writes `recording` (or, for the coil current, what to connect).
    pub(super) fn command(&self, recording: Recording) -> String {
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{}", round3(*x)))
                .collect::<Vec<_>>()
                .join(",")
        };
        let (a, b, b2) = (self.amplitude_a(), self.bias_a(), self.second_bias_a());
        let excite = "maglab excite --design";
        match recording {
            Recording::CoilCurrent => "connect the amplifier's current-monitor output to a \
                                       second ADC channel on the displacement's trigger"
                .to_string(),
            Recording::ThermalSoak => format!(
                "{excite} soak --freq-hz {} --amplitude-a {} --bias-a {} --soak-current-a {} \
                 --soak-s 120 -o thermal_soak",
                round3(self.frequencies_hz.first().copied().unwrap_or(100.0)),
                round3(a),
                round3(b),
                round3(0.9 * self.rig.current_limit_a)
            ),
            // Only [`measure_loops`] advises it, with the unmeasured loops' own currents; from
            // the design alone, its loops.
            Recording::QuasiStaticLoops | Recording::MeasuredLoops => format!(
                "{excite} sines --freq-hz 1 --amplitude-a {} --bias-a {} --duration-s 2 -o slow_loops",
                list(if self.amplitudes_a.is_empty() {
                    &[0.3]
                } else {
                    &self.amplitudes_a
                }),
                round3(b)
            ),
            Recording::SecondBias => format!(
                "{excite} sines --freq-hz {} --amplitude-a {} --bias-a {} --sample-rate-hz {} \
                 -o second_bias",
                list(if self.frequencies_hz.is_empty() {
                    &[100.0]
                } else {
                    &self.frequencies_hz
                }),
                round3(a),
                round3(b2),
                self.rig.sample_rate_hz.round()
            ),
            Recording::ThroughResonance => {
                let freqs = self.through_resonance_hz();
                format!(
                    "{excite} sines --freq-hz {} --amplitude-a {} --bias-a {},{} \
                     --sample-rate-hz {} -o through_resonance",
                    list(&freqs),
                    round3(a),
                    round3(b),
                    round3(b2),
                    self.rig.sample_rate_hz.round()
                )
            }
        }
    }
}

/// `x` to three significant digits (for a command line).
pub(super) fn round3(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(2 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}
