//! `maglab track`: the inverse controller on the host against the bench plant — the paper's
//! Figures 7 (dynamic inverse) and 8 (static inverse).
//!
//! The controller is `magctl::inverse::ControlLoop`, the code the firmware's timer interrupt runs
//! (the QEMU check proves the firmware's command stream equals the host's bit for bit); the plant
//! is the bench plant (`maglab-plant`: its own f64 Preisach operator and RK4 integrator, no code
//! shared with the controller's model), with `--effect` switched on if asked, started in the
//! state the controller assumes (memory driven from negative saturation to the first field, the
//! rod moving as the trajectory at its first sample). Both inverses track the same Van der Pol
//! trajectory from the parameter file.
//!
//! With `--capture out/qemu/capture.csv` the current commands are not computed on the host but
//! read from a QEMU firmware run (`cargo xtask qemu`), so the figures show the firmware's own
//! output driving the plant.
//!
//! Outputs in `--out` (default `out/track`):
//! * `tracking.csv`: `t_s,y_desired_m,y_dynamic_m,error_dynamic_m,current_dynamic_a,
//!   y_static_m,error_static_m,current_static_a` (one row per control period; `t_s` is the end of
//!   the period, when the plant's displacement is compared with `ȳ`);
//! * `fig7_dynamic.png/.svg`, `fig8_static.png/.svg`: desired vs actual displacement, tracking
//!   error, input current over the first `--plot-s` seconds;
//! * stdout: RMS and max error of each inverse (absolute and in % of the trajectory's
//!   peak-to-peak) and the static/dynamic ratio.

use crate::params_io::{self, LoadedParams};
use crate::plot::{Figure, Panel, Series, PALETTE};
use anyhow::{bail, Context, Result};
use clap::Args as ClapArgs;
use magctl::board::capture_phase::CapturePhase;
use magctl::inverse::{ControlLoop, InverseKind};
use maglab_dataset::StartState;
use maglab_plant::{Effect, Plant};
use std::path::{Path, PathBuf};

/// Arguments of `maglab track`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Control time to run, s.
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
    /// Time span shown in the figures (from the start), s.
    #[arg(long, default_value_t = 0.1)]
    pub plot_s: f64,
    /// An effect of the plant, `name` or `name:key=value,...` (repeatable; see `maglab rig
    /// --list-effects`): the controller then meets a plant its model does not describe.
    #[arg(long = "effect")]
    pub effects: Vec<String>,
    /// Read the current commands of a QEMU run (`out/qemu/capture.csv` from `cargo xtask qemu`)
    /// instead of computing them on the host.
    #[arg(long, value_name = "FILE")]
    pub capture: Option<PathBuf>,
    /// Parameter file (default: the parameters baked into this build).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out/track")]
    pub out: PathBuf,
}

/// One inverse's commands and the plant's answer.
#[derive(Debug, Clone)]
pub struct Run {
    /// Current held over each period, A.
    pub current_a: Vec<f64>,
    /// Desired displacement at the end of each period, m.
    pub desired_m: Vec<f64>,
    /// Plant displacement at the end of each period, m.
    pub actual_m: Vec<f64>,
    /// Error statistics.
    pub stats: TrackingStats,
}

/// Both runs of `maglab track`.
#[derive(Debug, Clone)]
pub struct Tracking {
    /// Control period, s.
    pub period_s: f64,
    /// Dynamic inverse (Figure 7).
    pub dynamic: Run,
    /// Static inverse (Figure 8).
    pub static_: Run,
}

