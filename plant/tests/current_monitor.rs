//! The bench's coil-current channel (`BenchSettings::coil_current`): what the amplifier's
//! current monitor reads, on the displacement's trigger, with its own noise.

use maglab_dataset::{CurrentBetweenSamples, StartState};
use maglab_plant::bench::{record, sine_experiment};
use maglab_plant::{BenchSettings, CurrentMonitor, Effect, Plant};

fn settings(between: CurrentBetweenSamples, skew: f64, monitor: CurrentMonitor) -> BenchSettings {
    BenchSettings {
        current_between_samples: between,
        channel_skew_samples: skew,
        noise_m: 0.0,
        quantization_m: 0.0,
        coil_current: Some(monitor),
        ..BenchSettings::default()
    }
}

const IDEAL: CurrentMonitor = CurrentMonitor {
    noise_a: 0.0,
    quantization_a: 0.0,
};

fn rms(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64).sqrt()
}

#[test]
fn without_an_amplifier_the_monitor_reads_the_command_as_the_source_makes_it() {
    let params = actuator_params::paper_defaults();
    let e = sine_experiment(0, StartState::Demagnetized, 0.8, 0.3, 100.0, 0.1, 10_000.0);
    let cmd = &e.current_a;
    let n = cmd.len();
    // A held command is a staircase: read on its new step.
    let mut plant = Plant::new(&params, &[], 10_000.0).unwrap();
    let s = settings(CurrentBetweenSamples::Hold, 0.0, IDEAL);
    let held = record(&mut plant, &e, &s, 1).unwrap();
    let i = held.coil_current_a.as_ref().expect("the channel");
    assert_eq!(i.len(), n);
    assert!(rms(i, cmd) < 1e-12, "{}", rms(i, cmd));
    // A linear one read 0.4 samples late: 0.4 of the way to the next sample.
    let mut plant = Plant::new(&params, &[], 10_000.0).unwrap();
    let s = settings(CurrentBetweenSamples::Linear, 0.4, IDEAL);
    let r = record(&mut plant, &e, &s, 1).unwrap();
    let expected: Vec<f64> = (0..n)
        .map(|k| cmd[k] + 0.4 * (cmd[(k + 1).min(n - 1)] - cmd[k]))
        .collect();
    let i = r.coil_current_a.as_ref().unwrap();
    assert!(
        rms(&i[..n - 1], &expected[..n - 1]) < 1e-6,
        "{}",
        rms(i, &expected)
    );
    // The monitor's noise and steps, from a stream of their own: the displacement is the same.
    let mut plant = Plant::new(&params, &[], 10_000.0).unwrap();
    let noisy = settings(
        CurrentBetweenSamples::Hold,
        0.0,
        CurrentMonitor {
            noise_a: 1e-3,
            quantization_a: 1e-3,
        },
    );
    let r2 = record(&mut plant, &e, &noisy, 1).unwrap();
    let i2 = r2.coil_current_a.as_ref().unwrap();
    let noise = rms(i2, cmd);
    assert!((0.8e-3..1.3e-3).contains(&noise), "{noise}");
    assert!(i2
        .iter()
        .all(|v| (v / 1e-3 - (v / 1e-3).round()).abs() < 1e-6));
    assert!(r2.displacement_m == held.displacement_m);
}

#[test]
fn an_amplifier_shows_in_the_monitor_and_without_the_channel_nothing_is_read() {
    let params = actuator_params::paper_defaults();
    let e = sine_experiment(0, StartState::Demagnetized, 0.8, 0.3, 300.0, 0.1, 10_000.0);
    let amp = Effect::parse("amplifier_bandwidth:natural_hz=700").unwrap();
    let mut plant = Plant::new(&params, &[amp], 10_000.0).unwrap();
    let s = settings(CurrentBetweenSamples::Hold, 0.0, IDEAL);
    let r = record(&mut plant, &e, &s, 1).unwrap();
    let i = r.coil_current_a.as_ref().unwrap();
    // A 700 Hz loop lags a 300 Hz command by tens of degrees: a departure of 10 % of the
    // amplitude and more.
    assert!(rms(i, &e.current_a) > 0.03, "{}", rms(i, &e.current_a));
    let mut plant = Plant::new(&params, &[], 10_000.0).unwrap();
    let plain = BenchSettings {
        coil_current: None,
        ..s
    };
    assert!(record(&mut plant, &e, &plain, 1)
        .unwrap()
        .coil_current_a
        .is_none());
}
