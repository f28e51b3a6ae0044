//! The tests of `maglab-identify`'s modules, one module here per module there (they were `#[cfg(test)]`
//! modules in the source files). They live in one integration test so that `cargo test` does
//! not compile the crate a second time with `cfg(test)`: at `opt-level = 3` (the fits the other
//! tests run need it) that build cost ~60-70 s of CPU in every clean CI run (`Cargo.toml`,
//! `[lib] test = false`). The few internals they call are `#[doc(hidden)] pub`.

mod masses {
    use maglab_identify::masses::shifted;

    #[test]
    fn shifted_reads_later_samples_linearly_and_holds_the_ends() {
        let x = [0.0, 1.0, 4.0, 9.0];
        assert_eq!(shifted(&x, 0.0), x.to_vec());
        assert_eq!(shifted(&x, 1.0), vec![1.0, 4.0, 9.0, 9.0]);
        assert_eq!(shifted(&x, -1.0), vec![0.0, 0.0, 1.0, 4.0]);
        assert_eq!(shifted(&x, 0.5), vec![0.5, 2.5, 6.5, 9.0]);
        assert!(shifted(&[], 0.3).is_empty());
    }

    use maglab_identify::masses::{
        displacement_noise_m, fit_floor_m, LagCorrection, SQRT_NOISE_BIAS_MAX,
    };
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// White noise of RMS `sigma_m`, `n` samples, from `seed`.
    fn white(n: usize, sigma_m: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let normal = Normal::new(0.0, sigma_m).unwrap();
        (0..n).map(|_| normal.sample(&mut rng)).collect()
    }

    #[test]
    fn the_noise_of_a_slow_sweep_is_read_within_3_percent_whatever_its_reversals() {
        // A 1 Hz triangle of 60 µm at 10 kHz (reversals every 0.5 s) plus white noise.
        let n = 30_000;
        for (k, sigma) in [0.05e-6, 0.125e-6, 0.5e-6].into_iter().enumerate() {
            let noise = white(n, sigma, 7 + k as u64);
            let y: Vec<f64> = (0..n)
                .map(|i| {
                    let p = (i as f64 * 1e-4).fract();
                    60e-6 * if p < 0.5 { 2.0 * p } else { 2.0 - 2.0 * p } + noise[i]
                })
                .collect();
            let read = displacement_noise_m(&y);
            assert!(
                (read / sigma - 1.0).abs() < 0.03,
                "σ = {sigma:e} m read as {read:e} m"
            );
        }
        assert_eq!(displacement_noise_m(&[1.0, 2.0]), 0.0);
        // A noise-free ramp has no noise.
        let ramp: Vec<f64> = (0..1000).map(|i| i as f64 * 1e-8).collect();
        assert!(displacement_noise_m(&ramp) < 1e-20);
    }

    #[test]
    fn the_lag_correction_amplifies_white_noise_by_its_noise_gain() {
        let base = actuator_params::paper_defaults();
        let correction = LagCorrection::new(&base, [70.0, 0.7783, 392.0]);
        let step_s = 1e-4;
        let gain = correction.noise_gain(step_s);
        let noise = white(200_000, 1.0, 3);
        let u = correction.displacement(&noise, step_s);
        // Away from the ends, where the derivatives are not taken.
        let inner = &u[100..u.len() - 100];
        let rms = (inner.iter().map(|v| v * v).sum::<f64>() / inner.len() as f64).sqrt();
        assert!(gain > 1.0, "gain {gain}");
        assert!((rms / gain - 1.0).abs() < 0.01, "RMS {rms}, gain {gain}");
    }

    #[test]
    fn at_the_fit_floor_the_square_root_is_biased_by_at_most_its_bound() {
        // No noise: the zero band alone.
        assert_eq!(fit_floor_m(0.67e-6, 0.0, 67e-6), 0.67e-6);
        // Noise: E[√(u + n)] against √u at the floor, by Monte Carlo (n Gaussian, 10⁶ draws).
        let sigma = 0.5e-6;
        let floor = fit_floor_m(0.67e-6, sigma, 67e-6);
        assert!(
            floor > 10.0 * sigma && floor < 12.0 * sigma,
            "floor {floor:e} m"
        );
        let draws = white(1_000_000, sigma, 5);
        let mean = draws
            .iter()
            .map(|n| (floor + n).max(0.0).sqrt())
            .sum::<f64>()
            / draws.len() as f64;
        let bias = 1.0 - mean / floor.sqrt();
        assert!(
            bias > 0.7 * SQRT_NOISE_BIAS_MAX && bias < 1.2 * SQRT_NOISE_BIAS_MAX,
            "relative bias {bias:e} at the floor"
        );
    }
}
mod lines {
    use maglab_dataset::StartState;
    use maglab_identify::design::{Experiment, Grid};
    use maglab_identify::lines::*;