/// Current commands and desired displacements of the dynamic and static phases of a QEMU
/// capture file (header `phase,index,...` as written by `cargo xtask qemu`).
pub fn read_capture(path: &Path) -> Result<[(Vec<f32>, Vec<f64>); 2]> {
    let mut reader = csv::Reader::from_path(path)
        .with_context(|| format!("cannot read the capture file {}", path.display()))?;
    let headers = reader.headers()?.clone();
    let column = |name: &str| {
        headers.iter().position(|h| h == name).with_context(|| {
            format!(
                "{}: no column `{name}` in the header (expected the capture.csv of `cargo xtask qemu`)",
                path.display()
            )
        })
    };
    let (phase, current, desired) = (
        column("phase")?,
        column("current_a")?,
        column("y_desired_m")?,
    );
    let mut out: [(Vec<f32>, Vec<f64>); 2] = Default::default();
    for (k, record) in reader.records().enumerate() {
        let line = k + 2;
        let record = record.with_context(|| format!("{}: line {line}", path.display()))?;
        let field = |i: usize| record.get(i).unwrap_or("");
        let slot = match CapturePhase::from_name(field(phase)) {
            Some(CapturePhase::Dynamic) => 0,
            Some(CapturePhase::Static) => 1,
            // The benchmark's other phases (baselines, merge stress) track nothing.
            Some(_) => continue,
            None => bail!(
                "{}: line {line}: unknown phase `{}` (one of {})",
                path.display(),
                field(phase),
                CapturePhase::ALL.map(CapturePhase::name).join(", ")
            ),
        };
        let number = |i: usize, name: &str| -> Result<f64> {
            let text = field(i);
            let v: f64 = text.trim().parse().map_err(|_| {
                anyhow::anyhow!(
                    "{}: line {line}: column `{name}`: `{text}` is not a number",
                    path.display()
                )
            })?;
            if !v.is_finite() {
                bail!(
                    "{}: line {line}: column `{name}`: {v} is not finite",
                    path.display()
                );
            }
            Ok(v)
        };
        out[slot].0.push(number(current, "current_a")? as f32);
        out[slot].1.push(number(desired, "y_desired_m")?);
    }
    for (name, (currents, _)) in ["dynamic", "static"].iter().zip(&out) {
        if currents.is_empty() {
            bail!("{}: no `{name}` rows", path.display());
        }
    }
    Ok(out)
}

/// Error statistics of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingStats {
    /// RMS of `y - ȳ`, m.
    pub rms_error_m: f64,
    /// Largest `|y - ȳ|`, m.
    pub max_error_m: f64,
    /// Peak-to-peak of the desired trajectory `ȳ`, m.
    pub peak_to_peak_m: f64,
}

impl TrackingStats {
    /// Statistics of `actual` against `desired` (same sample times).
    pub fn of(desired_m: &[f64], actual_m: &[f64]) -> Self {
        let (mut sq, mut max, mut lo, mut hi) = (0.0f64, 0.0f64, f64::MAX, f64::MIN);
        for (&d, &a) in desired_m.iter().zip(actual_m) {
            let e = a - d;
            sq += e * e;
            max = max.max(e.abs());
            lo = lo.min(d);
            hi = hi.max(d);
        }
        TrackingStats {
            rms_error_m: (sq / desired_m.len().max(1) as f64).sqrt(),
            max_error_m: max,
            peak_to_peak_m: (hi - lo).max(0.0),
        }
    }

    /// RMS error relative to the peak-to-peak, %.
    pub fn rms_percent(&self) -> f64 {
        100.0 * self.rms_error_m / self.peak_to_peak_m.max(1e-300)
    }

    /// Largest error relative to the peak-to-peak, %.
    pub fn max_percent(&self) -> f64 {
        100.0 * self.max_error_m / self.peak_to_peak_m.max(1e-300)
    }
}

/// The plant's displacement at the end of every period under `currents_a` (each held over a
/// period), started as the controller assumes.
fn plant_response(
    loaded: &LoadedParams,
    control: &ControlLoop<'_>,
    kind: InverseKind,
    effects: &[Effect],
    currents_a: &[f32],
) -> Result<Vec<f64>> {
    let rate = loaded.params.control.sample_rate_hz as f64;
    let mut plant = Plant::new(&loaded.file, effects, rate).map_err(|e| anyhow::anyhow!(e))?;
    let start: magctl::inverse::LoopState<{ magctl::preisach::DEFAULT_CAPACITY }> =
        control.init(kind);
    let desired = control.trajectory().motion(&start.core.trajectory);
    let c0 = loaded.params.actuator.coil_factor_per_m as f64;
    plant
        .start(
            StartState::NegativeSaturation,
            start.core.memory.h_a_per_m as f64 / c0,
        )
        .map_err(|e| anyhow::anyhow!(e))?;
    plant.set_motion(
        desired.displacement_m as f64,
        desired.velocity_m_per_s as f64,
    );
    Ok(currents_a
        .iter()
        .map(|&i| {
            plant.advance(i as f64, i as f64);
            plant.trim_history(0.01);
            plant.displacement_m()
        })
        .collect())
}

