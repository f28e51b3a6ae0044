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
mod denoise {
    use maglab_signal::denoise::without_white_noise;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::PI;

    fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let normal = Normal::new(0.0, sigma).unwrap();
        (0..n).map(|_| normal.sample(&mut rng)).collect()
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
    }

    /// A coil current's departure from its model: a 47.3 Hz part with its second and fifth
    /// harmonic, 0.7 s at 10 kHz (not a whole number of periods: the record's ends do not meet).
    fn current(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let t = k as f64 * 1e-4;
                0.001
                    + 0.008 * (2.0 * PI * 47.3 * t).sin()
                    + 0.004 * (4.0 * PI * 47.3 * t + 1.0).cos()
                    + 0.002 * (10.0 * PI * 47.3 * t).sin()
            })
            .collect()
    }

    #[test]
    fn every_coefficient_above_a_negligible_noise_is_kept_and_the_record_returns_whole() {
        let x = current(7001);
        let y = without_white_noise(&x, 1e-12);
        let worst = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst}");
    }

    /// Of white noise alone, next to nothing is left: the universal threshold keeps a pure-noise
    /// coefficient with a probability of about 1/√(π ln n) for the largest of them.
    #[test]
    fn white_noise_alone_is_taken_out() {
        for seed in 0..5 {
            let e = noise(7000, 1e-3, seed);
            let left = rms(&without_white_noise(&e, 1e-3));
            assert!(left < 0.1e-3, "seed {seed}: {left:e} A left of 1 mA");
        }
    }

    /// On a current's departure with harmonics and 1 mA of noise, what is left of the noise is a
    /// third of it, in the middle of the record as at its ends: the kept coefficients' own noise
    /// and the part of the components' leakage (47.3 Hz is on no coefficient) that fell below the
    /// threshold. It is smooth: of the sample-to-sample wiggle, which reverses a Preisach
    /// memory at every sample, less than a tenth is left. The fundamental's amplitude is the
    /// clean record's (hard thresholding does not shrink it).
    #[test]
    fn a_noisy_current_comes_back_close_to_the_clean_one_and_smooth() {
        let clean = current(7000);
        let sigma = 1e-3;
        let wiggle = |x: &[f64]| rms(&x.windows(2).map(|w| w[1] - w[0]).collect::<Vec<f64>>());
        for seed in 0..5 {
            let e = noise(7000, sigma, seed);
            let noisy: Vec<f64> = clean.iter().zip(&e).map(|(c, e)| c + e).collect();
            let y = without_white_noise(&noisy, sigma);
            let err: Vec<f64> = y.iter().zip(&clean).map(|(a, b)| a - b).collect();
            let middle = &err[350..err.len() - 350];
            println!(
                "seed {seed}: left {:.3} σ ({:.3} σ in the middle), wiggle {:.3} of the noise's",
                rms(&err) / sigma,
                rms(middle) / sigma,
                wiggle(&err) / wiggle(&e)
            );
            assert!(rms(&err) < 0.4 * sigma, "seed {seed}: {:e}", rms(&err));
            assert!(rms(middle) < 0.4 * sigma, "seed {seed}: {:e}", rms(middle));
            assert!(wiggle(&err) < 0.1 * wiggle(&e), "seed {seed}");
            // The 47.3 Hz component over 33 whole periods (6977 samples).
            let periods = 33.0f64;
            let m = (periods / 47.3 * 1e4).round() as usize;
            let amplitude = |x: &[f64]| {
                let (mut s, mut c) = (0.0f64, 0.0f64);
                for (k, v) in x[..m].iter().enumerate() {
                    let w = 2.0 * PI * 47.3 * k as f64 * 1e-4;
                    s += v * w.sin();
                    c += v * w.cos();
                }
                2.0 * (s * s + c * c).sqrt() / m as f64
            };
            // The noisy record's own amplitude is the unbiased estimate; it is off the clean one
            // by the noise (standard error σ √(2/m)). The denoised record's is the noisy one's.
            let (a_y, a_noisy, a_clean) = (amplitude(&y), amplitude(&noisy), amplitude(&clean));
            let se = sigma * (2.0 / m as f64).sqrt();
            println!("  amplitude: denoised {a_y:.6}, noisy {a_noisy:.6}, clean {a_clean:.6}, se {se:.1e}");
            assert!((a_y - a_noisy).abs() < 0.5 * se, "seed {seed}");
            assert!((a_y - a_clean).abs() < 4.0 * se, "seed {seed}");
        }
    }
}
