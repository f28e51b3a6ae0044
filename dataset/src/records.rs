//! The records the diagnosis advises when it cannot separate candidates
//! (`maglab_diagnose::diagnosis::advice`): biased sines, and a thermal soak.
//!
//! * A **sine** record is `i(t) = b + a sin(2π f t)`, switched on at `t = 0` (record it from a
//!   demagnetized rod, or document its start in `dataset.json`), for a whole number of periods.
//! * A **soak** record is one file, so that the coil's temperature carries over: the sine for
//!   `sine_s` (the coil cold), a ramp to `soak_current_a` and a hold there for `soak_s` (it heats by
//!   `R I²`), a ramp back to the bias, and the same sine again (hot). The ramps take
//!   [`SOAK_RAMP_S`], slow against the eddy currents and the resonance (a step would ring).
//!   The two sines differ by what depends on the dissipated `I²` over seconds: the thermal drift.

use crate::excitation::Excitation;

/// Duration of each ramp of a soak record, s.
pub const SOAK_RAMP_S: f64 = 0.05;

/// Fewest samples per period of the highest sine: 10 resolve its first harmonics and keep the
/// held current between samples a small part of a period.
pub const MIN_SAMPLES_PER_PERIOD: f64 = 10.0;

/// One sine record's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sine {
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Amplitude (half the peak-to-peak), A.
    pub amplitude_a: f64,
    /// Mean current, A.
    pub bias_a: f64,
    /// Duration, s (rounded up to whole periods).
    pub duration_s: f64,
}

/// Checks a sine against the sampling rate and the current limit; the error names the setting.
pub fn check_sine(sine: &Sine, sample_rate_hz: f64, current_limit_a: f64) -> Result<(), String> {
    let positive = [
        ("--freq-hz", sine.frequency_hz),
        ("--duration-s", sine.duration_s),
        ("--sample-rate-hz", sample_rate_hz),
    ];
    for (name, v) in positive {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{name} must be a finite number > 0, got {v}"));
        }
    }
    if !(sine.amplitude_a.is_finite() && sine.amplitude_a >= 0.0) {
        return Err(format!(
            "--amplitude-a must be a finite number >= 0, got {}",
            sine.amplitude_a
        ));
    }
    if !sine.bias_a.is_finite() {
        return Err(format!("--bias-a must be finite, got {}", sine.bias_a));
    }
    if sample_rate_hz < MIN_SAMPLES_PER_PERIOD * sine.frequency_hz {
        return Err(format!(
            "--freq-hz {} needs --sample-rate-hz >= {} (at least {MIN_SAMPLES_PER_PERIOD} \
             samples per period), got {sample_rate_hz}",
            sine.frequency_hz,
            MIN_SAMPLES_PER_PERIOD * sine.frequency_hz
        ));
    }
    let peak = sine.bias_a.abs() + sine.amplitude_a;
    if peak > current_limit_a {
        return Err(format!(
            "--bias-a {} with --amplitude-a {} peaks at {peak:.4} A, above \
             control.current_limit_a = {current_limit_a} A",
            sine.bias_a, sine.amplitude_a
        ));
    }
    Ok(())
}

/// The samples of a sine (checked with [`check_sine`] first).
pub fn sine_record(sine: &Sine, sample_rate_hz: f64) -> Excitation {
    let periods = (sine.duration_s * sine.frequency_hz).ceil().max(1.0);
    let n = (periods / sine.frequency_hz * sample_rate_hz).round() as usize;
    let dt = 1.0 / sample_rate_hz;
    let w = 2.0 * std::f64::consts::PI * sine.frequency_hz;
    let t_s: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let current_a = t_s
        .iter()
        .map(|&t| sine.bias_a + sine.amplitude_a * (w * t).sin())
        .collect();
    Excitation {
        t_s,
        current_a,
        reversals: 0,
    }
}

