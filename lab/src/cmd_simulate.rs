//! `maglab simulate`: runs the core's dynamic model (paper eqs (4)-(5)) — or the static model (6)
//! — on the host for a given current and writes the trajectories and plots.
//!
//! Inputs (one of):
//! * `--freq 1,50,100,200,400` sines with DC bias (`--bias-a`, `--amplitude-a`), one run per
//!   frequency, each from the same demagnetized state at equilibrium under the bias, for
//!   `--periods` periods; the last period is the steady-state loop.
//! * `--current-csv FILE` with the columns `t_s` and `current_a` (others, such as a measurement
//!   file's `displacement_m`, are ignored): the current is held from each sample to the next
//!   (what a DAC does) and sampled at the control rate.
//! * `--van-der-pol` a Van der Pol-shaped current `bias + amplitude · x(t) / max|x|`
//!   (`--vdp-mu`, `--vdp-frequency-hz`), the oscillator of the trajectory generator.
//!
//! Outputs in `--out` (default `out/simulate`): one CSV per run with
//! `t_s,current_a,h_a_per_m,m_a_per_m,displacement_m`, row `k` the state at `t_k = k / rate`
//! before the current of row `k` acts (the measurement files' convention, so a simulated file
//! lines up with a measured one sample for sample), `loops.png/.svg` (displacement against
//! current over the last period, one curve per frequency: the paper's Figure 6 shape) and
//! `traces.png/.svg` (current and displacement against time).

use crate::params_io::{self, LoadedParams};
use crate::plot::{Figure, Panel, Series, PALETTE};
use anyhow::{bail, Context, Result};
use clap::Args as ClapArgs;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use magctl::model::{DynamicModel, ModelOutput, ModelState, StaticModel};
use magctl::params::Trajectory;
use magctl::preisach::PreisachMeasure;
use magctl::trajectory::VanDerPol;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Arguments of `maglab simulate`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Sine frequencies in Hz, comma separated (e.g. 1,50,100,200,400).
    #[arg(long, value_delimiter = ',', conflicts_with_all = ["current_csv", "van_der_pol"])]
    pub freq: Vec<f64>,
    /// A current file with header `t_s,current_a` instead of sines.
    #[arg(long, value_name = "FILE", conflicts_with = "van_der_pol")]
    pub current_csv: Option<PathBuf>,
    /// A Van der Pol-shaped current instead of sines.
    #[arg(long)]
    pub van_der_pol: bool,
    /// DC bias of the sine / Van der Pol current, A.
    #[arg(long, default_value_t = 0.5)]
    pub bias_a: f64,
    /// Amplitude of the sine / Van der Pol current, A.
    #[arg(long, default_value_t = 0.45)]
    pub amplitude_a: f64,
    /// Periods per sine run (the last one is plotted as the loop).
    #[arg(long, default_value_t = 4.0)]
    pub periods: f64,
    /// Duration of a Van der Pol run, s.
    #[arg(long, default_value_t = 0.1)]
    pub duration_s: f64,
    /// μ of the Van der Pol current.
    #[arg(long, default_value_t = 2.0)]
    pub vdp_mu: f64,
    /// Frequency scale of the Van der Pol current, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub vdp_frequency_hz: f64,
    /// Model to run.
    #[arg(long, value_enum, default_value_t = ModelKind::Dynamic)]
    pub model: ModelKind,
    /// Step rate, Hz (default: the parameter file's `control.sample_rate_hz`).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Parameter file (default: the parameters baked into this build).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out/simulate")]
    pub out: PathBuf,
}

/// Which model `simulate` steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelKind {
    /// The rate-dependent model (4)-(5).
    Dynamic,
    /// The static model (6).
    Static,
}

/// One simulated run.
struct Run {
    label: String,
    /// Samples `(t_s, current_a, output)`.
    samples: Vec<(f64, f64, ModelOutput)>,
    /// Index of the first sample of the plotted loop.
    loop_start: usize,
}

/// Runs `maglab simulate`.
pub fn run(args: &Args) -> Result<()> {
    let loaded = params_io::load(args.params.as_deref())?;
    let rate_hz = args
        .rate_hz
        .unwrap_or(loaded.params.control.sample_rate_hz as f64);
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        bail!("--rate-hz must be a positive number, got {rate_hz}");
    }
    for (name, v) in [
        ("--bias-a", args.bias_a),
        ("--amplitude-a", args.amplitude_a),
        ("--periods", args.periods),
    ] {
        if !v.is_finite() {
            bail!("{name} must be finite, got {v}");
        }
    }
    let measure = loaded.measure();
    let inputs = inputs(args, &loaded, rate_hz)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let total_steps: usize = inputs.iter().map(|i| i.currents_a.len()).sum();
    let progress = LazyProgress::new(total_steps as u64);
    let mut runs = Vec::new();
    for input in &inputs {
        let run = simulate(&measure, &loaded, args.model, rate_hz, input, &progress);
        let path = args.out.join(format!("{}.csv", input.file_stem));
        write_csv(&path, &run)?;
        println!("wrote {} ({} samples)", path.display(), run.samples.len());
        runs.push(run);
    }
    progress.finish();
    print_summary(&runs, &loaded);
    let written = plot(&runs, &loaded, &args.out)?;
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// A current sequence at the control rate.
struct Input {
    label: String,
    file_stem: String,
    currents_a: Vec<f64>,
    loop_start: usize,
}

