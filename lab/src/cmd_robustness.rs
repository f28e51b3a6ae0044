//! `maglab robustness`: the closed loop against plants the model does not describe — the
//! robustness matrix of the feedback (`magctl::inverse::feedback`).
//!
//! Every case runs the controller of the parameter file (`--params`, default the baked one) on the
//! host in lock-step with the bench plant (`maglab-plant`: its own f64 Preisach operator and RK4
//! integrator), twice: feedforward only (`control.feedback.structure = off`) and with the file's
//! feedback. Each tick the plant's sensor output at `t_k` (its own dynamics when a sensor effect is
//! on) plus white noise is quantized to an ADC count of the `sensor` section and handed to
//! `ControlLoop::tick_sensed`, exactly as the firmware's interrupt receives it; the command is
//! held over the period. The plant starts where the controller assumes (negative saturation
//! driven to the first field, the rod on the trajectory).
//!
//! The cases: the nominal plant; each library effect of the plant at a magnitude that leaves a
//! 5–30 % open-loop error; backlash; ±20 % on R_eddy, ξ, f0, λ_s, M_s; the Preisach masses scaled by
//! ±10 %; sensor noise at three levels (on the plant with R_eddy +20 %, so that there is an error
//! to correct). Errors are the plant's true displacement against `ȳ`, RMS and max over
//! `[--settle-s, --duration-s]` (the learning's first cycles excluded), in % of the trajectory's
//! peak-to-peak.
//!
//! Writes `<out>/robustness.csv` (`case,open_loop_rms_pct,closed_loop_rms_pct,
//! closed_loop_max_pct,current_rms_a`), `<out>/robustness.png/.svg`, and prints the table; and
//! the learning transient of every closed-loop run, `<out>/transient.csv`
//! (`case,whole_run_rms_pct,settled_rms_pct,settle_s,settle_cycles`: the RMS over the whole run,
//! the RMS over the scored window, and when the error last exceeded [`SETTLED_PCT`] of the
//! peak-to-peak — in seconds and in trajectory cycles; empty when it never stays below).

use crate::params_io::{self, LoadedParams};
use crate::plot::PALETTE;
use crate::plot_bars::{BarChart, BarSeries};
use actuator_params::ActuatorParams;
use anyhow::{bail, Context, Result};
use clap::Args as ClapArgs;
use magctl::inverse::{ControlLoop, InverseKind, LoopState};
use magctl::params::{ActuatorParameters, Feedback};
use magctl::sensor::SensorScale;
use maglab_dataset::StartState;
use maglab_plant::{Effect, Plant};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `maglab robustness`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The controller's parameter file (default: the parameters baked into this build); the
    /// plants are this file with each case's change.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Control time of each run, s.
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
    /// Errors are scored from this time on (the learning's first cycles excluded), s.
    #[arg(long, default_value_t = 0.5)]
    pub settle_s: f64,
    /// Run only the cases whose name contains one of these (comma separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Scale the feedback's gains (learning, K_p, K_i) by this factor (the stability check at
    /// 2×).
    #[arg(long, default_value_t = 1.0)]
    pub gain_scale: f64,
    /// Feedback structure instead of the file's: off, integral or repetitive.
    #[arg(long)]
    pub structure: Option<String>,
    /// K_p of the PI instead of the file's (before --gain-scale).
    #[arg(long)]
    pub proportional_gain: Option<f32>,
    /// K_i of the PI instead of the file's, 1/s (before --gain-scale).
    #[arg(long)]
    pub integral_gain_per_s: Option<f32>,
    /// Harmonics the learning corrects instead of the file's.
    #[arg(long)]
    pub learning_harmonics: Option<u32>,
    /// Use the static inverse (Figure 8) instead of the dynamic one.
    #[arg(long)]
    pub static_inverse: bool,
    /// Without the stroke-gain estimate (`magctl::inverse::StrokeGainLaw`): the learning alone.
    #[arg(long)]
    pub no_stroke_gain: bool,
    /// Output directory.
    #[arg(long, default_value = "out/robustness")]
    pub out: PathBuf,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only redraw the plot from this robustness.csv (e.g. with rows appended by `cargo xtask
    /// robustness`) into --out.
    #[arg(long, value_name = "CSV")]
    pub plot_only: Option<PathBuf>,
    /// Also write every case's per-tick traces (`<out>/traces/<case>.csv`: t_s, desired,
    /// open- and closed-loop displacement, closed-loop current and flags).
    #[arg(long)]
    pub traces: bool,
}

