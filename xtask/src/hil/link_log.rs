//! The link's log (`link.csv`: one row per tick, the plant's sample and the firmware's command)
//! and the tracking error scored from it or from the plant's own log.

use anyhow::{ensure, Context, Result};
use magctl::inverse::CommandFlags;
use magctl::link::{CommandFrame, Sample};
use magctl::params::BAKED_PARAMETERS;
use magctl::sensor::SensorScale;
use std::io::Write;
use std::path::Path;

/// The header of `link.csv`.
pub const LINK_CSV_HEADER: &str =
    "tick,sample_kind,sample_raw,sample_m,current_a,desired_m,flags,instructions";

/// One tick of the link: the plant's sample and the firmware's command.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TickRow {
    pub sample: Option<Sample>,
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
        let (kind, raw, m) = match r.sample {
            Some(s @ Sample::Count(c)) => ("S", c.to_string(), sample_m(&scale, s)),
            Some(s @ Sample::Metres(v)) => ("M", format!("{v:e}"), sample_m(&scale, s)),
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
        writeln!(f, "{k},{kind},{raw},{m:e},{i},{d},{fl},{ins}")?;
    }
    f.flush()?;
    Ok(())
}

/// RMS and max |y − ȳ| in % of ȳ's peak-to-peak over the tracking ticks (conditioning excluded): the plant's true
/// displacement from its log when present, the next tick's sensor reading otherwise.
pub(super) fn tracking_error(
    plant_log: &Path,
    rows: &[TickRow],
) -> Result<Option<(f64, f64, &'static str)>> {
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    let on;
    if plant_log.exists() {
        on = "true displacement, plant log";
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
    } else {
        on = "sensor reading at the period's end";
        let scale = SensorScale::new(&BAKED_PARAMETERS.sensor);
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
    }
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