/// Runs both inverses (or replays a capture) against the bench plant.
pub fn track(
    loaded: &LoadedParams,
    duration_s: f64,
    effects: &[Effect],
    capture: Option<&Path>,
) -> Result<Tracking> {
    let params = &loaded.params;
    let measure = loaded.measure();
    let control = ControlLoop::new(&measure, params)
        .map_err(|e| anyhow::anyhow!("{}: invalid control settings: {e:?}", loaded.origin))?;
    let rate = params.control.sample_rate_hz as f64;
    let period_s = 1.0 / rate;
    let captured = match capture {
        Some(path) => Some(read_capture(path)?),
        None => None,
    };
    let ticks = (duration_s * rate).round() as usize;
    if captured.is_none() && ticks == 0 {
        bail!("--duration-s {duration_s} is shorter than one control period ({period_s} s)");
    }
    let run = |kind: InverseKind, slot: usize| -> Result<Run> {
        let (currents, desired): (Vec<f32>, Vec<f64>) = match &captured {
            Some(c) => c[slot].clone(),
            None => {
                let mut state: magctl::inverse::LoopState<{ magctl::preisach::DEFAULT_CAPACITY }> =
                    control.init(kind);
                let outputs: Vec<_> = (0..ticks).map(|_| control.tick(kind, &mut state)).collect();
                (
                    outputs.iter().map(|t| t.current_a).collect(),
                    outputs
                        .iter()
                        .map(|t| t.desired.displacement_m as f64)
                        .collect(),
                )
            }
        };
        let actual = plant_response(loaded, &control, kind, effects, &currents)?;
        Ok(Run {
            stats: TrackingStats::of(&desired, &actual),
            current_a: currents.iter().map(|&i| i as f64).collect(),
            desired_m: desired,
            actual_m: actual,
        })
    };
    Ok(Tracking {
        period_s,
        dynamic: run(InverseKind::Dynamic, 0)?,
        static_: run(InverseKind::Static, 1)?,
    })
}

fn write_csv(path: &Path, t: &Tracking) -> Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("cannot write {}", path.display()))?;
    w.write_record([
        "t_s",
        "y_desired_m",
        "y_dynamic_m",
        "error_dynamic_m",
        "current_dynamic_a",
        "y_static_m",
        "error_static_m",
        "current_static_a",
    ])?;
    let n = t.dynamic.desired_m.len().min(t.static_.desired_m.len());
    for k in 0..n {
        let (d, s) = (&t.dynamic, &t.static_);
        w.write_record([
            format!("{:.6}", (k + 1) as f64 * t.period_s),
            format!("{:e}", d.desired_m[k]),
            format!("{:e}", d.actual_m[k]),
            format!("{:e}", d.actual_m[k] - d.desired_m[k]),
            format!("{:e}", d.current_a[k]),
            format!("{:e}", s.actual_m[k]),
            format!("{:e}", s.actual_m[k] - s.desired_m[k]),
            format!("{:e}", s.current_a[k]),
        ])?;
    }
    w.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The Figure 7/8 layout: displacement (desired and actual), tracking error, current.