fn inputs(args: &Args, loaded: &LoadedParams, rate_hz: f64) -> Result<Vec<Input>> {
    if let Some(path) = &args.current_csv {
        let currents_a = read_current_csv(path, rate_hz)?;
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("current")
            .to_string();
        return Ok(vec![Input {
            label: stem.clone(),
            file_stem: format!("simulate_{stem}"),
            currents_a,
            loop_start: 0,
        }]);
    }
    if args.van_der_pol {
        let trajectory = Trajectory {
            van_der_pol_mu: args.vdp_mu as f32,
            frequency_scale_hz: args.vdp_frequency_hz as f32,
            displacement_min_m: -1.0,
            displacement_max_m: 1.0,
        };
        let mut control = loaded.params.control;
        control.sample_rate_hz = rate_hz as f32;
        let vdp = VanDerPol::new(&trajectory, &control).map_err(|e| {
            anyhow::anyhow!("invalid Van der Pol settings (--vdp-mu, --vdp-frequency-hz): {e:?}")
        })?;
        let mut state = vdp.start_state();
        let n = (args.duration_s * rate_hz).round() as usize;
        if n == 0 {
            bail!(
                "--duration-s {} gives no samples at {rate_hz} Hz",
                args.duration_s
            );
        }
        let peak = vdp.peak_x() as f64;
        let currents_a = (0..n)
            .map(|_| {
                vdp.step(&mut state);
                args.bias_a + args.amplitude_a * state.x as f64 / peak
            })
            .collect();
        return Ok(vec![Input {
            label: format!(
                "Van der Pol μ={} f={} Hz",
                args.vdp_mu, args.vdp_frequency_hz
            ),
            file_stem: "simulate_van_der_pol".into(),
            currents_a,
            loop_start: 0,
        }]);
    }
    let freqs = if args.freq.is_empty() {
        vec![1.0, 50.0, 100.0, 200.0, 400.0]
    } else {
        args.freq.clone()
    };
    let mut out = Vec::new();
    for f in freqs {
        if !(f.is_finite() && f > 0.0 && f < rate_hz / 2.0) {
            bail!(
                "--freq {f}: must be positive and below the Nyquist frequency {} Hz",
                rate_hz / 2.0
            );
        }
        if args.periods < 1.0 {
            bail!("--periods must be >= 1, got {}", args.periods);
        }
        let n = (args.periods / f * rate_hz).round() as usize;
        let per_period = (rate_hz / f).round() as usize;
        let currents_a = (0..n)
            .map(|k| {
                args.bias_a
                    + args.amplitude_a * (2.0 * std::f64::consts::PI * f * k as f64 / rate_hz).sin()
            })
            .collect();
        out.push(Input {
            label: format!("{f} Hz"),
            file_stem: format!("simulate_{f}hz"),
            currents_a,
            loop_start: n.saturating_sub(per_period + 1),
        });
    }
    Ok(out)
}

fn simulate(
    measure: &PreisachMeasure,
    loaded: &LoadedParams,
    kind: ModelKind,
    rate_hz: f64,
    input: &Input,
    progress: &LazyProgress,
) -> Run {
    let actuator = &loaded.params.actuator;
    let dynamic = DynamicModel::new(measure, actuator, (1.0 / rate_hz) as f32);
    let statics = StaticModel::new(measure, actuator);
    let first = input.currents_a.first().copied().unwrap_or(0.0) as f32;
    let mut state: ModelState = dynamic.equilibrium(measure.demagnetized_at(0.0), first);
    let mut samples = Vec::with_capacity(input.currents_a.len());
    for (k, &i) in input.currents_a.iter().enumerate() {
        // Row k is the state at t_k, before the current of row k acts (the measurement files'
        // convention, so a simulated file lines up with a measured one sample for sample).
        let before = ModelOutput {
            current_a: i as f32,
            h_a_per_m: state.h_a_per_m,
            m_a_per_m: state.m_a_per_m,
            displacement_m: state.displacement_m,
            velocity_m_per_s: state.velocity_m_per_s,
            current_rejected: false,
        };
        samples.push((k as f64 / rate_hz, i, before));
        match kind {
            ModelKind::Dynamic => dynamic.step(&mut state, i as f32),
            ModelKind::Static => statics.step(&mut state, i as f32),
        };
        if k % 4096 == 4095 {
            progress.advance(4096);
        }
    }
    progress.advance((input.currents_a.len() % 4096) as u64);
    Run {
        label: input.label.clone(),
        samples,
        loop_start: input.loop_start,
    }
}