/// One plant of the matrix.
#[derive(Debug, Clone)]
pub struct Case {
    /// Row name.
    pub name: String,
    /// The plant's parameters.
    pub plant: ActuatorParams,
    /// The plant's effects.
    pub effects: Vec<Effect>,
    /// Sensor noise (standard deviation), m.
    pub noise_m: f64,
    /// The controller's `sensor.sample_delay_s` for this case, when the case documents its
    /// sensor's lag there (else the file's).
    pub controller_sample_delay_s: Option<f64>,
}

/// Default sensor noise of every case, m (a good LVDT/capacitive sensor on a 80 µm range).
pub const BASE_NOISE_M: f64 = 0.02e-6;

/// The matrix's cases for the controller's parameter file `nominal`.
pub fn cases(nominal: &ActuatorParams) -> Result<Vec<Case>> {
    let mut out = Vec::new();
    let case =
        |name: &str, plant: ActuatorParams, effects: &[&str], noise_m: f64| -> Result<Case> {
            Ok(Case {
                name: name.to_string(),
                plant,
                effects: effects
                    .iter()
                    .map(|t| Effect::parse(t).map_err(|e| anyhow::anyhow!("{t}: {e}")))
                    .collect::<Result<_>>()?,
                noise_m,
                controller_sample_delay_s: None,
            })
        };
    // Library effects at magnitudes that leave a 5-30 % open-loop error (checked by the test).
    for (name, effect) in [
        (
            "eddy_frequency_dependence",
            "eddy_frequency_dependence:share=0.6",
        ),
        ("amplifier_bandwidth", "amplifier_bandwidth:natural_hz=900"),
        (
            "reversible_magnetization",
            "reversible_magnetization:susceptibility=3",
        ),
        ("thermal_drift", "thermal_drift:coil_rise_k_per_a2=150"),
        (
            "delta_e_effect",
            "delta_e_effect:magnetization_stiffening=1.5",
        ),
        (
            "mechanical_load",
            "mechanical_load:mass_ratio=1.2,coupling_hz=900",
        ),
        ("backlash", "backlash:width_m=2e-6"),
    ] {
        out.push(case(name, nominal.clone(), &[effect], BASE_NOISE_M)?);
    }
    // A sensor with its own second-order low-pass and conversion delay: the bench sees a 5 %
    // error that is not in the rod at all. Feedback from that sensor can only make the *reading*
    // follow ȳ; the controller is told the sensor's group delay at low frequency (2ζ/ω_n plus the
    // conversion delay plus the file's own), as a user copies it from the sensor's data sheet.
    {
        let (fn_hz, zeta, delay_s) = (1500.0, 0.7, 5e-5);
        let mut c = case(
            "sensor_dynamics (lag in sensor.sample_delay_s)",
            nominal.clone(),
            &[&format!(
                "sensor_dynamics:natural_hz={fn_hz},damping_ratio={zeta},delay_s={delay_s}"
            )],
            BASE_NOISE_M,
        )?;
        c.controller_sample_delay_s = Some(
            nominal.sensor.sample_delay_s
                + delay_s
                + 2.0 * zeta / (2.0 * std::f64::consts::PI * fn_hz),
        );
        out.push(c);
    }
    type Edit = fn(&mut ActuatorParams, f64);
    let edits: [(&str, Edit); 5] = [
        ("R_eddy", |p, s| p.actuator.eddy_resistance_ohm *= s),
        ("xi", |p, s| p.actuator.damping_ratio *= s),
        ("f0", |p, s| p.actuator.resonance_hz *= s),
        ("lambda_s", |p, s| {
            p.actuator.saturation_magnetostriction *= s
        }),
        ("M_s", |p, s| {
            p.actuator.saturation_magnetization_a_per_m *= s
        }),
    ];
    for (name, edit) in edits {
        for scale in [1.2, 0.8] {
            let mut p = nominal.clone();
            edit(&mut p, scale);
            let label = format!("{name} {:+.0}%", 100.0 * (scale - 1.0));
            out.push(case(&label, p, &[], BASE_NOISE_M)?);
        }
    }
    for scale in [1.1, 0.9] {
        let mut p = nominal.clone();
        for w in &mut p.preisach.weights_a_per_m {
            *w *= scale;
        }
        let label = format!("masses {:+.0}%", 100.0 * (scale - 1.0));
        out.push(case(&label, p, &[], BASE_NOISE_M)?);
    }
    for noise in [0.03e-6, 0.1e-6, 0.3e-6] {
        let mut p = nominal.clone();
        p.actuator.eddy_resistance_ohm *= 1.2;
        let label = format!("noise {:.2} um + R_eddy +20%", noise * 1e6);
        out.push(case(&label, p, &[], noise)?);
    }
    Ok(out)
}