fn figure(run: &Run, period_s: f64, plot_s: f64, title: &str) -> Figure {
    let n = ((plot_s / period_s).round() as usize).clamp(1, run.desired_m.len());
    let t = |k: usize| (k + 1) as f64 * period_s * 1e3;
    let series = |label: Option<&str>, ys: Vec<f64>, color: usize, width: u32| Series {
        label: label.map(str::to_string),
        points: ys.into_iter().enumerate().map(|(k, y)| (t(k), y)).collect(),
        color: PALETTE[color],
        width,
    };
    let um = |v: &[f64]| v.iter().take(n).map(|y| y * 1e6).collect::<Vec<_>>();
    let mut displacement = Panel::new(
        &format!("{title}: displacement"),
        "time (ms)",
        "displacement (µm)",
    );
    displacement.series = vec![
        series(Some("desired ȳ"), um(&run.desired_m), 0, 2),
        series(Some("actual y (bench plant)"), um(&run.actual_m), 2, 2),
    ];
    let mut error = Panel::new(
        &format!(
            "tracking error y - ȳ (RMS {:.3} %, max {:.3} % of p2p)",
            run.stats.rms_percent(),
            run.stats.max_percent()
        ),
        "time (ms)",
        "error (µm)",
    );
    let errors: Vec<f64> = run
        .actual_m
        .iter()
        .zip(&run.desired_m)
        .take(n)
        .map(|(a, d)| (a - d) * 1e6)
        .collect();
    error.series = vec![series(None, errors, 1, 2)];
    let mut current = Panel::new("input current", "time (ms)", "current (A)");
    current.series = vec![series(
        None,
        run.current_a.iter().take(n).copied().collect(),
        3,
        2,
    )];
    Figure {
        panels: vec![displacement, error, current],
        rows: 3,
        cols: 1,
        size_px: (1000, 1100),
    }
}

fn report(name: &str, s: &TrackingStats) {
    println!(
        "  {name:<16} RMS {:.3e} m = {:>7.3} % of p2p   max {:.3e} m = {:>7.3} %",
        s.rms_error_m,
        s.rms_percent(),
        s.max_error_m,
        s.max_percent()
    );
}

