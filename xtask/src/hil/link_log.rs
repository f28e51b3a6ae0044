//! The link's log (`link.csv`: one row per tick, the plant's sample and the firmware's command)
//! and the tracking error scored from it or from the plant's own log.

use anyhow::{bail, ensure, Context, Result};
use magctl::inverse::CommandFlags;
use magctl::link::{CommandFrame, Sample};
use magctl::params::BAKED_PARAMETERS;
use magctl::sensor::SensorScale;
use std::io::Write;
use std::path::Path;

/// The header of `link.csv`.
pub const LINK_CSV_HEADER: &str =
    "tick,sample_kind,sample_raw,sample_m,current_a,desired_m,flags,instructions,coil_current_a";

/// One tick of the link: the plant's sample (with the coil current its current monitor read, in
/// link version 2's frames) and the firmware's command.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TickRow {
    pub sample: Option<Sample>,
    pub coil_current_a: Option<f32>,
    pub command: Option<CommandFrame>,
}

fn sample_m(scale: &SensorScale, s: Sample) -> f64 {
    match s {
        Sample::Count(c) => scale.displacement_m(c).map_or(f64::NAN, |m| m as f64),
        Sample::Metres(m) => m as f64,
    }
}

pub(super) fn write_link_csv(path: &Path, rows: &[TickRow]) -> Result<()> {
    let scale = SensorScale::new(&BAKED_PARAMETERS.sensor);
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(f, "{LINK_CSV_HEADER}")?;
    for (k, r) in rows.iter().enumerate() {
        let with_current = r.coil_current_a.is_some();
        let (kind, raw, m) = match r.sample {
            Some(s @ Sample::Count(c)) => (
                if with_current { "T" } else { "S" },
                c.to_string(),
                sample_m(&scale, s),
            ),
            Some(s @ Sample::Metres(v)) => (
                if with_current { "U" } else { "M" },
                format!("{v:e}"),
                sample_m(&scale, s),
            ),
            None => ("", String::new(), f64::NAN),
        };
        let (i, d, fl, ins) = match r.command {
            Some(c) => (
                format!("{:e}", c.value),
                format!("{:e}", c.desired_m),
                c.flags.to_string(),
                c.aux.to_string(),
            ),
            None => Default::default(),
        };
        let coil = r
            .coil_current_a
            .map(|c| format!("{c:e}"))
            .unwrap_or_default();
        writeln!(f, "{k},{kind},{raw},{m:e},{i},{d},{fl},{ins},{coil}")?;
    }
    f.flush()?;
    Ok(())
}

/// The file an external plant may write its true displacement to (`docs/hil.md`, "Scoring"):
/// `tick,y_m`, one row per tick, `y_m` the rod's true displacement at the end of the tick's
/// period. Its path is passed in this environment variable.
pub const TRUE_DISPLACEMENT_ENV: &str = "HIL_TRUE_DISPLACEMENT_CSV";

/// RMS and max |y − ȳ| in % of ȳ's peak-to-peak over the tracking ticks (conditioning excluded),
/// and what `y` was: the plant's true displacement from its log (`maglab hil-plant`) or from the
/// file an external plant wrote (`true_displacement`), else the next tick's sensor reading.
pub(super) fn tracking_error(
    plant_log: &Path,
    true_displacement: &Path,
    rows: &[TickRow],
) -> Result<Option<(f64, f64, &'static str)>> {
    let (pairs, on) = if plant_log.exists() {
        (plant_log_pairs(plant_log)?, "true displacement, plant log")
    } else if true_displacement.exists() {
        (
            reported_pairs(true_displacement, rows)?,
            "true displacement, reported by the plant",
        )
    } else {
        (
            sensed_pairs(rows),
            "SENSED displacement: the sensor reading at the period's end (the plant reported no true displacement)",
        )
    };
    if pairs.len() < 2 {
        return Ok(None);
    }
    let (lo, hi) = pairs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
            (l.min(p.0), h.max(p.0))
        });
    let p2p = hi - lo;
    let n = pairs.len() as f64;
    let rms = (pairs.iter().map(|(d, y)| (y - d).powi(2)).sum::<f64>() / n).sqrt();
    let max = pairs.iter().map(|(d, y)| (y - d).abs()).fold(0.0, f64::max);
    Ok(Some((100.0 * rms / p2p, 100.0 * max / p2p, on)))
}

/// `(desired, true)` pairs of the tracking ticks from `maglab hil-plant`'s log.
fn plant_log_pairs(plant_log: &Path) -> Result<Vec<(f64, f64)>> {
    let mut pairs = Vec::new();
    let text = std::fs::read_to_string(plant_log)?;
    for (n, line) in text.lines().enumerate().skip(1) {
        let cols: Vec<&str> = line.split(',').collect();
        ensure!(
            cols.len() == 9,
            "{}: line {}: expected 9 columns",
            plant_log.display(),
            n + 1
        );
        let desired: f64 = cols[3].parse().with_context(|| format!("line {}", n + 1))?;
        let y: f64 = cols[4].parse().with_context(|| format!("line {}", n + 1))?;
        let flags: u8 = cols[7].parse().with_context(|| format!("line {}", n + 1))?;
        if flags & (CommandFlags::CONDITIONING | CommandFlags::MEASURE) == 0 {
            pairs.push((desired, y));
        }
    }
    Ok(pairs)
}

/// `(desired, true)` pairs of the tracking ticks from an external plant's `tick,y_m` file, the
/// desired displacement from the tick's command frame. A malformed row, a tick the run did not
/// command or a non-finite value is an error naming the line.
fn reported_pairs(path: &Path, rows: &[TickRow]) -> Result<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path)?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, "tick,y_m")) => {}
        other => bail!(
            "{}: line 1: expected the header `tick,y_m`, found `{}`",
            path.display(),
            other.map_or("", |(_, l)| l)
        ),
    }
    let mut pairs = Vec::new();
    for (n, line) in lines {
        let at = || format!("{}: line {}: `{line}`", path.display(), n + 1);
        let (tick, y) = line
            .split_once(',')
            .with_context(|| format!("{}: expected `tick,y_m`", at()))?;
        let tick: usize = tick
            .trim()
            .parse()
            .with_context(|| format!("{}: tick is not a whole number", at()))?;
        let y: f64 = y
            .trim()
            .parse()
            .with_context(|| format!("{}: y_m is not a number", at()))?;
        ensure!(y.is_finite(), "{}: y_m is not finite", at());
        let command = rows
            .get(tick)
            .and_then(|r| r.command)
            .with_context(|| format!("{}: the firmware sent no command for tick {tick}", at()))?;
        if command.flags & (CommandFlags::CONDITIONING | CommandFlags::MEASURE) == 0 {
            pairs.push((command.desired_m as f64, y));
        }
    }
    Ok(pairs)
}

/// `(desired, sensed)` pairs: each tracking tick's command against the next tick's sample.
fn sensed_pairs(rows: &[TickRow]) -> Vec<(f64, f64)> {
    let scale = SensorScale::new(&BAKED_PARAMETERS.sensor);
    let mut pairs = Vec::new();
    for w in rows.windows(2) {
        if let (Some(c), Some(s)) = (w[0].command, w[1].sample) {
            if c.flags & (CommandFlags::CONDITIONING | CommandFlags::MEASURE) != 0 {
                continue;
            }
            let y = sample_m(&scale, s);
            if y.is_finite() {
                pairs.push((c.desired_m as f64, y));
            }
        }
    }
    pairs
}