/// Error statistics of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunStats {
    /// RMS error, % of the trajectory's peak-to-peak.
    pub rms_pct: f64,
    /// Largest error, % of the peak-to-peak.
    pub max_pct: f64,
    /// RMS coil current command, A.
    pub current_rms_a: f64,
    /// Commands flagged SENSOR_FAULT.
    pub sensor_fault_ticks: usize,
}

/// One run's traces (every tick).
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Desired displacement at the end of each period, m.
    pub desired_m: Vec<f64>,
    /// True displacement at the end of each period, m.
    pub actual_m: Vec<f64>,
    /// Current commands, A.
    pub current_a: Vec<f64>,
    /// Flags.
    pub flags: Vec<u8>,
}

/// Runs the controller `control` (built from `controller`) against `case` for `ticks` ticks.
pub fn run_case(
    controller: &ActuatorParameters,
    control: &ControlLoop<'_>,
    kind: InverseKind,
    case: &Case,
    ticks: usize,
    seed: u64,
) -> Result<Trace> {
    let rate = controller.control.sample_rate_hz as f64;
    let mut plant = Plant::new(&case.plant, &case.effects, rate)
        .map_err(|e| anyhow::anyhow!("{}: {e}", case.name))?;
    let mut state: LoopState<{ magctl::preisach::DEFAULT_CAPACITY }> = control.init(kind);
    // As the firmware starts: the rod demagnetized at 0 A, then the start-up conditioning
    // (`magctl::inverse::Conditioning`) with the sensor read, up to the loop's first current.
    plant
        .start(StartState::SwitchOnDemagnetized, 0.0)
        .map_err(|e| anyhow::anyhow!(e))?;
    let scale = SensorScale::new(&controller.sensor);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, case.noise_m.max(f64::MIN_POSITIVE))
        .map_err(|e| anyhow::anyhow!("noise: {e}"))?;
    // The sensor's documented conversion delay (`sensor.sample_delay_s` of the plant's file).
    let delay_s = case.plant.sensor.sample_delay_s;
    let read = |plant: &Plant, rng: &mut rand::rngs::StdRng| {
        let mut y = plant.sensor_at(plant.time_s() - delay_s);
        if case.noise_m > 0.0 {
            y += noise.sample(rng);
        }
        scale.displacement_m(scale.count_of(y as f32))
    };
    let conditioning = *control.conditioning();
    let mut sequence = control.conditioning_sequence(0.0, &state);
    while !sequence.done() {
        let sample = read(&plant, &mut rng);
        let out = control.condition_sensed(kind, &conditioning, &mut sequence, &mut state, sample);
        let i = out.current_a as f64;
        plant.advance(i, i);
        plant.trim_history(0.01);
    }
    let mut trace = Trace::default();
    for _ in 0..ticks {
        let sample = read(&plant, &mut rng);
        let out = control.tick_sensed(kind, &mut state, sample);
        let i = out.current_a as f64;
        plant.advance(i, i);
        plant.trim_history(0.01);
        trace.desired_m.push(out.desired.displacement_m as f64);
        trace.actual_m.push(plant.displacement_m());
        trace.current_a.push(i);
        trace.flags.push(out.flags.0);
    }
    Ok(trace)
}