/// Runs `maglab track`.
pub fn run(args: &Args) -> Result<()> {
    if !(args.duration_s.is_finite() && args.duration_s > 0.0) {
        bail!(
            "--duration-s must be a positive number, got {}",
            args.duration_s
        );
    }
    if !(args.plot_s.is_finite() && args.plot_s > 0.0) {
        bail!("--plot-s must be a positive number, got {}", args.plot_s);
    }
    let effects = args
        .effects
        .iter()
        .map(|t| Effect::parse(t).map_err(|e| anyhow::anyhow!("--effect {t}: {e}")))
        .collect::<Result<Vec<_>>>()?;
    let loaded = params_io::load(args.params.as_deref())?;
    println!("parameters: {} ({})", loaded.origin, loaded.provenance);
    let started = std::time::Instant::now();
    let t = track(&loaded, args.duration_s, &effects, args.capture.as_deref())?;
    let source = match &args.capture {
        Some(p) => format!("current commands from the QEMU capture {}", p.display()),
        None => "current commands from magctl::inverse::ControlLoop on the host".to_string(),
    };
    let described: Vec<String> = effects.iter().map(|e| e.to_string()).collect();
    println!(
        "tracking the Van der Pol trajectory (p2p {:.3e} m) for {} periods; {source}; bench plant, effects: {} ({:.1} s):",
        t.dynamic.stats.peak_to_peak_m,
        t.dynamic.desired_m.len(),
        if described.is_empty() { "none".to_string() } else { described.join("; ") },
        started.elapsed().as_secs_f64()
    );
    report("dynamic inverse", &t.dynamic.stats);
    report("static inverse", &t.static_.stats);
    println!(
        "  static / dynamic RMS error: {:.1}x",
        t.static_.stats.rms_error_m / t.dynamic.stats.rms_error_m
    );

    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let csv_path = args.out.join("tracking.csv");
    write_csv(&csv_path, &t)?;
    println!("wrote {}", csv_path.display());
    for (run, stem, title) in [
        (&t.dynamic, "fig7_dynamic", "dynamic inverse (Fig. 7)"),
        (&t.static_, "fig8_static", "static inverse (Fig. 8)"),
    ] {
        for path in figure(run, t.period_s, args.plot_s, title).write(&args.out.join(stem))? {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("maglab-track-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A short run writes every output, and the dynamic inverse beats the static one by the
    /// margin the acceptance asks for (RMS ≤ 1 % of p2p; the static inverse several times worse:
    /// its phase lag at the ≈ 94 Hz fundamental alone is ≈ 0.37 rad, ~13 % of p2p in RMS).
    /// 0.05 s (≈ 5 periods of the trajectory) keeps it fast.
    #[test]
    fn short_run_writes_outputs_and_dynamic_beats_static() {
        let out = temp_dir("run");
        let args = Args {
            duration_s: 0.05,
            plot_s: 0.02,
            effects: Vec::new(),
            capture: None,
            params: None,
            out: out.clone(),
        };
        run(&args).unwrap();
        for name in [
            "tracking.csv",
            "fig7_dynamic.png",
            "fig7_dynamic.svg",
            "fig8_static.png",
            "fig8_static.svg",
        ] {
            let meta = std::fs::metadata(out.join(name)).unwrap();
            assert!(meta.len() > 0, "{name} is empty");
        }
        let rows = std::fs::read_to_string(out.join("tracking.csv"))
            .unwrap()
            .lines()
            .count();
        assert_eq!(rows, 1 + 500);
        let t = track(&params_io::load(None).unwrap(), 0.05, &[], None).unwrap();
        assert!(
            t.dynamic.stats.rms_percent() <= 1.0,
            "{:?}",
            t.dynamic.stats
        );
        assert!(t.static_.stats.rms_error_m > 5.0 * t.dynamic.stats.rms_error_m);
        std::fs::remove_dir_all(&out).ok();
    }

    /// Replaying the host run's commands from a capture file gives the same plant response: the
    /// capture path feeds the plant exactly what it read (currents written with `{:e}`, which
    /// round-trips f32 exactly).
    #[test]
    fn capture_replay_matches_the_host_run() {
        let dir = temp_dir("capture");
        let loaded = params_io::load(None).unwrap();
        let host = track(&loaded, 0.01, &[], None).unwrap();
        let mut text = String::from("phase,index,t_s,current_a,y_desired_m,instructions\n");
        for (name, run) in [("dynamic", &host.dynamic), ("static", &host.static_)] {
            for (k, (i, y)) in run.current_a.iter().zip(&run.desired_m).enumerate() {
                text.push_str(&format!(
                    "{name},{k},0,{:e},{:e},800\n",
                    *i as f32, *y as f32
                ));
            }
        }
        // Every other phase the benchmark run writes is read and skipped.
        for phase in CapturePhase::ALL {
            if !matches!(phase, CapturePhase::Dynamic | CapturePhase::Static) {
                text.push_str(&format!("{},0,0,1.0,2e-5,400000\n", phase.name()));
            }
        }
        let path = dir.join("capture.csv");
        std::fs::write(&path, text).unwrap();
        let replay = track(&loaded, 0.01, &[], Some(&path)).unwrap();
        assert_eq!(replay.dynamic.actual_m, host.dynamic.actual_m);
        assert_eq!(replay.static_.actual_m, host.static_.actual_m);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn bad_capture_rows_name_the_line_and_column() {
        let dir = temp_dir("bad");
        let path = dir.join("capture.csv");
        std::fs::write(
            &path,
            "phase,index,current_a,y_desired_m\ndynamic,0,0.5,2e-5\ndynamic,1,abc,2e-5\n",
        )
        .unwrap();
        let e = format!("{:#}", read_capture(&path).unwrap_err());
        assert!(
            e.contains("line 3") && e.contains("current_a") && e.contains("abc"),
            "{e}"
        );
        std::fs::write(&path, "phase,index,current_a\ndynamic,0,0.5\n").unwrap();
        let e = format!("{:#}", read_capture(&path).unwrap_err());
        assert!(e.contains("y_desired_m"), "{e}");
        std::fs::write(&path, "phase,current_a,y_desired_m\nwarp,0.5,2e-5\n").unwrap();
        let e = format!("{:#}", read_capture(&path).unwrap_err());
        assert!(e.contains("line 2") && e.contains("warp"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