/// The samples of a soak record: `sine` cold, the soak at `soak_current_a` for `soak_s`, `sine`
/// hot (module docs). `soak_current_a` must be within the limit.
pub fn soak_record(
    sine: &Sine,
    soak_current_a: f64,
    soak_s: f64,
    sample_rate_hz: f64,
    current_limit_a: f64,
) -> Result<Excitation, String> {
    check_sine(sine, sample_rate_hz, current_limit_a)?;
    if !(soak_s.is_finite() && soak_s > 0.0) {
        return Err(format!(
            "--soak-s must be a finite number > 0, got {soak_s}"
        ));
    }
    if !(soak_current_a.is_finite() && soak_current_a.abs() <= current_limit_a) {
        return Err(format!(
            "--soak-current-a {soak_current_a} must be finite and within control.current_limit_a \
             = {current_limit_a} A"
        ));
    }
    let cold = sine_record(sine, sample_rate_hz);
    let samples = |s: f64| (s * sample_rate_hz).round().max(1.0) as usize;
    let mut current_a = cold.current_a.clone();
    let ramp = |from: f64, to: f64, out: &mut Vec<f64>| {
        let n = samples(SOAK_RAMP_S);
        out.extend((1..=n).map(|k| from + (to - from) * k as f64 / n as f64));
    };
    // The sine ends on its bias (whole periods), so the ramps start and end there.
    ramp(sine.bias_a, soak_current_a, &mut current_a);
    current_a.extend(std::iter::repeat_n(soak_current_a, samples(soak_s)));
    ramp(soak_current_a, sine.bias_a, &mut current_a);
    current_a.extend_from_slice(&cold.current_a);
    let dt = 1.0 / sample_rate_hz;
    Ok(Excitation {
        t_s: (0..current_a.len()).map(|k| k as f64 * dt).collect(),
        current_a,
        reversals: 0,
    })
}

/// A file name for a sine record: `NN_sine_f<f>hz_a<a>_b<b>.csv`.
pub fn sine_file_name(index: usize, sine: &Sine) -> String {
    format!(
        "{index:02}_sine_f{}hz_a{:.2}_b{:.2}.csv",
        sine.frequency_hz, sine.amplitude_a, sine.bias_a
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const SINE: Sine = Sine {
        frequency_hz: 100.0,
        amplitude_a: 0.3,
        bias_a: 0.8,
        duration_s: 0.105,
    };

    #[test]
    fn a_sine_is_whole_periods_at_its_bias_and_amplitude() {
        let r = sine_record(&SINE, 10_000.0);
        // 0.105 s at 100 Hz rounds up to 11 periods.
        assert_eq!(r.t_s.len(), 1100);
        let (lo, hi) = r
            .current_a
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &i| (a.min(i), b.max(i)));
        assert!(
            (hi - 1.1).abs() < 1e-9 && (lo - 0.5).abs() < 1e-9,
            "{lo} {hi}"
        );
        let mean = r.current_a.iter().sum::<f64>() / r.current_a.len() as f64;
        assert!((mean - 0.8).abs() < 1e-9, "{mean}");
    }

    #[test]
    fn a_sine_beyond_the_limit_or_the_sampling_is_refused_by_name() {
        let e = check_sine(
            &Sine {
                bias_a: 1.9,
                ..SINE
            },
            10_000.0,
            2.0,
        )
        .unwrap_err();
        assert!(
            e.contains("--bias-a 1.9") && e.contains("current_limit_a"),
            "{e}"
        );
        let e = check_sine(&SINE, 500.0, 2.0).unwrap_err();
        assert!(e.contains("--sample-rate-hz >= 1000"), "{e}");
        let e = check_sine(
            &Sine {
                duration_s: 0.0,
                ..SINE
            },
            1e4,
            2.0,
        )
        .unwrap_err();
        assert!(e.contains("--duration-s"), "{e}");
    }

    #[test]
    fn a_soak_is_the_sine_cold_the_hold_and_the_sine_hot() {
        let r = soak_record(&SINE, 1.8, 1.0, 10_000.0, 2.0).unwrap();
        let sine = sine_record(&SINE, 10_000.0).current_a;
        let ramp = (SOAK_RAMP_S * 10_000.0) as usize;
        assert_eq!(r.current_a.len(), 2 * sine.len() + 2 * ramp + 10_000);
        assert_eq!(&r.current_a[..sine.len()], &sine[..]);
        assert_eq!(&r.current_a[r.current_a.len() - sine.len()..], &sine[..]);
        let hold = &r.current_a[sine.len() + ramp..sine.len() + ramp + 10_000];
        assert!(hold.iter().all(|&i| i == 1.8));
        // No step anywhere: the largest sample-to-sample change is the sine's own
        // (2π f a / f_s = 0.019 A) plus one ramp step (0.002 A) where the two meet.
        let max_step = r
            .current_a
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        assert!(max_step < 0.019 + 0.002 + 1e-9, "{max_step}");
        assert!(soak_record(&SINE, 2.5, 1.0, 1e4, 2.0)
            .unwrap_err()
            .contains("--soak-current-a 2.5"));
    }
}
