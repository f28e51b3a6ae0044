//! The tests of `maglab-model`'s modules, one module here per module there, through the
//! crate's public API (an integration test: no second `cfg(test)` build of the crate at
//! `opt-level = 3`).

mod candidates {
    use maglab_model::candidates::*;
    use maglab_model::effects::EffectName;
    use maglab_model::model::Nominal;

    #[test]
    fn coordinates_round_trip_and_stay_in_range() {
        let s = ParamSpec {
            name: "x",
            lo: 10.0,
            hi: 5000.0,
            log: true,
            stage: Stage::Mech,
            edge: Edge::Low,
        };
        assert!((s.value(s.coordinate(250.0)) - 250.0).abs() < 1e-9);
        assert!(s.value(50.0) <= 5000.0 && s.value(-50.0) >= 10.0);
        let l = ParamSpec {
            name: "y",
            lo: -1.0,
            hi: 1.0,
            log: false,
            stage: Stage::Mech,
            edge: Edge::None,
        };
        assert!((l.value(l.coordinate(0.3)) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn a_load_at_the_lightest_mass_is_pinned() {
        // A load of 2 % of the rod's mass does not load the rod: it is a filter on the
        // reading (the sensor's form), so the load candidate pinned there is no explanation.
        let n = Nominal::from_params(&actuator_params::paper_defaults());
        let specs = effect_parameters(EffectName::MechanicalLoad, &n);
        let mass = specs
            .iter()
            .find(|s| s.name == "mass_ratio")
            .expect("mass_ratio");
        assert!(mass.pinned(mass.coordinate(0.02)));
        assert!(mass.pinned(mass.coordinate(10.0)));
        assert!(!mass.pinned(mass.coordinate(0.05)));
        assert!(!mass.pinned(mass.coordinate(0.3)));
    }

    #[test]
    fn a_start_at_a_limit_is_inside_it_and_has_a_gradient() {
        let skew = ParamSpec {
            name: "channel_skew_samples",
            lo: -1.0,
            hi: 1.0,
            log: false,
            stage: Stage::Mech,
            edge: Edge::Both,
        };
        let slope = |z: f64| (skew.value(z + 1e-3) - skew.value(z)) / 1e-3;
        for v in [-1.0, 1.0, 1.5] {
            let at_limit = skew.coordinate(v);
            let start = skew.start_coordinate(v);
            // At the limit a Jacobian step moves the value by ~1e-8 samples; from the start by ~1e-5.
            assert!(slope(at_limit).abs() < 1e-5, "{v}: {}", slope(at_limit));
            assert!(slope(start).abs() > 1e-2, "{v}: {}", slope(start));
            assert!(!skew.pinned(start));
            let margin = (skew.value(start).abs() - 1.0).abs();
            assert!((margin - 2.0 * START_MARGIN).abs() < 1e-9, "{v}: {margin}");
        }
        // Inside the margin a start is the value itself.
        assert!((skew.value(skew.start_coordinate(0.3)) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn a_value_within_one_percent_of_either_end_is_at_the_range_end() {
        // A refitted f0 in a ×/÷ 1.06 band (log scale): no physical limit at either end, yet a fit
        // that ends there wanted a value beyond what the file allows.
        let f0 = ParamSpec {
            name: "resonance_hz",
            lo: 392.0 / 1.06,
            hi: 392.0 * 1.06,
            log: true,
            stage: Stage::Mech,
            edge: Edge::None,
        };
        let at_end = |v: f64| f0.at_range_end(f0.coordinate(v));
        // 1 % of the log range is a factor of 1.06^0.02 (0.12 %).
        assert!(at_end(369.85) && at_end(392.0 / 1.06) && at_end(415.5) && at_end(500.0));
        assert!(!at_end(371.0) && !at_end(392.0) && !at_end(415.0));
        assert!(
            !f0.pinned(f0.coordinate(369.85)),
            "no physical limit: never pinned"
        );
    }

    #[test]
    fn counts_match_specs() {
        let n = Nominal::from_params(&actuator_params::paper_defaults());
        for e in EffectName::LIBRARY {
            assert_eq!(effect_parameters(e, &n).len(), effect_parameter_count(e));
            for s in effect_starts(e, &n) {
                assert_eq!(s.len(), effect_parameter_count(e));
            }
        }
    }

    #[test]
    fn a_richer_form_adds_its_second_term_after_the_rest() {
        let n = Nominal::from_params(&actuator_params::paper_defaults());
        let eddy = EffectName::EddyFrequencyDependence;
        let amp = EffectName::AmplifierBandwidth;
        let c = Candidate::single(eddy).with_richer(eddy);
        assert_eq!(c.name(), "eddy_frequency_dependence(2 paths)");
        assert_eq!(c.distinct_effects(), vec![eddy]);
        let specs = parameters(&c, &n, &REFIT_RANGE);
        assert_eq!(specs.len(), COMMON_PARAMETER_COUNT + 3 + 2);
        assert_eq!(parameter_count_at(&c.effects, 1), 2);
        // R_dc from the refitted R (60 ohm) and the anchor over the whole step (3 x 2).
        let (e, _) = model_parameters(&c, &[60.0, 0.7, 400.0, 0.0, 3.0, 100.0, 0.5, 2.0, 1000.0]);
        assert_eq!(e.eddy_path, Some((3.0, 100.0)));
        assert_eq!(e.second_eddy_path, Some((2.0, 1000.0)));
        assert!((e.eddy_resistance_ohm - 60.0 / 6f64.sqrt()).abs() < 1e-12);
        // A pair with the richer eddy: the second path's parameters come last.
        let pair = Candidate {
            effects: vec![amp, eddy],
        }
        .with_richer(eddy);
        assert_eq!(
            pair.name(),
            "amplifier_bandwidth+eddy_frequency_dependence(2 paths)"
        );
        assert_eq!(pair.without(eddy), Candidate::single(amp));
        let values = [
            60.0, 0.7, 400.0, 0.0, 900.0, 0.7, 0.0, 3.0, 100.0, 0.5, 2.0, 1000.0,
        ];
        assert_eq!(parameters(&pair, &n, &REFIT_RANGE).len(), values.len());
        let (e, _) = model_parameters(&pair, &values);
        assert_eq!(e.amplifier, Some((900.0, 0.7, 0.0)));
        assert_eq!(e.second_eddy_path, Some((2.0, 1000.0)));
        // Only effects with a richer form have a second term.
        assert!(second_term_parameters(amp, &n).is_empty());
        for e in RICHER_FORM {
            assert_eq!(
                second_term_parameters(e, &n).len(),
                second_term_parameter_count(e)
            );
            assert!(!second_term_starts(e, &effect_starts(e, &n)[0]).is_empty());
        }
    }

    #[test]
    fn a_two_mode_load_hangs_its_second_mass_on_the_first() {
        let n = Nominal::from_params(&actuator_params::paper_defaults());
        let load = EffectName::MechanicalLoad;
        let c = Candidate::single(load).with_richer(load);
        assert_eq!(c.name(), "mechanical_load(2 modes)");
        assert_eq!(second_term_label(load), "second_mode");
        let specs = parameters(&c, &n, &REFIT_RANGE);
        assert_eq!(specs.len(), COMMON_PARAMETER_COUNT + 3 + 3);
        // The second mode's ranges are the first's (mass relative to the first load mass).
        assert_eq!(specs[7..], specs[4..7]);
        let (_, m) = model_parameters(
            &c,
            &[60.0, 0.7, 400.0, 0.0, 0.3, 600.0, 0.1, 0.5, 2400.0, 0.08],
        );
        assert_eq!(m.load, Some((0.3, 600.0, 0.1)));
        assert_eq!(m.second_load, Some((0.5, 2400.0, 0.08)));
        // Its starts: two masses at 2, 4 and 8 times the first coupling.
        let starts = second_term_starts(load, &[0.3, 600.0, 0.1]);
        assert_eq!(starts.len(), 6);
        assert!(starts
            .iter()
            .all(|s| s.len() == 3 && s[1] >= 1200.0 && s[1] <= 4800.0));
        // One-mode candidates keep no second mass.
        let (_, one) = model_parameters(
            &Candidate::single(load),
            &[60.0, 0.7, 400.0, 0.0, 0.3, 600.0, 0.1],
        );
        assert_eq!(one.second_load, None);
    }

    #[test]
    fn no_start_sits_at_a_physical_limit() {
        // A start at a limit is a fit that may stay pinned there, which disqualifies the
        // candidate (the reversible term's grid once began at the saturation field's floor).
        let mut n = Nominal::from_params(&actuator_params::paper_defaults());
        n.slowest_period_s = 1.0 / 20.0;
        for e in EffectName::LIBRARY {
            let specs = effect_parameters(e, &n);
            for start in effect_starts(e, &n) {
                for (spec, &v) in specs.iter().zip(&start) {
                    assert!(
                        !spec.pinned(spec.coordinate(v)),
                        "{}: start {} = {v} is at a physical limit [{}, {}]",
                        e.name(),
                        spec.name,
                        spec.lo,
                        spec.hi
                    );
                }
            }
        }
    }

    #[test]
    fn thermal_time_constant_floor_follows_the_slowest_excitation() {
        let mut n = Nominal::from_params(&actuator_params::paper_defaults());
        let floor = |n: &Nominal| {
            effect_parameters(EffectName::ThermalDrift, n)
                .iter()
                .find(|p| p.name == "time_constant_s")
                .map(|p| (p.lo, p.edge))
        };
        // Before data are seen: 0.5 s; with a 20 Hz slowest sine, two of its periods.
        assert_eq!(floor(&n), Some((0.5, Edge::Low)));
        n.slowest_period_s = 1.0 / 20.0;
        assert_eq!(floor(&n), Some((0.1, Edge::Low)));
        // Every start lies inside the range.
        for s in effect_starts(EffectName::ThermalDrift, &n) {
            assert!(s[0] >= 0.1 && s[0] <= 1000.0);
        }
    }
}
mod fit {
    use maglab_model::candidates::{self, Candidate};
    use maglab_model::effects::EffectName;
    use maglab_model::fit::*;
    use maglab_model::model::Nominal;

    #[test]
    fn switching_an_effect_off_drops_every_term_of_it_and_keeps_the_rest_aligned() {
        let n = Nominal::from_params(&actuator_params::paper_defaults());
        let (eddy, amp) = (
            EffectName::EddyFrequencyDependence,
            EffectName::AmplifierBandwidth,
        );
        let candidate = Candidate {
            effects: vec![eddy, amp],
        }
        .with_richer(eddy);
        let specs = candidates::parameters(&candidate, &n, &candidates::REFIT_RANGE);
        // Common, eddy (3), amplifier (3), eddy's second path (2).
        let values = vec![
            60.0, 0.7, 400.0, 0.1, 3.0, 100.0, 0.5, 900.0, 0.8, 2e-4, 2.0, 1000.0,
        ];
        assert_eq!(specs.len(), values.len());
        let f = Fitted {
            candidate,
            specs,
            values,
            training_rms_m: 1e-7,
            evaluations: 9,
        };
        let amp_only = f.without(eddy);
        assert_eq!(amp_only.candidate, Candidate::single(amp));
        assert_eq!(
            amp_only.values,
            vec![60.0, 0.7, 400.0, 0.1, 900.0, 0.8, 2e-4]
        );
        let richer_eddy = f.without(amp);
        assert_eq!(
            richer_eddy.candidate.name(),
            "eddy_frequency_dependence(2 paths)"
        );
        assert_eq!(
            richer_eddy.values,
            vec![60.0, 0.7, 400.0, 0.1, 3.0, 100.0, 0.5, 2.0, 1000.0]
        );
        // Knocking out the last listing drops the second path only.
        let one_path = f.knocked_out(2);
        assert_eq!(
            one_path.candidate.name(),
            "eddy_frequency_dependence+amplifier_bandwidth"
        );
        assert_eq!(one_path.values.len(), 10);
        assert_eq!(
            f.report_names().last().map(String::as_str),
            Some("eddy_frequency_dependence.second_path.corner_hz")
        );
        assert!(f.pinned().is_empty());
    }
}
mod model {
    use magctl::preisach::PreisachMeasure;
    use maglab_dataset::{CurrentBetweenSamples, StartState};
    use maglab_model::fit::ModelSetup;
    use maglab_model::model::*;
    use std::f64::consts::PI;

    /// The nominal constants and the Preisach measure of the paper's parameters.
    fn paper_model() -> (Nominal, PreisachMeasure) {
        let params = actuator_params::paper_defaults();
        let core = magctl::params::ActuatorParameters::from_file(&params, "defaults").unwrap();
        (Nominal::from_params(&params), core.preisach.measure())
    }

    /// The electric stage without effects on `currents` (linear between samples), from the
    /// switched-on demagnetized state.
    fn nominal_electro(
        nominal: &Nominal,
        measure: &PreisachMeasure,
        currents: &[f64],
        step_s: f64,
        substeps: usize,
    ) -> ElectroRun {
        let setup = ModelSetup {
            nominal,
            measure,
            step_s,
            interpolation: CurrentBetweenSamples::Linear,
            substeps,
            single_run: false,
        };
        let drive = ElectroDrive {
            currents_a: currents,
            start: &ModelStart::State(StartState::SwitchOnDemagnetized),
            previous: None,
        };
        run_electro(
            &setup,
            &Electro::nominal(nominal.eddy_resistance_ohm),
            drive,
        )
    }

    /// The `exp`/`ln` form of the reversible term against the textbook `powf` form, over the
    /// candidate's ranges of shape and saturation field and fields from 0 to 10 H_s.
    #[test]
    fn reversible_term_matches_the_powf_form() {
        let (chi, hs) = (0.3, 20_000.0);
        let mut worst = 0.0f64;
        for p in [0.5, 1.0, 2.0, 3.7, 8.0] {
            for k in 0..=400 {
                let h = (k as f64 - 200.0) / 20.0 * hs;
                let q: f64 = 1.0 + (h / hs).abs().powf(p);
                let term = chi * h * q.powf(-1.0 / p);
                let slope = chi * q.powf(-1.0 / p - 1.0);
                let (t, s) = reversible(Some((chi, hs, p)), h);
                worst = worst
                    .max((t - term).abs() / (chi * hs))
                    .max((s - slope).abs() / chi);
            }
        }
        assert!(worst < 1e-13, "largest relative difference {worst:.2e}");
        assert_eq!(reversible(Some((chi, hs, 2.0)), 0.0), (0.0, chi));
        assert_eq!(reversible(None, 1e4), (0.0, 0.0));
    }

    /// The largest absolute difference between two runs.
    fn max_difference(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    }

    #[test]
    fn second_order_step_tracks_a_ramp_and_settles() {
        // A critically damped 2nd-order low-pass driven by a ramp lags it by 2ζ/ω in steady state.
        let (omega, zeta, delta) = (2.0 * PI * 500.0, 1.0, 1e-5);
        let lp = second_order(omega, zeta, delta);
        let mut x = [0.0, 0.0];
        let mut c = 0.0;
        for _ in 0..20_000 {
            x = lp.step(x, c, c + delta);
            c += delta;
        }
        assert!((c - x[0] - 2.0 * zeta / omega).abs() < 1e-9, "{}", c - x[0]);
        // c accumulates 20 000 rounding errors, so the slope is only good to ~1e-9.
        assert!((x[1] - 1.0).abs() < 1e-8, "{}", x[1]);
    }

    #[test]
    fn linear_mechanics_as_a_matrix_equal_the_rk4_loop() {
        // ΔE with zero coefficients takes the RK4 loop with the same stiffness; without ΔE the
        // same substep runs as its matrix. Both must agree to rounding, with and without the
        // load mode and the thermal input.
        let (nominal, measure) = paper_model();
        let step_s = 1e-4;
        let currents: Vec<f64> = (0..2000)
            .map(|k| 0.3 + 0.25 * (2.0 * PI * 150.0 * k as f64 * step_s).sin())
            .collect();
        let run = nominal_electro(&nominal, &measure, &currents, step_s, 2);
        for (load, second_load, thermal) in [
            (None, None, None),
            (Some((0.4, 900.0, 0.2)), None, None),
            (Some((0.4, 900.0, 0.2)), Some((0.5, 2500.0, 0.1)), None),
            (None, None, Some((0.3, 0.2, 0.01, 0.02))),
        ] {
            let mut mech = Mech::nominal(0.6, nominal.resonance_hz);
            mech.load = load;
            mech.second_load = second_load;
            mech.thermal = thermal;
            let matrix = run_mech(&nominal, &mech, &run, currents.len(), step_s, (0.0, 0.0));
            mech.delta_e = Some((0.0, 0.0, 0.0, 0.0));
            let looped = run_mech(&nominal, &mech, &run, currents.len(), step_s, (0.0, 0.0));
            let scale = looped.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let worst = max_difference(&matrix, &looped);
            assert!(
                worst <= 1e-12 * scale,
                "{load:?} {thermal:?}: {worst:e} of {scale:e}"
            );
        }
    }

    #[test]
    fn parameter_sets_integrated_side_by_side_are_each_the_track_alone_bit_for_bit() {
        // Fifteen sets on one run: five each of the rod alone, with a load, with a second mode;
        // four of each five with ΔE (of strengths that need different `sub`s, so that groups of
        // one to four form), the fifth linear; every other one heated. Each must be exactly the
        // track `track_mech` gives alone.
        let (nominal, measure) = paper_model();
        let step_s = 1e-4;
        let currents: Vec<f64> = (0..1500)
            .map(|k| 0.4 + 0.3 * (2.0 * PI * 120.0 * k as f64 * step_s).sin())
            .collect();
        let run = nominal_electro(&nominal, &measure, &currents, step_s, 2);
        let mut sets = Vec::new();
        for k in 0..15 {
            let mut mech = Mech::nominal(0.5 + 0.02 * k as f64, nominal.resonance_hz);
            if k % 5 != 4 {
                let strength = if k % 5 == 3 {
                    30.0
                } else {
                    0.3 + 0.5 * k as f64
                };
                mech.delta_e = Some((strength, -0.2, 0.1, 0.02 * k as f64));
            }
            if k >= 5 {
                mech.load = Some((0.3, 700.0 + 150.0 * k as f64, 0.2));
            }
            if k >= 10 {
                mech.second_load = Some((0.4, 2000.0, 0.1));
            }
            if k % 2 == 1 {
                mech.thermal = Some((0.3, 0.2, 0.01, 0.02));
            }
            sets.push(mech);
        }
        let theta0: Vec<(f64, f64)> = (0..sets.len()).map(|k| (0.01 * k as f64, 0.0)).collect();
        let together = track_mech_lanes(&nominal, &sets, &run, currents.len(), step_s, &theta0);
        assert_eq!(together.len(), sets.len());
        for ((mech, t0), lane) in sets.iter().zip(&theta0).zip(&together) {
            let alone = track_mech(&nominal, mech, &run, currents.len(), step_s, *t0);
            assert_eq!(lane.pos_m, alone.pos_m, "{mech:?}");
            assert_eq!(lane.rate_m_per_s, alone.rate_m_per_s, "{mech:?}");
        }
    }

    #[test]
    fn a_heated_rod_keeps_a_fraction_of_its_strain_never_a_negative_one() {
        // Thermal drift's gain `1 − g φ` is the fraction of λ_s the warm rod keeps: at a steady
        // `φ = I²` with `g φ = 0.5` the rod settles at half its cold displacement; with
        // `g φ = 2` it has none left, and the strain must settle at zero, not at minus the cold
        // one (the expansion `e` set to zero so that only the gain acts).
        let (nominal, measure) = paper_model();
        let step_s = 1e-4;
        let current_a = 0.5;
        let currents = vec![current_a; 3000];
        let run = nominal_electro(&nominal, &measure, &currents, step_s, 1);
        let settled = |thermal: Option<(f64, f64, f64, f64)>| {
            let mut mech = Mech::nominal(0.6, nominal.resonance_hz);
            mech.thermal = thermal;
            let y = run_mech(&nominal, &mech, &run, currents.len(), step_s, (0.0, 0.0));
            *y.last().expect("samples")
        };
        let cold = settled(None);
        assert!(cold > 1e-6, "the rod strains at {current_a} A: {cold:e}");
        let i2 = current_a * current_a;
        let half = settled(Some((0.005, 0.005, 0.5 / i2, 0.0)));
        assert!(
            (half / cold - 0.5).abs() < 1e-6,
            "half the gain left: {half:e} of {cold:e}"
        );
        let none_left = settled(Some((0.005, 0.005, 2.0 / i2, 0.0)));
        assert!(
            none_left.abs() < 1e-6 * cold,
            "no gain left: {none_left:e} (cold {cold:e})"
        );
    }

    #[test]
    fn a_second_load_mass_gives_the_chains_frequency_response() {
        // Rod, first and second load mass in a chain, the sensor on the first: driven by a
        // sinusoidal u = k_u M², the steady-state motion of the first load mass must match
        // the chain's transfer function Y2/U, solved from the three equations of motion (per
        // unit rod mass, module docs) at s = jω: below, between and above the load's modes.
        use nalgebra::{Complex, Matrix3, Vector3};
        let (nominal, measure) = paper_model();
        let (step_s, substeps, n) = (1e-4, 10usize, 3000usize);
        let template = nominal_electro(&nominal, &measure, &[0.3; 4], step_s, 1);
        let (xi, f0) = (0.3, nominal.resonance_hz);
        let (r2, f2, z2) = (0.4, 900.0, 0.1);
        let (r3, f3, z3) = (0.5, 2200.0, 0.08);
        let mut mech = Mech::nominal(xi, f0);
        mech.load = Some((r2, f2, z2));
        mech.second_load = Some((r3, f3, z3));
        let ms = nominal.saturation_a_per_m;
        for f_hz in [312.5, 1250.0, 3333.3333333333335] {
            let w = 2.0 * PI * f_hz;
            let dt = step_s / substeps as f64;
            // u / (k_u M_s²) = 0.3 + 0.1 sin(ω t).
            let run = ElectroRun {
                substeps,
                m_a_per_m: (0..=n * substeps)
                    .map(|j| ms * (0.3 + 0.1 * (w * j as f64 * dt).sin()).sqrt())
                    .collect(),
                current_sq_a2: vec![0.0; n * substeps],
                end_memory: template.end_memory.clone(),
            };
            let y = run_mech(&nominal, &mech, &run, n, step_s, (0.0, 0.0));
            // Amplitude and phase of the last 1000 samples (whole periods), least squares.
            let tail = n - 1000..n;
            let (mut ss, mut sc, mut cc, mut ys, mut yc, mut sum) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            let mean = tail.clone().map(|k| y[k]).sum::<f64>() / 1000.0;
            for k in tail {
                let (sn, cs) = (w * k as f64 * step_s).sin_cos();
                let v = y[k] - mean;
                ss += sn * sn;
                sc += sn * cs;
                cc += cs * cs;
                ys += v * sn;
                yc += v * cs;
                sum += v;
            }
            assert!(sum.abs() < 1e-9);
            let det = ss * cc - sc * sc;
            let (b_sin, b_cos) = ((ys * cc - yc * sc) / det, (yc * ss - ys * sc) / det);
            let measured =
                Complex::new(b_sin, b_cos) / (0.1 * nominal.displacement_per_m2_m * ms * ms);
            // Y = A⁻¹ B U with s = jω.
            let s_ = Complex::new(0.0, w);
            let mode = |f: f64, z: f64| {
                let wm = 2.0 * PI * f;
                (wm * wm, 2.0 * z * wm)
            };
            let (w0, d0) = mode(f0, xi);
            let (k2, c2) = mode(f2, z2);
            let (k3, c3) = mode(f3, z3);
            let e2 = s_ * c2 + k2;
            let e3 = s_ * c3 + k3;
            let zero = Complex::new(0.0, 0.0);
            let a = Matrix3::new(
                s_ * s_ + s_ * d0 + w0 + e2 * r2,
                -e2 * r2,
                zero,
                -e2,
                s_ * s_ + e2 + e3 * r3,
                -e3 * r3,
                zero,
                -e3,
                s_ * s_ + e3,
            );
            let b = Vector3::new(Complex::new(w0, 0.0), zero, zero);
            let expected = a.lu().solve(&b).unwrap()[1];
            // The response to sin(ωt) is |H| sin(ωt + ∠H) = Re(H) sin + Im(H) cos. Measured
            // on this drive: 0.01 %, 0.05 % and 0.4 % off (u is linear between substeps).
            let error = (measured - expected).norm() / expected.norm();
            assert!(
                error < 0.01,
                "{f_hz} Hz: measured {measured} expected {expected} ({:.2} %)",
                100.0 * error
            );
        }
    }

    /// `Z(jω)` of the Foster form [`eddy_paths`] returns.
    fn impedance(z_hf: f64, paths: &[Option<(f64, f64)>; 2], f_hz: f64) -> f64 {
        let w = 2.0 * PI * f_hz;
        let (mut re, mut im) = (z_hf, 0.0);
        for (tau, dz) in paths.iter().flatten() {
            let d = 1.0 + (w * tau).powi(2);
            re += dz / d;
            im -= dz * w * tau / d;
        }
        (re * re + im * im).sqrt()
    }

    #[test]
    fn two_eddy_paths_step_the_resistance_at_each_corner_in_either_order() {
        // R = 1/Z steps up 3x at 10 Hz and 2x at 10 kHz: Z_dc, Z_dc/3 between the corners
        // (a decade and a half from each: within 5 %), Z_dc/6 above both.
        let z_dc = 1.0e-3;
        for (first, second) in [((3.0, 10.0), (2.0, 1.0e4)), ((2.0, 1.0e4), (3.0, 10.0))] {
            let (z_hf, paths) = eddy_paths(z_dc, Some(first), Some(second));
            assert!((z_hf - z_dc / 6.0).abs() < 1e-15);
            assert!((impedance(z_hf, &paths, 0.0) - z_dc).abs() < 1e-15);
            let mid = impedance(z_hf, &paths, 316.0);
            assert!(
                (mid * 3.0 / z_dc - 1.0).abs() < 0.05,
                "{}",
                mid * 3.0 / z_dc
            );
            let top = impedance(z_hf, &paths, 1.0e7);
            assert!((top * 6.0 / z_dc - 1.0).abs() < 0.01);
        }
        // One path: Z_hf = Z_dc / ratio; none: Z_dc.
        let (z_hf, paths) = eddy_paths(z_dc, Some((4.0, 50.0)), None);
        assert!((z_hf - z_dc / 4.0).abs() < 1e-15 && paths[1].is_none());
        assert_eq!(eddy_paths(z_dc, None, None), (z_dc, [None, None]));
    }

    /// The electromagnetic stage of `e` on a 220 Hz sine of 0.3 ± 0.25 A (1500 samples at
    /// 10 kHz, two substeps, the current linear between samples) from `start`.
    fn on_a_sine(
        nominal: &Nominal,
        measure: &PreisachMeasure,
        start: StartState,
        e: &Electro,
    ) -> ElectroRun {
        let step_s = 1e-4;
        let currents: Vec<f64> = (0..1500)
            .map(|k| 0.3 + 0.25 * (2.0 * PI * 220.0 * k as f64 * step_s).sin())
            .collect();
        let setup = ModelSetup {
            nominal,
            measure,
            step_s,
            interpolation: CurrentBetweenSamples::Linear,
            substeps: 2,
            single_run: false,
        };
        let start = ModelStart::State(start);
        let drive = ElectroDrive {
            currents_a: &currents,
            start: &start,
            previous: None,
        };
        run_electro(&setup, e, drive)
    }

    #[test]
    fn a_second_eddy_path_that_steps_nothing_is_the_one_path_model() {
        // Its share of Z is zero, so the two-path step (the general κ) must reproduce the
        // one-path step to rounding.
        let (nominal, measure) = paper_model();
        let run = |e: &Electro| {
            on_a_sine(&nominal, &measure, StartState::SwitchOnDemagnetized, e).m_a_per_m
        };
        let mut one = Electro::nominal(nominal.eddy_resistance_ohm);
        one.eddy_path = Some((3.0, 150.0));
        let mut two = one;
        two.second_eddy_path = Some((1.0, 2000.0));
        let (a, b) = (run(&one), run(&two));
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = max_difference(&a, &b);
        assert!(worst <= 1e-6 * scale, "{worst:e} of {scale:e}");
        // And the second path does act when it steps R.
        two.second_eddy_path = Some((2.0, 300.0));
        let c = run(&two);
        let moved = max_difference(&a, &c);
        assert!(moved > 1e-3 * scale, "{moved:e} of {scale:e}");
    }

    #[test]
    fn a_current_loop_around_a_coil_without_inductance_is_the_second_order_low_pass() {
        // At τ_L = 0 the loop is T = ωn²/(s² + 2ζωn s + ωn²) in its own realization (output
        // a₀ x₁): the same as the sensor's low-pass realization (state [y, y']) on a ramp and a
        // step, to rounding.
        let (omega, zeta, delta) = (2.0 * PI * 600.0, 0.8, 1e-5);
        let l = CurrentLoop::new(600.0, 0.8, 0.0, 1.0e4, delta);
        let lp = second_order(omega, zeta, delta);
        let (mut x, mut y) = (l.rest(0.2), [0.2, 0.0]);
        let mut worst = 0.0f64;
        for k in 0..4000 {
            let (c0, c1) = if k < 2000 {
                (0.2 + k as f64 * 1e-4, 0.2 + (k + 1) as f64 * 1e-4)
            } else {
                (1.0, 1.0)
            };
            x = l.advance(x, c0, c1);
            y = lp.step(y, c0, c1);
            worst = worst.max((l.output(x) - y[0]).abs());
        }
        assert!(worst < 1e-12, "{worst:e}");
        assert_eq!(l.implicit_impedance(), 0.0);
    }

    #[test]
    fn a_current_loop_whose_coil_time_constant_vanishes_leaves_no_emf() {
        // τ_L → 0 takes the run with the loop's EMF term to the run without it.
        let (nominal, measure) = paper_model();
        let run = |e: &Electro| on_a_sine(&nominal, &measure, StartState::NegativeSaturation, e);
        let mut low_pass = Electro::nominal(nominal.eddy_resistance_ohm);
        low_pass.amplifier = Some((600.0, 0.8, 0.0));
        let mut current_loop = low_pass;
        current_loop.amplifier = Some((600.0, 0.8, 1e-12));
        let (a, b) = (run(&low_pass), run(&current_loop));
        let scale = a.m_a_per_m.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = max_difference(&a.m_a_per_m, &b.m_a_per_m);
        // The EMF term is 1e-12/c0 of w': the core's f32 solve rounds what it moves to its
        // own step (6e-8 relative) and carries that over the substeps.
        assert!(worst <= 1e-5 * scale, "{worst:e} of {scale:e}");
        // The mean square current the loop leaves agrees to about 1e-8 of the current's square.
        let i2_scale = a.current_sq_a2.iter().fold(0.0f64, |m, v| m.max(*v));
        let worst_i2 = max_difference(&a.current_sq_a2, &b.current_sq_a2);
        assert!(worst_i2 <= 1e-7 * i2_scale, "{worst_i2:e} of {i2_scale:e}");
        // A coil of 0.5 ms (κ ≈ 49 on the paper's rod) does act.
        current_loop.amplifier = Some((600.0, 0.8, 5e-4));
        let moved = max_difference(&a.m_a_per_m, &run(&current_loop).m_a_per_m);
        assert!(moved > 1e-2 * scale, "{moved:e} of {scale:e}");
    }

    #[test]
    fn a_current_loop_passes_dc_and_rejects_a_steady_emf() {
        // T(0) = 1: at rest the output is the input, and under a constant flux rate the EMF
        // current 1 − T leaves decays to zero (the integrator takes the EMF over).
        let (c0, delta) = (1.0e4, 1e-5);
        let l = CurrentLoop::new(800.0, 2.0, 5e-4, c0, delta);
        let rest = l.rest(0.7);
        assert!((l.output(rest) - 0.7).abs() < 1e-12);
        assert!((l.output(l.advance(rest, 0.7, 0.7)) - 0.7).abs() < 1e-12);
        let w_rate = 3.0e3;
        let mut x = [0.0; 2];
        let first = l.emf_current(x, w_rate);
        // At the first substep almost the whole EMF current flows: (τ_L/c0)(1 − g) w'.
        assert!((first - l.implicit_impedance() * w_rate).abs() < 1e-12);
        assert!(first > 0.0);
        for _ in 0..200_000 {
            x = l.advance(x, w_rate, w_rate);
        }
        let settled = l.emf_current(x, w_rate);
        assert!(settled.abs() < 1e-6 * first, "{settled:e} of {first:e}");
    }

    #[test]
    fn hermite_is_exact_for_cubics() {
        let f = |t: f64| 1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t;
        let df = |t: f64| 2.0 - 6.0 * t + 1.5 * t * t;
        let d = 0.1;
        let v: Vec<f64> = (0..10).map(|k| f(k as f64 * d)).collect();
        let r: Vec<f64> = (0..10).map(|k| df(k as f64 * d)).collect();
        for t in [0.03, 0.44, 0.77] {
            assert!((hermite(&v, &r, d, t) - f(t)).abs() < 1e-12);
        }
    }
}
mod nuisance {
    use maglab_dataset::data::Measurement;
    use maglab_dataset::{CurrentBetweenSamples, StartState};
    use maglab_model::experiments::experiment_data;
    use maglab_model::fit::ModelSetup;
    use maglab_model::model::{Electro, ModelStart, Nominal};
    use maglab_model::nuisance::{lead_in_memory, start_sets};

    fn record(name: &str, current_a: Vec<f64>, step_s: f64) -> Measurement {
        Measurement {
            path: std::path::PathBuf::from(name),
            t_s: (0..current_a.len()).map(|k| k as f64 * step_s).collect(),
            displacement_m: vec![0.0; current_a.len()],
            current_a,
            coil_current_a: None,
            step_s,
        }
    }

    /// A sine that continues a reversal sweep: starting it from the memory the sweep left
    /// (simulated once) gives exactly the magnetization of simulating the chain through the
    /// sweep, and `electro_runs` no longer simulates the sweep for it. Without the lead-in, the
    /// start plan `previous` would start the sine demagnetized.
    #[test]
    fn an_experiment_continuing_a_sweep_starts_from_the_memory_the_sweep_left() {
        let params = actuator_params::paper_defaults();
        let nominal = Nominal::from_params(&params);
        let core = magctl::params::ActuatorParameters::from_file(&params, "defaults").unwrap();
        let measure = core.preisach.measure();
        let step_s = 1e-4;
        let top_a = 1.0;
        // A 1 Hz triangle over the whole range, ending at +0.6 of it on the way down.
        let sweep: Vec<f64> = (0..15_000)
            .map(|k| {
                let phase = (k as f64 * step_s).fract();
                top_a * (1.0 - 4.0 * (phase - 0.5).abs()).clamp(-1.0, 1.0)
            })
            .collect();
        let sine: Vec<f64> = (0..500)
            .map(|k| 0.5 + 0.2 * (2.0 * std::f64::consts::PI * 100.0 * k as f64 * step_s).sin())
            .collect();
        let records = [
            record("00_sweep.csv", sweep, step_s),
            record("01_sine.csv", sine, step_s),
        ];
        let setup = ModelSetup {
            nominal: &nominal,
            measure: &measure,
            step_s,
            interpolation: CurrentBetweenSamples::Linear,
            substeps: 1,
            single_run: false,
        };
        let electro = Electro::nominal(nominal.eddy_resistance_ohm);
        let settles = [0, 0];
        let through_the_sweep = experiment_data(
            &records,
            &settles,
            &[
                (ModelStart::State(StartState::NegativeSaturation), false),
                (ModelStart::State(StartState::Previous), true),
            ],
        );
        let chained = setup.electro_runs(&electro, &through_the_sweep, &[1], &[500]);

        let documented = [Some(StartState::NegativeSaturation), None];
        let memory = lead_in_memory(
            &setup,
            &electro,
            &records[0],
            Some(StartState::NegativeSaturation),
        );
        let lead_ins = [None, Some(memory)];
        let plans = start_sets(&documented, &lead_ins);
        let (_, previous_plan) = plans
            .iter()
            .find(|(plan, _)| *plan == StartState::Previous)
            .expect("the previous plan is tried");
        assert!(matches!(previous_plan[1], (ModelStart::After(_), true)));
        let (_, demagnetized_plan) = plans
            .iter()
            .find(|(plan, _)| *plan == StartState::Demagnetized)
            .expect("the demagnetized plan is tried");
        assert_eq!(
            demagnetized_plan[1],
            (ModelStart::State(StartState::Demagnetized), false)
        );

        let after = experiment_data(&records, &settles, previous_plan);
        let from_lead_in = setup.electro_runs(&electro, &after, &[1], &[500]);
        assert_eq!(from_lead_in[0].m_a_per_m, chained[0].m_a_per_m);
        // And it is not the demagnetized start the plan had before.
        let demagnetized = experiment_data(&records, &settles, demagnetized_plan);
        let cold = setup.electro_runs(&electro, &demagnetized, &[1], &[500]);
        let differ = cold[0]
            .m_a_per_m
            .iter()
            .zip(&chained[0].m_a_per_m)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(differ > 0.01 * nominal.saturation_a_per_m, "{differ}");
    }
}

mod experiments {
    use maglab_dataset::data::Measurement;
    use maglab_model::experiments::describe;
    use std::f64::consts::PI;

    #[test]
    fn amplitude_and_bias_are_those_of_the_settled_sine_not_of_the_opening_transient() {
        // A 0.15 A sine at 20 Hz about 0.5 A, measured on a coil whose amplifier starts at 2 A
        // (where the sweep before it ended) and settles with a 2 ms time constant.
        let (rate_hz, n) = (10_000.0, 5_000);
        let current_a: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / rate_hz;
                0.5 + 0.15 * (2.0 * PI * 20.0 * t).sin() + 1.5 * (-t / 2e-3).exp()
            })
            .collect();
        let m = Measurement {
            path: "00_sine.csv".into(),
            t_s: (0..n).map(|k| k as f64 / rate_hz).collect(),
            displacement_m: vec![0.0; n],
            current_a,
            coil_current_a: None,
            step_s: 1.0 / rate_hz,
        };
        let info = &describe(std::slice::from_ref(&m), rate_hz)[0];
        // Settled after one period (500 samples, 0.05 s = 25 time constants).
        assert_eq!(info.settle_samples, 500);
        assert!((info.amplitude_a - 0.15).abs() < 1e-3, "{info:?}");
        assert!((info.bias_a - 0.5).abs() < 1e-3, "{info:?}");
    }
}

mod coverage {
    use maglab_model::coverage::*;
    use serde_json::json;

    fn sine(bias: f64, amp: f64, cycles: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| bias + amp * (2.0 * std::f64::consts::PI * cycles * k as f64 / n as f64).sin())
            .collect()
    }

    #[test]
    fn turning_points_of_a_sine_and_a_ramp() {
        let (mn, mx) = turning_points(&sine(0.5, 0.2, 2.0, 2000), 0.01);
        assert_eq!((mn.len(), mx.len()), (2, 2), "{mn:?} {mx:?}");
        assert!(mx.iter().all(|m| (m - 0.7).abs() < 1e-6));
        assert!(mn.iter().all(|m| (m - 0.3).abs() < 1e-6), "{mn:?}");
        // Wiggles inside the dead band are no reversal.
        let ramp: Vec<f64> = (0..100)
            .map(|k| k as f64 * 0.01 + 0.001 * (k % 2) as f64)
            .collect();
        let (mn, mx) = turning_points(&ramp, 0.01);
        assert_eq!((mn.len(), mx.len()), (0, 0), "{mn:?} {mx:?}");
    }

    /// A FORC-like sweep: from 0 A up to 1.4 A, down to 1.4 − 0.14 k, back up, ...
    fn forc() -> Vec<f64> {
        let mut forc: Vec<f64> = (0..=140).map(|s| s as f64 * 0.01).collect();
        for k in 1..=10 {
            let steps = (14 * k) as usize;
            forc.extend((1..=steps).map(|s| 1.4 - s as f64 * 0.01));
            forc.extend((1..=steps).rev().map(|s| 1.4 - (s - 1) as f64 * 0.01));
        }
        forc
    }

    #[test]
    fn a_forc_sweep_covers_only_loops_up_to_its_top_and_a_slow_sine_covers_its_own() {
        let forc = forc();
        let small = sine(0.55, 0.15, 20.0, 10_000);
        let top = sine(1.1, 0.3, 20.0, 10_000);
        let dynamic = vec![
            ("small".to_string(), 20.0, &small[..]),
            ("top".to_string(), 20.0, &top[..]),
        ];
        let cell = cell_of_currents([&forc[..], &small[..], &top[..]]).unwrap();
        assert!((cell - 1.4 / GRID_LEVELS as f64).abs() < 1e-9);
        let u = uncovered_loops(&MeasuredLoops::of_records(&[&forc], cell), &dynamic);
        assert_eq!(u.len(), 1, "{u:?}");
        assert_eq!(u[0].file, "small");
        assert!((u[0].lo_a - 0.4).abs() < 1e-3 && (u[0].hi_a - 0.7).abs() < 1e-3);
        let slow = sine(0.55, 0.15, 1.0, 10_000);
        let both = MeasuredLoops::of_records(&[&forc, &slow], cell);
        assert!(uncovered_loops(&both, &dynamic).is_empty());
        // A loop within one cell needs nothing.
        assert!(MeasuredLoops::of_records(&[], cell).covers(0.5, 0.5 + 0.9 * cell));
    }

    #[test]
    fn the_provenance_entry_reads_back_and_a_broken_one_names_its_field() {
        let measured = MeasuredLoops::of_records(&[&forc()], 0.056);
        // A slow sine's periods reverse at the same currents: kept once each.
        let slow = sine(0.55, 0.15, 5.0, 10_000);
        let once = MeasuredLoops::of_records(&[&slow], 0.056);
        assert_eq!(
            (once.minima_a.len(), once.maxima_a.len()),
            (1, 1),
            "{once:?}"
        );
        let mut provenance = actuator_params::Provenance {
            source: String::new(),
            details: Default::default(),
        };
        assert!(MeasuredLoops::from_provenance(&provenance).is_none());
        provenance
            .details
            .insert(MeasuredLoops::PROVENANCE_KEY.into(), measured.to_json());
        let back = MeasuredLoops::from_provenance(&provenance)
            .unwrap()
            .unwrap();
        assert_eq!(back, measured);
        provenance.details.insert(
            MeasuredLoops::PROVENANCE_KEY.into(),
            json!({"minima_a": [0.1, "x"], "maxima_a": [], "cell_a": 0.05}),
        );
        let e = MeasuredLoops::from_provenance(&provenance)
            .unwrap()
            .unwrap_err();
        assert!(
            e.contains("provenance.quasi_static_reversals.minima_a"),
            "{e}"
        );
        assert!(e.contains("\"x\""), "{e}");
    }
}

mod drift {
    use maglab_model::drift::*;

    /// A triangle sweep between ±2 A, `periods` periods at 1 Hz, sampled at 1 kHz, and a
    /// hysteretic displacement: a play (backlash) operator of half-width 0.3 A on the current,
    /// through a static nonlinearity, times `gain(t)`.
    fn sweep(periods: usize, gain: impl Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = periods * 1000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let i: Vec<f64> = t
            .iter()
            .map(|&t| {
                let p = t.fract();
                // Starts at -2 A, up to +2 A at half a period, back down.
                if p < 0.5 {
                    -2.0 + 8.0 * p
                } else {
                    6.0 - 8.0 * p
                }
            })
            .collect();
        let mut play: f64 = -1.7;
        let y: Vec<f64> = t
            .iter()
            .zip(&i)
            .map(|(&t, &i)| {
                play = play.max(i - 0.3).min(i + 0.3);
                gain(t) * 30e-6 * (play / 1.7).powi(2).min(1.0)
            })
            .collect();
        (t, i, y)
    }

    #[test]
    fn visits_count_only_after_the_other_extreme() {
        let (t, i, y) = sweep(3, |_| 1.0);
        let [top, bottom] = extreme_visits(&t, &i, &y);
        assert_eq!(top.visits.len(), 3);
        // The start at -2 A comes before any visit to +2 A: not counted.
        assert_eq!(bottom.visits.len(), 2);
        assert!(top.spread_m() < 1e-12 && bottom.spread_m() < 1e-12);
    }

    #[test]
    fn a_rate_independent_record_gets_no_warning() {
        let (t, i, y) = sweep(5, |_| 1.0);
        assert_eq!(drift_warning("forc.csv", &t, &i, &y), None);
        // Noise below the limit neither.
        let noisy: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(k, y)| y + 0.1e-6 * ((k * 7919 % 1000) as f64 / 500.0 - 1.0))
            .collect();
        assert_eq!(drift_warning("forc.csv", &t, &i, &noisy), None);
    }

    #[test]
    fn a_slow_gain_change_is_named_with_its_figures() {
        // The gain falls by 10 % over 5 s (a rod warming up).
        let (t, i, y) = sweep(5, |t| 1.0 - 0.02 * t);
        let w = drift_warning("forc.csv", &t, &i, &y).expect("a warning");
        assert!(w.starts_with("forc.csv: at 2.000 A"), "{w}");
        assert!(w.contains("5 visits"), "{w}");
        // 30 µm × 0.02/s × 4 s between the first and the last visit = 2.4 µm, 8 % of 30 µm.
        assert!(w.contains("(5 visits; 8.0 %"), "{w}");
    }

    #[test]
    fn degenerate_records_are_no_warning() {
        assert_eq!(drift_warning("x.csv", &[], &[], &[]), None);
        let t = [0.0, 1.0, 2.0];
        assert_eq!(
            drift_warning("x.csv", &t, &[1.0; 3], &[2.0, 3.0, 4.0]),
            None
        );
        assert_eq!(
            drift_warning("x.csv", &t, &[0.0, 1.0, 0.0], &[5.0; 3]),
            None
        );
    }
}
mod coil_current {
    use maglab_dataset::data::Measurement;
    use maglab_model::coil_current::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const RATE_HZ: f64 = 10_000.0;

    /// A held command and what a monitor reads of it through a first-order lag `tau_s` (exact
    /// for a held input, read on the command's trigger), with white noise `noise_a`.
    fn record(tau_s: f64, noise_a: f64, seed: u64) -> Measurement {
        let n = 5_000;
        let h = 1.0 / RATE_HZ;
        let command: Vec<f64> = (0..n)
            .map(|k| 0.8 + 0.4 * (2.0 * std::f64::consts::PI * 150.0 * k as f64 * h).sin())
            .collect();
        let a = if tau_s > 0.0 { (-h / tau_s).exp() } else { 0.0 };
        let normal = Normal::new(0.0, noise_a).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut y = command[0];
        let measured: Vec<f64> = command
            .iter()
            .map(|&c| {
                let reading = y + normal.sample(&mut rng);
                y = a * y + (1.0 - a) * c;
                reading
            })
            .collect();
        Measurement {
            path: "sine.csv".into(),
            t_s: (0..n).map(|k| k as f64 * h).collect(),
            current_a: command,
            displacement_m: vec![0.0; n],
            coil_current_a: Some(measured),
            step_s: h,
        }
    }

    #[test]
    fn an_amplifier_that_follows_the_command_is_ruled_out_and_a_lag_is_named_and_measured() {
        // Follows the command: the likelihood ratio stays below the 0.1 % quantile on every one
        // of 20 noise draws (the false-alarm rate is 0.1 %: 20 draws clear it with 98 %).
        for seed in 0..20 {
            let j = judge(&[record(0.0, 1e-3, seed)]).unwrap();
            assert!(!j.amplifier_named, "seed {seed}: {}", j.reason);
            assert!(
                j.likelihood_ratio <= CHI2_1_QUANTILE,
                "{}",
                j.likelihood_ratio
            );
            assert!((j.noise_a - 1e-3).abs() < 1e-4, "{}", j.noise_a);
        }
        // A 200 µs lag (800 Hz): named, and measured.
        let j = judge(&[record(200e-6, 1e-3, 1)]).unwrap();
        assert!(j.amplifier_named, "{}", j.reason);
        assert!(
            (j.lag_time_constant_s / 200e-6 - 1.0).abs() < 0.05,
            "{}",
            j.lag_time_constant_s
        );
        // Without the channel there is nothing to judge.
        let mut plain = record(0.0, 1e-3, 1);
        plain.coil_current_a = None;
        assert!(judge(&[plain]).is_none());
    }

    #[test]
    fn a_tiny_lag_is_significant_but_immaterial() {
        // 50 µs at 150 Hz: what the skew does not take up of it departs by about 60 µA RMS, far
        // above a monitor noise of 10 µA but below 0.2 % of the range.
        let j = judge(&[record(50e-6, 1e-5, 3)]).unwrap();
        assert!(j.likelihood_ratio > CHI2_1_QUANTILE, "{}", j.reason);
        assert!(!j.amplifier_named, "{}", j.reason);
    }

    #[test]
    fn the_interval_means_of_a_sampled_sine_are_kept_to_fourth_order() {
        let h = 1.0 / RATE_HZ;
        let w = 2.0 * std::f64::consts::PI * 400.0;
        let c: Vec<f64> = (0..200).map(|k| (w * k as f64 * h).sin()).collect();
        let q = interval_means_preserved(&c);
        // The exact mean of sin over [t_k, t_k+1].
        let exact =
            |k: usize| ((w * k as f64 * h).cos() - (w * (k + 1) as f64 * h).cos()) / (w * h);
        let worst = |x: &[f64]| {
            (5..190)
                .map(|k| (0.5 * (x[k] + x[k + 1]) - exact(k)).abs())
                .fold(0.0f64, f64::max)
        };
        // Linear interpolation of the raw samples misses by h² ω² / 12 ≈ 0.5 %; the corrected
        // ones by O(h⁴).
        assert!(worst(&c) > 4e-3, "{}", worst(&c));
        assert!(worst(&q) < 1e-4, "{}", worst(&q));
        // Quasi-static records take the coil current at the sample instants, dynamic ones its
        // interval means, both with the monitor's noise taken out: through a 1 ms lag, measured
        // with 100 µA of noise, the quasi-static current follows the noise-free coil current
        // within a fifth of the noise.
        let m = record(1e-3, 1e-4, 1);
        let j = judge(std::slice::from_ref(&m)).unwrap();
        assert!(j.amplifier_named, "{}", j.reason);
        let taken = with_measured_current(&[m.clone(), m.clone()], &[true, false], &j).unwrap();
        let measured = m.coil_current_a.as_ref().unwrap();
        assert_eq!(
            taken[0].current_a,
            coil_current_at_samples(&m.current_a, measured, m.step_s, &j)
        );
        assert_eq!(
            taken[1].current_a,
            coil_current_input(&m.current_a, measured, m.step_s, &j)
        );
        // Of the monitor's 100 µA (×1.17 by the interval means' correction) less than a fifth
        // is left in a dynamic record's current, whether the amplifier is named or ruled out.
        for (tau_s, named) in [(0.0, false), (1e-3, true)] {
            let follows = record(tau_s, 1e-4, 2);
            let j0 = judge(std::slice::from_ref(&follows)).unwrap();
            assert_eq!(j0.amplifier_named, named, "{}", j0.reason);
            let reference =
                interval_means_preserved(&record(tau_s, 0.0, 2).coil_current_a.unwrap());
            let rms_off = |x: &[f64]| {
                let n = x.len() - 200;
                (x.iter()
                    .zip(&reference)
                    .skip(100)
                    .take(n)
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>()
                    / n as f64)
                    .sqrt()
            };
            let follows_measured = follows.coil_current_a.as_ref().unwrap();
            let raw = rms_off(&interval_means_preserved(follows_measured));
            let left = rms_off(&coil_current_input(
                &follows.current_a,
                follows_measured,
                follows.step_s,
                &j0,
            ));
            assert!(raw > 1e-4, "the raw reading is off by {raw} A");
            assert!(
                left < 0.2e-4,
                "lag {tau_s} s: the dynamic input is off by {left} A"
            );
        }
        let clean = record(1e-3, 0.0, 1).coil_current_a.unwrap();
        // The largest difference once the lag's start-up (100 samples) has passed.
        let worst_after_start = |current_a: &[f64]| {
            current_a
                .iter()
                .zip(&clean)
                .skip(100)
                .map(|(d, c)| (d - c).abs())
                .fold(0.0f64, f64::max)
        };
        let rms_after_start = |current_a: &[f64]| {
            let off: Vec<f64> = current_a
                .iter()
                .zip(&clean)
                .skip(100)
                .map(|(d, c)| d - c)
                .collect();
            (off.iter().map(|e| e * e).sum::<f64>() / off.len() as f64).sqrt()
        };
        let left = rms_after_start(&taken[0].current_a);
        assert!(left < 0.2e-4, "quasi-static vs coil current: {left} A RMS");
        // The command through the fitted lag alone, which a first-order amplifier is.
        let worst = worst_after_start(&delivered_current(&m.current_a, m.step_s, &j));
        assert!(worst < 1e-5, "delivered vs coil current: {worst} A");
        let bare = worst_after_start(&m.current_a);
        assert!(bare > 0.1, "the command itself is off by {bare} A");
    }
}

mod priors {
    use actuator_params::{Datasheet, Toleranced};
    use maglab_model::candidates::{effect_parameters, library_parameters, Edge};
    use maglab_model::effects::EffectName;
    use maglab_model::model::Nominal;
    use maglab_model::priors::{minus_3db_ratio, TERFENOL_DENSITY_KG_M3};

    fn nominal_with(datasheet: Datasheet) -> Nominal {
        let mut p = actuator_params::paper_defaults();
        p.datasheet = Some(datasheet);
        Nominal::from_params(&p)
    }

    fn t(value: f64, plus_minus: f64) -> Option<Toleranced> {
        Some(Toleranced { value, plus_minus })
    }

    #[test]
    fn the_minus_3db_ratio_of_a_second_order_low_pass() {
        // ζ = 1/√2 (Butterworth): the −3 dB frequency is the natural frequency.
        assert!((minus_3db_ratio(std::f64::consts::FRAC_1_SQRT_2) - 1.0).abs() < 1e-12);
        // Against |H(j g ωn)|² = 1/2 evaluated directly.
        for zeta in [0.3, 0.5, 1.0, 3.0] {
            let g = minus_3db_ratio(zeta);
            let mag2 = 1.0 / ((1.0 - g * g).powi(2) + (2.0 * zeta * g).powi(2));
            assert!((mag2 - 0.5).abs() < 1e-12, "zeta {zeta}: {mag2}");
        }
    }

    #[test]
    fn a_datasheet_bounds_the_parameters_it_fixes_and_no_other() {
        let n = nominal_with(Datasheet {
            sensor_bandwidth_hz: t(1500.0, 150.0),
            sensor_delay_s: t(5e-5, 8e-5),
            load_mass_kg: t(0.01, 0.002),
            ..Datasheet::default()
        });
        let sensor = effect_parameters(EffectName::SensorDynamics, &n);
        let library = library_parameters(EffectName::SensorDynamics, &n);
        let (natural, damping, delay) = (&sensor[0], &sensor[1], &sensor[2]);
        // The natural frequencies some damping ratio of the range maps into 1350-1650 Hz.
        assert!((natural.lo - 1350.0 / minus_3db_ratio(library[1].lo)).abs() < 1e-9);
        assert!((natural.hi - 1650.0 / minus_3db_ratio(library[1].hi)).abs() < 1e-9);
        assert_eq!(natural.edge, Edge::Both);
        assert_eq!(
            damping, &library[1],
            "the damping ratio has no datasheet value"
        );
        // The delay's band cut at 0, linear (a log range cannot start at 0).
        assert_eq!((delay.lo, delay.log), (0.0, false));
        assert!((delay.hi - 1.3e-4).abs() < 1e-15);
        // The load's mass over a third of the rod's.
        let p = actuator_params::paper_defaults();
        let rod = TERFENOL_DENSITY_KG_M3 * p.actuator.rod_area_m2 * p.actuator.rod_length_m / 3.0;
        let load = effect_parameters(EffectName::MechanicalLoad, &n);
        assert!(
            (load[0].lo - 0.008 / rod).abs() < 1e-12 && (load[0].hi - 0.012 / rod).abs() < 1e-12
        );
        // Untouched: the amplifier (no value given) and every other effect.
        assert_eq!(
            effect_parameters(EffectName::AmplifierBandwidth, &n),
            library_parameters(EffectName::AmplifierBandwidth, &n)
        );
        // The reports list each value and what it bounds; R and L bound nothing.
        let n2 = nominal_with(Datasheet {
            coil_resistance_ohm: t(5.8, 0.3),
            amplifier_bandwidth_hz: t(2000.0, 200.0),
            ..Datasheet::default()
        });
        let uses = n2.priors.uses(&|e| library_parameters(e, &n2));
        assert_eq!(uses.len(), 2);
        assert_eq!(
            uses[0].acts_on.as_ref().map(|(p, _)| p.as_str()),
            Ok("amplifier_bandwidth.natural_hz")
        );
        assert!(uses[1].acts_on.is_err(), "{}", uses[1].describe());
        // The amplifier is an instrument fitted with the rod unless the coil current is measured.
        assert_eq!(
            n2.priors.instruments(false),
            [EffectName::AmplifierBandwidth]
        );
        assert!(n2.priors.instruments(true).is_empty());
    }

    #[test]
    fn starts_lie_at_the_datasheet_values_inside_the_bands() {
        let n = nominal_with(Datasheet {
            sensor_bandwidth_hz: t(1500.0, 150.0),
            ..Datasheet::default()
        });
        let specs = effect_parameters(EffectName::SensorDynamics, &n);
        let start = n.priors.start(EffectName::SensorDynamics, &specs);
        assert_eq!(start[0], 1500.0);
        assert!((start[1] - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-15);
        assert_eq!(
            start[2], 0.0,
            "a delay without a datasheet value starts at 0"
        );
        for (v, s) in start.iter().zip(&specs) {
            assert!((s.lo..=s.hi).contains(v));
        }
    }
}