/// Reads the columns `t_s` and `current_a` (by name; other columns, such as a measurement file's
/// `displacement_m`, are ignored) and resamples the current at `rate_hz` by holding each sample
/// until the next.
fn read_current_csv(path: &Path, rate_hz: f64) -> Result<Vec<f64>> {
    let name = path.display();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("{name}: cannot open"))?;
    let headers = reader
        .headers()
        .with_context(|| format!("{name}: line 1: cannot read the header"))?
        .clone();
    let expected = ["t_s", "current_a"];
    let columns: Vec<usize> = expected
        .iter()
        .map(|want| headers.iter().position(|h| h == *want))
        .collect::<Option<Vec<_>>>()
        .with_context(|| {
            format!(
                "{name}: line 1: the header needs the columns `t_s` and `current_a`, found `{}`",
                headers.iter().collect::<Vec<_>>().join(",")
            )
        })?;
    let mut samples: Vec<(f64, f64)> = Vec::new();
    for (row, record) in reader.records().enumerate() {
        let line = row + 2;
        let record = record.with_context(|| format!("{name}: line {line}: malformed row"))?;
        if record.len() != headers.len() {
            bail!(
                "{name}: line {line}: expected {} columns, found {}",
                headers.len(),
                record.len()
            );
        }
        let mut values = [0.0f64; 2];
        for (k, value) in values.iter_mut().enumerate() {
            let col = columns[k];
            let field = record.get(col).unwrap_or("");
            *value = field.parse::<f64>().with_context(|| {
                format!(
                    "{name}: line {line}, column {} (`{}`): `{field}` is not a number",
                    col + 1,
                    expected[k]
                )
            })?;
            if !value.is_finite() {
                bail!(
                    "{name}: line {line}, column {} (`{}`): value {field} is not finite",
                    col + 1,
                    expected[k]
                );
            }
        }
        if let Some(&(t_prev, _)) = samples.last() {
            if values[0] <= t_prev {
                bail!("{name}: line {line}, column 1 (`t_s`): time {} does not increase (previous {t_prev})", values[0]);
            }
        }
        samples.push((values[0], values[1]));
    }
    if samples.len() < 2 {
        bail!("{name}: needs at least 2 samples, found {}", samples.len());
    }
    let t0 = samples[0].0;
    let t_end = samples[samples.len() - 1].0;
    let n = ((t_end - t0) * rate_hz).floor() as usize + 1;
    let mut out = Vec::with_capacity(n);
    let mut j = 0;
    for k in 0..n {
        let t = t0 + k as f64 / rate_hz;
        while j + 1 < samples.len() && samples[j + 1].0 <= t {
            j += 1;
        }
        out.push(samples[j].1);
    }
    Ok(out)
}

fn write_csv(path: &Path, run: &Run) -> Result<()> {
    let mut text = String::from("t_s,current_a,h_a_per_m,m_a_per_m,displacement_m\n");
    for (t, i, o) in &run.samples {
        let _ = writeln!(
            text,
            "{t:.7},{i:.6},{:.3},{:.3},{:.6e}",
            o.h_a_per_m, o.m_a_per_m, o.displacement_m
        );
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

fn print_summary(runs: &[Run], loaded: &LoadedParams) {
    let stroke = loaded.params.actuator.stroke_m() as f64;
    println!(
        "{:<28} {:>12} {:>12} {:>12} {:>14}",
        "run", "y_min_um", "y_max_um", "p-p_um", "loop_area_uA·m"
    );
    for run in runs {
        let cycle = &run.samples[run.loop_start..];
        let (lo, hi) = cycle
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), (_, _, o)| {
                (
                    lo.min(o.displacement_m as f64),
                    hi.max(o.displacement_m as f64),
                )
            });
        // Shoelace area of the (current, displacement) loop over the last period.
        let area: f64 = cycle
            .windows(2)
            .map(|w| {
                (w[1].1 - w[0].1)
                    * 0.5
                    * (w[1].2.displacement_m as f64 + w[0].2.displacement_m as f64)
            })
            .sum::<f64>()
            .abs();
        println!(
            "{:<28} {:>12.3} {:>12.3} {:>12.3} {:>14.4}",
            run.label,
            lo * 1e6,
            hi * 1e6,
            (hi - lo) * 1e6,
            area * 1e6
        );
    }
    println!(
        "(stroke l_m λ_s = {:.2} um; parameters: {})",
        stroke * 1e6,
        loaded.origin
    );
}