    fn experiment<'a>(input: &'a [f64], output: &'a [f64], selected: &'a [bool]) -> Experiment<'a> {
        Experiment {
            label: "loop",
            input,
            output,
            selected,
            initial: StartState::Periodic,
            weights: None,
        }
    }

    /// A steep loop (output changing over a tenth of the range) gets most of its lines there; a
    /// linear response gets equal intervals (to sampling); no change gives the uniform grid.
    #[test]
    fn lines_follow_the_output_change() {
        let n = 2001;
        let input: Vec<f64> = (0..n)
            .map(|t| 100.0 * (2.0 * std::f64::consts::PI * t as f64 / (n - 1) as f64).sin())
            .collect();
        let steep: Vec<f64> = input.iter().map(|&u| (u / 5.0).tanh()).collect();
        let linear: Vec<f64> = input.iter().map(|&u| 0.01 * u).collect();
        let flat = vec![1.0; n];
        let selected = vec![true; n];
        let g = choose_grid(
            -110.0,
            110.0,
            LineChoice::EqualOutput,
            &[experiment(&input, &steep, &selected)],
        );
        let lines = g.lines();
        let inside = lines.iter().filter(|h| h.abs() <= 11.0).count();
        assert!(inside >= 12, "{lines:?}");
        let widths: Vec<f64> = lines.windows(2).map(|w| w[1] - w[0]).collect();
        let min = widths.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(min >= MIN_INTERVAL_FRACTION * g.cell_width() * (1.0 - 1e-12));
        let g = choose_grid(
            -100.0,
            100.0,
            LineChoice::EqualOutput,
            &[experiment(&input, &linear, &selected)],
        );
        for (k, h) in g.lines().iter().enumerate() {
            let expected = -100.0 + 8.0 * k as f64;
            assert!((h - expected).abs() < 2.0, "line {k}: {h} vs {expected}");
        }
        let g = choose_grid(
            -100.0,
            100.0,
            LineChoice::EqualOutput,
            &[experiment(&input, &flat, &selected)],
        );
        assert_eq!(g, Grid::uniform(-100.0, 100.0));
        assert_eq!(
            choose_grid(-1.0, 1.0, LineChoice::Uniform, &[]),
            Grid::uniform(-1.0, 1.0)
        );
        assert_eq!(
            LineChoice::parse("equal-output"),
            Ok(LineChoice::EqualOutput)
        );
        assert!(LineChoice::parse("equal").unwrap_err().contains("`equal`"));
    }

    /// Two folds whatever the number of experiments; in each the fit and predicted rows split
    /// the selected rows of every experiment in blocks, and the two folds swap them.
    #[test]
    fn folds_alternate_blocks_of_every_experiment() {
        for experiments in [1usize, 2, 5] {
            let rows: Vec<Vec<bool>> = (0..experiments + 1)
                // (the last experiment has no fit rows: in no fold)
                .map(|e| (0..400).map(|t| e < experiments && t % 3 != 0).collect())
                .collect();
            let selected: Vec<&[bool]> = rows.iter().map(|r| r.as_slice()).collect();
            let folds = validation_folds(&selected);
            assert_eq!(folds.len(), 2);
            for (e, row) in rows.iter().enumerate() {
                for (t, &selected_row) in row.iter().enumerate() {
                    let (fit0, pred0) = (folds[0].0[e][t], folds[0].1[e][t]);
                    assert!(!(fit0 && pred0));
                    assert_eq!(fit0 || pred0, selected_row);
                    assert_eq!((folds[1].0[e][t], folds[1].1[e][t]), (pred0, fit0));
                }
                let fitted = row.iter().zip(&folds[0].0[e]).filter(|p| *p.1).count();
                let total = row.iter().filter(|&&x| x).count();
                assert!(
                    total == 0 || (fitted * 2).abs_diff(total) <= total / 10,
                    "{e}"
                );
            }
        }
        assert!(validation_folds(&[&[false; 10]]).is_empty());
    }
}
mod quality {
    use maglab_identify::masses::{FileReport, StartFrom};
    use maglab_identify::quality::*;