impl Trace {
    /// The first tick from which `|y − ȳ|` stays below `pct` % of the whole run's peak-to-peak
    /// (`None` if the last tick is above it).
    pub fn settled_from(&self, pct: f64) -> Option<usize> {
        let (lo, hi) = self
            .desired_m
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &d| (l.min(d), h.max(d)));
        let bound = pct / 100.0 * (hi - lo);
        let n = self.desired_m.len();
        match (0..n)
            .rev()
            .find(|&k| (self.actual_m[k] - self.desired_m[k]).abs() >= bound)
        {
            None => Some(0),
            Some(k) if k + 1 < n => Some(k + 1),
            Some(_) => None,
        }
    }

    /// The learning transient: whole-run RMS and the settling time, with the trajectory's period
    /// `period_ticks` (control ticks per cycle) and the control rate.
    pub fn transient(&self, period_ticks: f64, rate_hz: f64) -> Transient {
        let settled = self.settled_from(SETTLED_PCT);
        Transient {
            whole_run_rms_pct: self.stats(0).rms_pct,
            settle_s: settled.map(|k| k as f64 / rate_hz),
            settle_cycles: settled.map(|k| k as f64 / period_ticks),
        }
    }

    /// Statistics over the ticks from `from`.
    pub fn stats(&self, from: usize) -> RunStats {
        let (mut sq, mut max, mut lo, mut hi, mut isq) = (0.0f64, 0.0f64, f64::MAX, f64::MIN, 0.0);
        let n = self.desired_m.len().saturating_sub(from).max(1);
        for k in from..self.desired_m.len() {
            let (d, a) = (self.desired_m[k], self.actual_m[k]);
            let e = a - d;
            sq += e * e;
            max = max.max(e.abs());
            lo = lo.min(d);
            hi = hi.max(d);
            isq += self.current_a[k] * self.current_a[k];
        }
        let p2p = (hi - lo).max(1e-300);
        RunStats {
            rms_pct: 100.0 * (sq / n as f64).sqrt() / p2p,
            max_pct: 100.0 * max / p2p,
            current_rms_a: (isq / n as f64).sqrt(),
            sensor_fault_ticks: self
                .flags
                .iter()
                .filter(|&&f| f & magctl::inverse::CommandFlags::SENSOR_FAULT != 0)
                .count(),
        }
    }
}

/// The error below which a run counts as settled, % of the trajectory's peak-to-peak.
pub const SETTLED_PCT: f64 = 1.0;

/// The learning transient of a closed-loop run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transient {
    /// RMS error over the whole run (the first cycles included), % of the peak-to-peak.
    pub whole_run_rms_pct: f64,
    /// Time from which the error stays below [`SETTLED_PCT`], s (`None`: it never does).
    pub settle_s: Option<f64>,
    /// The same in cycles of the trajectory.
    pub settle_cycles: Option<f64>,
}

/// One row of the matrix.
#[derive(Debug, Clone)]
pub struct Row {
    /// Case name.
    pub case: String,
    /// Feedforward only.
    pub open_loop: RunStats,
    /// With the feedback.
    pub closed_loop: RunStats,
    /// The closed loop's learning transient (`None` when read back from a CSV).
    pub transient: Option<Transient>,
}