fn plot(runs: &[Run], loaded: &LoadedParams, out: &Path) -> Result<Vec<PathBuf>> {
    let mut loops = Panel::new(
        &format!(
            "Displacement vs current, last period ({})",
            loaded.provenance
        ),
        "current I [A]",
        "displacement y [µm]",
    );
    let mut current = Panel::new("Current", "time [ms]", "current I [A]");
    let mut displacement = Panel::new("Displacement", "time [ms]", "displacement y [µm]");
    for (k, run) in runs.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let cycle = &run.samples[run.loop_start..];
        loops.series.push(Series {
            label: Some(run.label.clone()),
            points: cycle
                .iter()
                .map(|(_, i, o)| (*i, o.displacement_m as f64 * 1e6))
                .collect(),
            color,
            width: 2,
        });
        // Time traces over the whole run, time relative to the run's start.
        current.series.push(Series {
            label: Some(run.label.clone()),
            points: run.samples.iter().map(|(t, i, _)| (t * 1e3, *i)).collect(),
            color,
            width: 1,
        });
        displacement.series.push(Series {
            label: Some(run.label.clone()),
            points: run
                .samples
                .iter()
                .map(|(t, _, o)| (t * 1e3, o.displacement_m as f64 * 1e6))
                .collect(),
            color,
            width: 1,
        });
    }
    let mut written = Figure {
        panels: vec![loops],
        rows: 1,
        cols: 1,
        size_px: (1000, 750),
    }
    .write(&out.join("loops"))?;
    written.extend(
        Figure {
            panels: vec![current, displacement],
            rows: 2,
            cols: 1,
            size_px: (1200, 900),
        }
        .write(&out.join("traces"))?,
    );
    Ok(written)
}

/// A progress bar that only appears once a run has taken more than a second.
struct LazyProgress {
    bar: ProgressBar,
    started: Instant,
    shown: std::cell::Cell<bool>,
}

impl LazyProgress {
    fn new(total: u64) -> Self {
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} steps ({per_sec}, eta {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        LazyProgress {
            bar,
            started: Instant::now(),
            shown: std::cell::Cell::new(false),
        }
    }

    fn advance(&self, steps: u64) {
        self.bar.inc(steps);
        if !self.shown.get() && self.started.elapsed() > Duration::from_secs(1) {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            self.shown.set(true);
        }
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `text` as file `name` in a temporary folder (removed when the folder is dropped).
    fn write(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        (dir, path)
    }

    fn error_of(name: &str, text: &str) -> String {
        format!(
            "{:#}",
            read_current_csv(&write(name, text).1, 1000.0).unwrap_err()
        )
    }

    #[test]
    fn current_file_is_held_between_samples_at_the_control_rate() {
        let (_dir, path) = write("ok.csv", "t_s,current_a\n0,0.5\n0.0025,0.7\n0.004,0.1\n");
        // 1 kHz: samples at 0, 1, 2, 3, 4 ms hold the last value at or before each time.
        let currents = read_current_csv(&path, 1000.0).unwrap();
        assert_eq!(currents, vec![0.5, 0.5, 0.5, 0.7, 0.1]);
    }

    #[test]
    fn bad_current_files_name_file_line_and_column() {
        let e = error_of("header.csv", "t_s,current\n0,0.5\n");
        assert!(
            e.contains("header.csv: line 1: the header needs the columns `t_s` and `current_a`"),
            "{e}"
        );
        let e = error_of("number.csv", "t_s,current_a\n0,0.5\n0.001,abc\n");
        assert!(
            e.contains("number.csv: line 3, column 2 (`current_a`): `abc` is not a number"),
            "{e}"
        );
        let e = error_of("nan.csv", "t_s,current_a\n0,0.5\n0.001,NaN\n");
        assert!(
            e.contains("nan.csv: line 3, column 2 (`current_a`): value NaN is not finite"),
            "{e}"
        );
        let e = error_of("time.csv", "t_s,current_a\n0,0.5\n0,0.6\n");
        assert!(
            e.contains("time.csv: line 3, column 1 (`t_s`): time 0 does not increase"),
            "{e}"
        );
        let e = error_of("short.csv", "t_s,current_a\n0,0.5\n");
        assert!(
            e.contains("short.csv: needs at least 2 samples, found 1"),
            "{e}"
        );
        let e = error_of("columns.csv", "t_s,current_a\n0,0.5\n0.001,0.5,7\n");
        assert!(e.contains("columns.csv: line 3"), "{e}");
        // A measurement file (with its displacement column) is a current file too.
        let (_dir, path) = write(
            "measurement.csv",
            "t_s,current_a,displacement_m\n0,0.5,1e-6\n0.001,0.7,2e-6\n0.002,0.1,3e-6\n",
        );
        assert_eq!(
            read_current_csv(&path, 1000.0).unwrap(),
            vec![0.5, 0.7, 0.1]
        );
    }
}