    fn file(nrmse: f64, above: usize) -> FileReport {
        FileReport {
            file: "00_forc.csv".into(),
            samples: 1000,
            clipped_negative: 0,
            above_stroke: above,
            sign_changes: 1,
            noise_m: 0.0,
            fit_floor_m: 0.0,
            rows_below_floor: 0,
            nrmse_magnetization: Some(nrmse),
            nrmse_displacement: Some(nrmse),
            h_a_per_m: Vec::new(),
            m_measured_a_per_m: Vec::new(),
            m_predicted_a_per_m: Vec::new(),
            start_from: StartFrom::Documented,
        }
    }

    fn sine(hz: f64, nrmse: f64) -> DynamicResidual {
        DynamicResidual {
            file: format!("sine_{hz}.csv"),
            frequency_hz: hz,
            nrmse,
        }
    }

    #[test]
    fn a_model_that_fits_gets_no_warning() {
        // The figures of a case without an effect (seed 1, case 4).
        let dynamic = [sine(20.0, 0.029), sine(100.0, 0.012), sine(400.0, 0.3)];
        let w = warnings(
            &[file(0.003, 160)],
            Masses::Saturating {
                sum_a_per_m: 7.87e5,
            },
            7.87e5,
            &dynamic,
            Some(200.0),
        );
        assert!(w.is_empty(), "{w:?}");
    }

    #[test]
    fn a_missed_record_whose_start_was_estimated_says_so() {
        let warning = |start_from| {
            let missed = FileReport {
                start_from,
                ..file(0.24, 0)
            };
            let w = warnings(
                &[missed],
                Masses::Saturating {
                    sum_a_per_m: 7.87e5,
                },
                7.87e5,
                &[],
                None,
            );
            assert_eq!(w.len(), 1, "{w:?}");
            w[0].clone()
        };
        assert!(!warning(StartFrom::Documented).contains("start state"));
        assert!(warning(StartFrom::Estimated).contains("was estimated (document it)"));
        let previous = warning(StartFrom::EstimatedForPrevious);
        assert!(
            previous.contains("documents it `previous`") && previous.contains("documented reset"),
            "{previous}"
        );
        // A record within the limit gets no warning, however its start was chosen.
        let fits = FileReport {
            start_from: StartFrom::EstimatedForPrevious,
            ..file(0.003, 0)
        };
        let sum = Masses::Saturating {
            sum_a_per_m: 7.87e5,
        };
        assert!(warnings(&[fits], sum, 7.87e5, &[], None).is_empty());
    }

    #[test]
    fn each_limit_is_named_when_crossed() {
        let w = warnings(
            &[file(0.77, 710)],
            Masses::Saturating { sum_a_per_m: 1.2e5 },
            7.87e5,
            &[],
            None,
        );
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].contains("00_forc.csv") && w[0].contains("77.0 %") && w[0].contains("71 %"));
        assert!(w[1].contains("0.15 x M_s"));
        let dynamic = [sine(20.0, 0.42), sine(50.0, 0.12), sine(400.0, 0.01)];
        let w = warnings(
            &[file(0.003, 0)],
            Masses::Saturating {
                sum_a_per_m: 7.87e5,
            },
            7.87e5,
            &dynamic,
            Some(200.0),
        );
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("sine_20.csv at 20 Hz, 42.0 %"), "{w:?}");
    }

    #[test]
    fn experiments_above_the_fitted_band_are_not_judged() {
        // The held-out band may disagree: that is the diagnosis' business.
        let dynamic = [sine(20.0, 0.01), sine(300.0, 0.9), sine(400.0, 0.9)];
        assert!(warnings(
            &[],
            Masses::Saturating {
                sum_a_per_m: 7.87e5
            },
            7.87e5,
            &dynamic,
            Some(200.0)
        )
        .is_empty());
        assert_eq!(
            warnings(
                &[],
                Masses::Saturating {
                    sum_a_per_m: 7.87e5
                },
                7.87e5,
                &dynamic,
                None
            )
            .len(),
            1
        );
    }

    #[test]
    fn a_constant_at_an_end_of_its_search_is_named_with_that_end() {
        let centre = [98.0, 0.584, 470.4];
        let factors = [10.0, 5.0, 2.0];
        // A noise-only identification (seed 3 case 18): inside.
        assert!(search_bound_warnings([71.15, 0.7958, 403.1], centre, factors).is_empty());
        // A 200 Hz sensor lag absorbed (seed 3 case 30): R_eddy and f0 at their floors.
        let w = search_bound_warnings([9.81, 0.3781, 235.2], centre, factors);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].starts_with("R_eddy = 9.8100 ohm lies at the lower end"),
            "{w:?}"
        );
        assert!(w[0].contains("98.0000 ohm / 10 = 9.8000 ohm"), "{w:?}");
        assert!(
            w[1].starts_with("f0 = 235.2000 Hz lies at the lower end"),
            "{w:?}"
        );
        // The upper end, and 1 % inside it is still at it; 2 % inside is not.
        let w = search_bound_warnings([98.0, 2.914, 470.4], centre, factors);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("xi = 2.9140 lies at the upper end"),
            "{w:?}"
        );
        assert!(search_bound_warnings([98.0, 2.86, 470.4], centre, factors).is_empty());
    }
}
mod dynamics_phase_lag {
    use maglab_identify::dynamics::phase_lag::*;