/// The feedback settings of `params` with `structure` and the gains scaled by `gain_scale`.
pub fn feedback_settings(
    params: &ActuatorParameters,
    structure: Option<magctl::params::FeedbackStructure>,
    gain_scale: f32,
) -> Feedback {
    let mut f = params.control.feedback;
    if let Some(s) = structure {
        f.structure = s;
    }
    f.learning_gain *= gain_scale;
    f.proportional_gain *= gain_scale;
    f.integral_gain_per_s *= gain_scale;
    f
}

/// Parses a structure name.
pub fn parse_structure(text: &str) -> Result<magctl::params::FeedbackStructure> {
    Ok(match text {
        "off" => magctl::params::FeedbackStructure::Off,
        "integral" => magctl::params::FeedbackStructure::Integral,
        "repetitive" => magctl::params::FeedbackStructure::Repetitive,
        other => bail!("--structure `{other}`: expected off, integral or repetitive"),
    })
}

/// Runs the matrix (cases in parallel on all cores; rows in case order).
#[allow(clippy::too_many_arguments)]
pub fn matrix(
    loaded: &LoadedParams,
    cases: &[Case],
    feedback: &Feedback,
    kind: InverseKind,
    stroke_gain: bool,
    duration_s: f64,
    settle_s: f64,
    seed: u64,
    traces: Option<&Path>,
) -> Result<Vec<Row>> {
    use rayon::prelude::*;
    let p = &loaded.params;
    let measure = loaded.measure();
    ControlLoop::new(&measure, p)
        .map_err(|e| anyhow::anyhow!("{}: invalid control settings: {e:?}", loaded.origin))?;
    let rate = p.control.sample_rate_hz as f64;
    let ticks = (duration_s * rate).round() as usize;
    let from = (settle_s * rate).round() as usize;
    if from >= ticks {
        bail!("--settle-s {settle_s} must be below --duration-s {duration_s}");
    }
    cases
        .par_iter()
        .map(|case| {
            let mut params = *p;
            if let Some(d) = case.controller_sample_delay_s {
                params.sensor.sample_delay_s = d as f32;
            }
            let loop_for = |f: &Feedback| -> Result<ControlLoop<'_>> {
                let mut with = params;
                with.control.feedback = *f;
                let control = ControlLoop::new(&measure, &with).map_err(|e| {
                    anyhow::anyhow!("{}: invalid control settings: {e:?}", case.name)
                })?;
                Ok(if stroke_gain {
                    control
                } else {
                    control.without_stroke_gain()
                })
            };
            let mut off = *feedback;
            off.structure = magctl::params::FeedbackStructure::Off;
            let o = run_case(&params, &loop_for(&off)?, kind, case, ticks, seed)?;
            let c = run_case(&params, &loop_for(feedback)?, kind, case, ticks, seed)?;
            if let Some(dir) = traces {
                write_trace(dir, &case.name, rate, &o, &c)?;
            }
            let period_ticks = loop_for(feedback)?.trajectory().period_steps() as f64;
            Ok(Row {
                case: case.name.clone(),
                open_loop: o.stats(from),
                closed_loop: c.stats(from),
                transient: Some(c.transient(period_ticks, rate)),
            })
        })
        .collect()
}

