//! Tests of the signal measures through their public API.

mod golden {
    use maglab_signal::golden::*;

    #[test]
    fn finds_the_minimum_of_a_parabola_to_the_bracket_width() {
        let x = golden_section_min(-1.0, 3.0, 40, |x| (x - 0.7).powi(2));
        assert!((x - 0.7).abs() < 4.0 * 0.62f64.powi(40) + 1e-9, "{x}");
    }

    #[test]
    fn a_minimum_at_the_edge_is_approached() {
        let x = golden_section_min(0.0, 1.0, 30, |x| x);
        assert!(x < 1e-5, "{x}");
    }
}
mod spectrum {
    use maglab_signal::spectrum::*;
    use std::f64::consts::PI;

    #[test]
    fn a_biased_sine_with_harmonics_gives_its_frequency_and_phase() {
        let step = 1e-4;
        let f = 47.3;
        let x: Vec<f64> = (0..6000)
            .map(|k| {
                let t = k as f64 * step;
                2.0 + 0.7 * (2.0 * PI * f * t + 0.4).sin() + 0.3 * (4.0 * PI * f * t + 1.0).cos()
            })
            .collect();
        let tone = dominant_tone(&x, step).unwrap();
        // Bin = 1/0.6 s = 1.67 Hz; the interpolation lands within 5 % of a bin.
        assert!(
            (tone.frequency_hz - f).abs() < 0.05 * tone.bin_hz,
            "{tone:?}"
        );
        assert!(tone.tonal_fraction > 0.7, "{tone:?}");
        let refined = refine_frequency(&x, step, &tone, 3);
        assert!((refined - f).abs() < 1e-6, "{refined}");
        let fit = harmonic_fit(&x, step, refined, 0..x.len(), 3).unwrap();
        assert!((fit.amplitude() - 0.7).abs() < 1e-6);
        assert!((fit.phase_rad() - 0.4).abs() < 1e-6);
        assert!((fit.mean - 2.0).abs() < 1e-6);
    }

    #[test]
    fn a_reversal_sequence_is_not_tonal() {
        // Reversals of decreasing amplitude at a constant sweep rate (like a FORC excitation):
        // the half-period shrinks with the amplitude, so the power spreads over many bins.
        let mut x = Vec::new();
        for a in (1..=20).rev() {
            let amp = a as f64;
            let n = 10 * a;
            for k in 0..n {
                x.push(-amp + 2.0 * amp * k as f64 / n as f64);
            }
            for k in 0..n {
                x.push(amp - 2.0 * amp * k as f64 / n as f64);
            }
        }
        let tone = dominant_tone(&x, 1e-3).unwrap();
        assert!(tone.tonal_fraction < 0.9, "{tone:?}");
    }
}
mod measures {
    use maglab_signal::branches::*;
    use maglab_signal::noise::*;
    use maglab_signal::spectrum::*;
    use std::f64::consts::PI;

    #[test]
    fn noise_level_of_white_noise_with_a_harmonic() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let normal = Normal::new(0.0, 2.0).unwrap();
        let x: Vec<f64> = (0..10000)
            .map(|k| normal.sample(&mut rng) + 5.0 * (2.0 * PI * 0.37 * k as f64).sin())
            .collect();
        let s = white_noise_sigma(&x);
        // ~3500 bins: the median's relative standard error is ~1/sqrt(3500)·1.4 ≈ 2.5 %; allow 10 %.
        assert!((s - 2.0).abs() < 0.2, "{s}");
    }

    #[test]
    fn fundamental_and_labels_of_a_sine() {
        let rate = 10_000.0;
        let x: Vec<f64> = (0..5000)
            .map(|k| 0.5 + 0.3 * (2.0 * PI * 50.0 * k as f64 / rate).sin())
            .collect();
        let f = dominant_frequency_hz(&x, rate).unwrap();
        assert!((f - 50.0).abs() < 0.5, "{f}");
        let r = whole_periods(100, 5000, 50.0, rate);
        let c = fourier_coefficient(&x, r, 50.0, rate);
        assert!((c.norm() - 0.3).abs() < 1e-9, "{c}");
        let labels = branch_labels(&x);
        assert!(labels.ascending[10] && !labels.ascending[60]);
        assert!(labels.near_reversal[50] && !labels.near_reversal[100]);
    }
}