    #[test]
    fn damping_inverts_the_second_order_phase() {
        for &(xi, r) in &[(0.65f64, 0.1f64), (0.78, 0.5), (0.2, 0.9), (0.5, 1.5)] {
            // Phase of 1 / (1 - r² + 2iξr).
            let theta = (2.0 * xi * r).atan2(1.0 - r * r);
            assert!((damping_from_lag(theta, r) - xi).abs() < 1e-12);
        }
    }

    #[test]
    fn the_mesh_is_geometric_up_to_r_bar() {
        let m = coarse_mesh(500.0, 40);
        assert!((m[0] - 1.0).abs() < 1e-12 && (m[39] - 500.0).abs() < 1e-9);
        let ratio = m[1] / m[0];
        assert!(m.windows(2).all(|w| (w[1] / w[0] - ratio).abs() < 1e-9));
    }
}

mod model {
    use maglab_dataset::StartState;
    use maglab_identify::columns::Series;
    use maglab_identify::design::Grid;
    use maglab_identify::model::{initial_of, is_closed_loop, PreisachModel, FORMAT, FORMAT_1};

    fn series(label: &str, input: Vec<f64>, output: Vec<f64>, selected: Vec<bool>) -> Series {
        Series {
            label: label.into(),
            lines: (1..=input.len() as u64).collect(),
            input,
            output,
            selected,
        }
    }

    #[test]
    fn each_experiment_is_judged_on_its_own_fit_rows() {
        let t: Vec<f64> = (0..=200).map(|k| k as f64 / 200.0).collect();
        let cycle = |x: &f64| (2.0 * std::f64::consts::PI * x).sin();
        let loop_in: Vec<f64> = t.iter().map(cycle).collect();
        let loop_out: Vec<f64> = t.iter().map(|x| cycle(&(x - 0.05))).collect();
        let all = vec![true; t.len()];
        let closed = series("closed", loop_in.clone(), loop_out.clone(), all.clone());
        // A first magnetization curve: from zero up, it does not return.
        let ramp = series("ramp", t.clone(), t.iter().map(|x| x * x).collect(), all);
        // A closed loop whose fit rows are only its first half is not one on those rows.
        let half: Vec<bool> = (0..t.len()).map(|k| k <= 100).collect();
        let half_selected = series("half", loop_in, loop_out, half);
        let mut none_selected = ramp.clone();
        none_selected.selected = vec![false; t.len()];
        assert!(is_closed_loop(&closed));
        assert!(!is_closed_loop(&ramp));
        assert!(!is_closed_loop(&half_selected));
        assert!(!is_closed_loop(&none_selected), "judged on all rows");
        let demag = StartState::DemagnetizedAtFirstInput;
        assert_eq!(initial_of(&closed, demag, true), StartState::Periodic);
        assert_eq!(initial_of(&ramp, demag, true), demag);
        assert_eq!(initial_of(&closed, demag, false), demag);
    }