/// One case's traces as CSV.
fn write_trace(dir: &Path, name: &str, rate_hz: f64, open: &Trace, closed: &Trace) -> Result<()> {
    let file: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let path = dir.join(format!("{file}.csv"));
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(
        f,
        "t_s,desired_m,open_loop_m,closed_loop_m,closed_loop_current_a,closed_loop_flags"
    )?;
    for k in 0..closed.desired_m.len() {
        writeln!(
            f,
            "{:.6},{:e},{:e},{:e},{:e},{}",
            (k + 1) as f64 / rate_hz,
            closed.desired_m[k],
            open.actual_m[k],
            closed.actual_m[k],
            closed.current_a[k],
            closed.flags[k]
        )?;
    }
    f.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The CSV of the matrix.
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(
        f,
        "case,open_loop_rms_pct,closed_loop_rms_pct,closed_loop_max_pct,current_rms_a"
    )?;
    for r in rows {
        writeln!(
            f,
            "{},{:.4},{:.4},{:.4},{:.4}",
            r.case,
            r.open_loop.rms_pct,
            r.closed_loop.rms_pct,
            r.closed_loop.max_pct,
            r.closed_loop.current_rms_a
        )?;
    }
    f.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Reads a robustness.csv back (for `--plot-only`).
fn read_csv(path: &Path) -> Result<Vec<Row>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let c: Vec<&str> = line.split(',').collect();
        if c.len() != 5 {
            bail!(
                "{}: line {}: expected 5 columns, got {}",
                path.display(),
                n + 1,
                c.len()
            );
        }
        let f = |i: usize| -> Result<f64> {
            c[i].parse().map_err(|_| {
                anyhow::anyhow!(
                    "{}: line {}: `{}` is not a number",
                    path.display(),
                    n + 1,
                    c[i]
                )
            })
        };
        let stats = |rms: f64, max: f64, current: f64| RunStats {
            rms_pct: rms,
            max_pct: max,
            current_rms_a: current,
            sensor_fault_ticks: 0,
        };
        rows.push(Row {
            case: c[0].to_string(),
            open_loop: stats(f(1)?, f64::NAN, f64::NAN),
            closed_loop: stats(f(2)?, f(3)?, f(4)?),
            transient: None,
        });
    }
    Ok(rows)
}

/// The learning transient as CSV (module docs).
pub fn write_transient_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let mut text = String::from("case,whole_run_rms_pct,settled_rms_pct,settle_s,settle_cycles\n");
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for r in rows {
        if let Some(t) = r.transient {
            text += &format!(
                "{},{:.4},{:.4},{},{}\n",
                r.case,
                t.whole_run_rms_pct,
                r.closed_loop.rms_pct,
                opt(t.settle_s),
                opt(t.settle_cycles)
            );
        }
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

/// The learning transient as text: whole run, settled window, time to settle below
/// [`SETTLED_PCT`].
pub fn transient_table(rows: &[Row], settle_window_s: f64) -> String {
    let mut s = format!(
        "learning transient (closed loop): {:<25} {:>13} {:>17} {:>22}\n",
        "case",
        "whole run RMS %",
        format!("from {settle_window_s} s RMS %"),
        format!("below {SETTLED_PCT} % from (s / cycles)")
    );
    for r in rows {
        let Some(t) = r.transient else { continue };
        let settle = match (t.settle_s, t.settle_cycles) {
            (Some(s), Some(c)) => format!("{s:.3} s / {c:.1}"),
            _ => "never".to_string(),
        };
        s += &format!(
            "  {:<56} {:>13.3} {:>17.3} {:>22}\n",
            r.case, t.whole_run_rms_pct, r.closed_loop.rms_pct, settle
        );
    }
    s
}

/// The table as text.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<48} {:>12} {:>12} {:>11} {:>9} {:>10}\n",
        "case", "open RMS %", "closed RMS %", "closed max %", "ratio", "I rms (A)"
    );
    for r in rows {
        s += &format!(
            "{:<48} {:>12.3} {:>12.3} {:>11.3} {:>8.1}x {:>10.3}\n",
            r.case,
            r.open_loop.rms_pct,
            r.closed_loop.rms_pct,
            r.closed_loop.max_pct,
            r.open_loop.rms_pct / r.closed_loop.rms_pct.max(1e-12),
            r.closed_loop.current_rms_a
        );
    }
    s
}

/// The plot: open- vs closed-loop RMS per case, named bars on a log axis in % of the
/// peak-to-peak, with the 1 % goal.
pub fn plot(stem: &Path, rows: &[Row]) -> Result<Vec<PathBuf>> {
    let values = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    BarChart {
        title: "Robustness matrix: tracking RMS error per case".into(),
        value_label: "RMS tracking error, % of the trajectory's peak-to-peak (log scale)".into(),
        unit: "%".into(),
        cases: rows.iter().map(|r| r.case.clone()).collect(),
        series: vec![
            BarSeries {
                label: "feedforward (open loop)".into(),
                color: PALETTE[5],
                values: values(&|r| r.open_loop.rms_pct),
            },
            BarSeries {
                label: "with feedback (closed loop)".into(),
                color: PALETTE[1],
                values: values(&|r| r.closed_loop.rms_pct),
            },
        ],
        reference: Some(("1 % goal".into(), 1.0)),
    }
    .write(stem)
}

/// Runs `maglab robustness`.
pub fn run(args: &Args) -> Result<()> {
    if let Some(csv) = &args.plot_only {
        let rows = read_csv(csv)?;
        crate::plot::register_font()?;
        for p in plot(&args.out.join("robustness"), &rows)? {
            println!("wrote {}", p.display());
        }
        return Ok(());
    }
    let loaded = params_io::load(args.params.as_deref())?;
    if !(args.gain_scale.is_finite() && args.gain_scale >= 0.0) {
        bail!("--gain-scale must be >= 0, got {}", args.gain_scale);
    }
    let structure = args.structure.as_deref().map(parse_structure).transpose()?;
    let mut params = loaded.params;
    if let Some(k) = args.proportional_gain {
        params.control.feedback.proportional_gain = k;
    }
    if let Some(k) = args.integral_gain_per_s {
        params.control.feedback.integral_gain_per_s = k;
    }
    if let Some(n) = args.learning_harmonics {
        params.control.feedback.learning_harmonics = n;
    }
    let feedback = feedback_settings(&params, structure, args.gain_scale as f32);
    if feedback.structure == magctl::params::FeedbackStructure::Off {
        bail!(
            "the feedback is off (control.feedback.structure or --structure): nothing to compare"
        );
    }
    let mut all = cases(&loaded.file)?;
    if !args.only.is_empty() {
        all.retain(|c| args.only.iter().any(|o| c.name.contains(o.as_str())));
        if all.is_empty() {
            bail!("--only {:?} matches no case", args.only);
        }
    }
    let kind = if args.static_inverse {
        InverseKind::Static
    } else {
        InverseKind::Dynamic
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let trace_dir = args.out.join("traces");
    if args.traces {
        std::fs::create_dir_all(&trace_dir)
            .with_context(|| format!("cannot create {}", trace_dir.display()))?;
    }
    let started = std::time::Instant::now();
    let rows = matrix(
        &loaded,
        &all,
        &feedback,
        kind,
        !args.no_stroke_gain,
        args.duration_s,
        args.settle_s,
        args.seed,
        args.traces.then_some(trace_dir.as_path()),
    )?;
    let csv = args.out.join("robustness.csv");
    write_csv(&csv, &rows)?;
    let transient_csv = args.out.join("transient.csv");
    write_transient_csv(&transient_csv, &rows)?;
    crate::plot::register_font()?;
    let pictures = plot(&args.out.join("robustness"), &rows)?;
    println!(
        "robustness matrix: {:?} inverse, feedback {:?} (gains x{}), errors over [{}, {}] s, {:.1} s",
        kind,
        feedback.structure,
        args.gain_scale,
        args.settle_s,
        args.duration_s,
        started.elapsed().as_secs_f64()
    );
    print!("{}", table(&rows));
    print!("{}", transient_table(&rows, args.settle_s));
    let reference = matrix(
        &loaded,
        &[Case {
            name: "nominal plant (no model error; reference, not a row)".into(),
            plant: loaded.file.clone(),
            effects: Vec::new(),
            noise_m: BASE_NOISE_M,
            controller_sample_delay_s: None,
        }],
        &feedback,
        kind,
        !args.no_stroke_gain,
        args.duration_s,
        args.settle_s,
        args.seed,
        None,
    )?;
    print!("{}", table(&reference).lines().nth(1).unwrap_or_default());
    println!();
    println!("wrote {}", csv.display());
    println!("wrote {}", transient_csv.display());
    for p in pictures {
        println!("wrote {}", p.display());
    }
    Ok(())
}