    /// A model file of the first format reads with its start state renamed: `demagnetized`
    /// meant around the first input there, `demagnetized-at-zero` what `demagnetized` means now.
    #[test]
    fn a_first_format_model_file_reads_with_its_start_state_renamed() {
        let weights = vec![1.0; maglab_identify::CELL_COUNT];
        let model = PreisachModel::from_weights(
            Grid::uniform(-1.0, 1.0),
            &weights,
            StartState::NegativeSaturation,
        );
        let dir = std::env::temp_dir().join(format!("preisach-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (old, new) in [
            ("demagnetized", StartState::DemagnetizedAtFirstInput),
            ("demagnetized-at-zero", StartState::Demagnetized),
            ("periodic", StartState::Periodic),
        ] {
            let mut v = serde_json::to_value(&model).unwrap();
            v["format"] = FORMAT_1.into();
            v["initial_state"] = old.into();
            let path = dir.join("old.json");
            std::fs::write(&path, v.to_string()).unwrap();
            let back = PreisachModel::load(&path).unwrap();
            assert_eq!(back.initial_state, new, "{old}");
            assert_eq!(back.format, FORMAT);
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}

mod coverage {
    use maglab_identify::coverage::*;

    fn sine(bias: f64, amp: f64, cycles: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| bias + amp * (2.0 * std::f64::consts::PI * cycles * k as f64 / n as f64).sin())
            .collect()
    }

    #[test]
    fn an_uncovered_loop_is_warned_about_only_when_missed_at_its_slowest_frequency() {
        // Reversal sweep: from 0 A up to the top, down to 1.4 − 0.14 k, back up, ...
        let mut forc: Vec<f64> = (0..=140).map(|s| s as f64 * 0.01).collect();
        for k in 1..=10 {
            let steps = (14 * k) as usize;
            forc.extend((1..=steps).map(|s| 1.4 - s as f64 * 0.01));
            forc.extend((1..=steps).rev().map(|s| 1.4 - (s - 1) as f64 * 0.01));
        }
        let small = sine(0.55, 0.15, 20.0, 10_000);
        let dynamic = vec![("small".to_string(), 20.0, &small[..])];
        let u = uncovered_loops(&MeasuredLoops::of_records(&[&forc], 1.4 / 25.0), &dynamic);
        assert_eq!(u.len(), 1, "{u:?}");
        let w = coverage_warning(&u, |_| Some(0.07), 0.02, 2).unwrap();
        assert!(w.contains("between 0.400 and 0.700 A at 7.0 %"), "{w}");
        assert!(coverage_warning(&u, |_| Some(0.005), 0.02, 2).is_none());
        // Only the slowest record of a loop counts: the same loop at 400 Hz missed by the
        // dynamics is no sign of the masses when its 20 Hz record fits.
        let mut both = u.clone();
        both.push(UncoveredLoop {
            file: "small-400".into(),
            frequency_hz: 400.0,
            ..u[0].clone()
        });
        let nrmse = |f: &str| Some(if f == "small-400" { 0.05 } else { 0.005 });
        assert!(coverage_warning(&both, nrmse, 0.02, 3).is_none());
    }
}

mod reach {
    use maglab_identify::design::Grid;
    use maglab_identify::fit::Bands;
    use maglab_identify::reach::*;
    use maglab_identify::LEVELS;

    #[test]
    fn a_reach_inside_the_grid_gets_a_band_on_each_side_and_the_reach_on_grid_lines() {
        let g = identification_grid(
            Grid::uniform(-30e3, 30e3),
            Reach {
                lo_a_per_m: 0.0,
                hi_a_per_m: 21_560.0,
            },
        );
        assert_eq!(
            g.bands,
            Bands {
                low: true,
                high: true
            }
        );
        let lines = g.grid.lines();
        assert!((lines[1] - 0.0).abs() < 1e-9, "{}", lines[1]);
        assert!((lines[LEVELS - 1] - 21_560.0).abs() < 1e-6);
        assert_eq!(g.reach.unwrap().hi_a_per_m, 21_560.0);
    }

    #[test]
    fn a_side_the_data_reach_keeps_the_base_grid_and_both_keep_it_all() {
        let base = Grid::uniform(-30e3, 30e3);
        let one = identification_grid(
            base,
            Reach {
                lo_a_per_m: -30.8e3,
                hi_a_per_m: 21e3,
            },
        );
        assert_eq!(
            one.bands,
            Bands {
                low: false,
                high: true
            }
        );
        assert_eq!(one.grid.h_min, -30e3);
        assert!((one.grid.lines()[LEVELS - 1] - 21e3).abs() < 1e-6);
        let both = identification_grid(
            base,
            Reach {
                lo_a_per_m: -30.8e3,
                hi_a_per_m: 30.8e3,
            },
        );
        assert_eq!(both.grid, base);
        assert!(!both.has_bands());
        assert_eq!(both.reach, None);
    }

    #[test]
    fn the_reach_of_records_is_c0_times_their_current_extremes() {
        let a = [0.2, 1.4, 0.5];
        let b = [0.0, 0.7];
        let r = Reach::of_currents([&a[..], &b[..]], 15_400.0).unwrap();
        assert_eq!((r.lo_a_per_m, r.hi_a_per_m), (0.0, 1.4 * 15_400.0));
        assert_eq!(Reach::of_currents([&[f64::NAN][..]], 1.0), None);
    }
}

mod experiments {
    use maglab_dataset::data::write_measurement;
    use maglab_dataset::excitation::{forc_excitation, ExciteOptions};
    use maglab_dataset::records::{sine_record, soak_record, Sine};
    use maglab_identify::experiments::{
        load_split_dataset, sinusoidal_stretch, steepest_change, ClassifyOptions, Kind,
    };
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use std::path::Path;

    const RATE_HZ: f64 = 10_000.0;

    /// A triangle between `lo` and `hi` A at `f` Hz for `seconds`, sampled at `RATE_HZ`.
    fn triangle(lo: f64, hi: f64, f: f64, seconds: f64) -> Vec<f64> {
        let n = (seconds * RATE_HZ) as usize;
        (0..n)
            .map(|k| {
                let phase = (k as f64 / RATE_HZ * f).fract();
                let up = 1.0 - (2.0 * phase - 1.0).abs();
                lo + (hi - lo) * up
            })
            .collect()
    }

    fn write(dir: &Path, name: &str, current_a: &[f64]) {
        let t: Vec<f64> = (0..current_a.len()).map(|k| k as f64 / RATE_HZ).collect();
        let y: Vec<f64> = current_a.iter().map(|i| 1e-6 * i).collect();
        write_measurement(&dir.join(name), &t, current_a, &y, None).unwrap();
    }

    #[test]
    fn a_sine_at_the_dynamic_limit_changes_as_fast_as_the_rule_allows() {
        // The rule's limit is the steepest change of a sine at `dynamic_min_hz` spanning the
        // record: such a sine meets it (within the sampling), a 20 % faster one exceeds it.
        let o = ClassifyOptions::default();
        let sine = |f: f64| {
            sine_record(
                &Sine {
                    frequency_hz: f,
                    amplitude_a: 0.4,
                    bias_a: 0.5,
                    duration_s: 1.0,
                },
                RATE_HZ,
            )
            .current_a
        };
        let at = steepest_change(&sine(o.dynamic_min_hz), 1.0 / RATE_HZ, o.dynamic_min_hz);
        assert!((at.range_a - 0.8).abs() < 1e-6, "{at:?}");
        assert!((at.change_a / at.limit_a - 1.0).abs() < 1e-3, "{at:?}");
        let faster = steepest_change(
            &sine(1.2 * o.dynamic_min_hz),
            1.0 / RATE_HZ,
            o.dynamic_min_hz,
        );
        assert!(faster.change_a > 1.15 * faster.limit_a, "{faster:?}");
    }

    #[test]
    fn the_reversal_sweeps_the_tools_write_are_quasi_static() {
        // `maglab excite --design forc` (1 Hz) and the firmware's programme (2 Hz,
        // `FORC_SWEEP_HZ`), at the rates they are recorded at: the first reversal curves are
        // short excursions near the top, a stretch of them must not pass for a sinusoid.
        let o = ClassifyOptions::default();
        for (sweep_rate_hz, sample_rate_hz) in [(1.0, 1_000.0), (1.0, 10_000.0), (2.0, 10_000.0)] {
            let forc = forc_excitation(&ExciteOptions {
                h_min_a_per_m: -30_000.0,
                h_max_a_per_m: 30_000.0,
                coil_factor_per_m: 15_000.0,
                sweep_rate_hz,
                sample_rate_hz,
                overdrive: 0.05,
            })
            .unwrap();
            let step_s = 1.0 / sample_rate_hz;
            assert_eq!(sinusoidal_stretch(&forc.current_a, step_s, &o), None);
            let s = steepest_change(&forc.current_a, step_s, o.dynamic_min_hz);
            assert!(
                s.change_a < s.limit_a,
                "{sweep_rate_hz} Hz at {sample_rate_hz} Hz: {s:?}"
            );
        }
    }

    #[test]
    fn a_noisy_reversal_sweep_is_slow_everywhere() {
        // The bench's FORC sweep runs as a full-range triangle at 2 Hz (`FORC_SWEEP_HZ`), 8
        // times slower than the limit; current noise of 1 % of the range does not make it fast.
        let o = ClassifyOptions::default();
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.02).unwrap();
        let i: Vec<f64> = triangle(-1.0, 1.0, 2.0, 5.0)
            .into_iter()
            .map(|i| i + noise.sample(&mut rng))
            .collect();
        let s = steepest_change(&i, 1.0 / RATE_HZ, o.dynamic_min_hz);
        assert!(s.change_a < s.limit_a, "{s:?}");
        let clean = steepest_change(
            &triangle(-1.0, 1.0, 2.0, 5.0),
            1.0 / RATE_HZ,
            o.dynamic_min_hz,
        );
        assert!(clean.change_a < 0.15 * clean.limit_a, "{clean:?}");
    }

    #[test]
    fn a_thermal_soak_is_not_used_unless_its_folder_says_quasi_static() {
        let dir = tempfile::tempdir().unwrap();
        // The soak `maglab diagnose` advises: the design's slowest sine (20 Hz, 0.18 A around
        // 0.53 A), a hold at 0.9 of a 2.2 A limit, the sine again. Its spectrum peaks at the
        // hold's 0.02 Hz, and its sines change the current more slowly than a 10 Hz sine over
        // its 1.45 A range would: the stretches of sine make it a dynamic experiment mixed with
        // a hold all the same.
        let sine = Sine {
            frequency_hz: 20.0,
            amplitude_a: 0.18,
            bias_a: 0.53,
            duration_s: 1.0,
        };
        let soak = soak_record(&sine, 1.98, 20.0, RATE_HZ, 2.2).unwrap();
        let sine_slope_a_per_s = soak.current_a[..10_000]
            .windows(2)
            .map(|w| (w[1] - w[0]).abs() * RATE_HZ)
            .fold(0.0, f64::max);
        let range_a = 1.98 - (0.53 - 0.18);
        assert!(sine_slope_a_per_s < std::f64::consts::PI * 10.0 * range_a);
        write(dir.path(), "00_forc.csv", &triangle(-1.0, 1.0, 2.0, 3.0));
        write(
            dir.path(),
            "01_sine.csv",
            &sine_record(&sine, RATE_HZ).current_a,
        );
        write(dir.path(), "02_soak.csv", &soak.current_a);
        let split = load_split_dataset(dir.path(), &ClassifyOptions::default()).unwrap();
        let kinds: Vec<Kind> = split.classification.iter().map(|c| c.kind).collect();
        assert_eq!(kinds, [Kind::QuasiStatic, Kind::Dynamic, Kind::NotUsed]);
        assert_eq!((split.quasi_static.len(), split.dynamic.len()), (1, 1));
        let why = &split.classification[2].reason;
        println!("{why}");
        assert!(
            why.contains("a sinusoid at 20.0") && why.contains("quasi-static/"),
            "{why}"
        );

        // The sub-folder overrides rule 2.
        let qs = dir.path().join("quasi-static");
        std::fs::create_dir(&qs).unwrap();
        std::fs::rename(dir.path().join("02_soak.csv"), qs.join("02_soak.csv")).unwrap();
        let split = load_split_dataset(dir.path(), &ClassifyOptions::default()).unwrap();
        assert_eq!(split.quasi_static.len(), 2);
    }

    #[test]
    fn a_folder_of_records_none_of_which_can_be_used_is_an_error_saying_why() {
        let dir = tempfile::tempdir().unwrap();
        let mut step = vec![0.0; 5_000];
        step.extend(vec![1.0; 5_000]);
        write(dir.path(), "step.csv", &step);
        let e = load_split_dataset(dir.path(), &ClassifyOptions::default()).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("no file of the dataset folder can be used"),
            "{text}"
        );
        assert!(text.contains("but not slow everywhere"), "{text}");
    }
}
