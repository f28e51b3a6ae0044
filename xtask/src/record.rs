//! `cargo xtask record`: the host side of the firmware's own measurement — reads the decoded
//! defmt log of a measurement run (`MEAS …` lines: the NUCLEO measurement image over RTT as
//! `probe-rs run` prints it, or `firmware-hil mode=measure-local` under QEMU), checks that the
//! record is complete, and writes the dataset folder `maglab identify` reads.
//!
//! ```text
//! cargo xtask record -o data -- probe-rs run --chip STM32F446RETx out/nucleo/firmware-nucleo-measure.elf
//! cargo xtask record -o data --log run.txt          # a saved log (probe-rs run ... > run.txt)
//! ```
//!
//! Lines (anywhere in a line, so probe-rs's timestamps and levels around them do not matter):
//! * `MEAS-BEGIN <rate> Hz <n> experiments <start state>`
//! * `MEAS-EXP <k> <ticks> forc <sweep Hz> 0 0` or `MEAS-EXP <k> <ticks> sine <Hz> <A> <bias A>`
//! * `MEAS <k> <first tick> [b, b, …]`: ticks of experiment `k` from `first tick` on, 13 bytes each
//!   (`magctl::record`: current f32, reading f32, flags u8, coil current f32 — NaN without a
//!   current monitor —, little endian)
//! * `MEAS-END <lost> lost <faults> sensor-faults`
//!
//! A record is refused — with the line number and what is wrong — when a tick is missing or
//! repeated, a tick was lost on the board, a reading is not finite, a line does not parse, or
//! the end line never came: nothing is written then.

use crate::util::display;
use anyhow::{bail, ensure, Context, Result};
use magctl::record::{decode_batch, MeasuredSample};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// One experiment of a record.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedExperiment {
    /// `forc` or `sine`.
    pub kind: String,
    /// Sweep Hz (forc) or frequency Hz, amplitude A, bias A (sine).
    pub values: [f64; 3],
    /// Announced ticks.
    pub ticks: usize,
    /// The ticks received, by index (`None`: not yet).
    pub samples: Vec<Option<MeasuredSample>>,
}

impl RecordedExperiment {
    /// File stem in the dataset folder (the same names as `cargo xtask hil --measure`).
    pub fn name(&self, k: usize) -> String {
        match self.kind.as_str() {
            "forc" => format!("{k:02}_forc"),
            _ => format!(
                "{k:02}_sine_{:07.1}hz_amp{:.3}a_bias{:.3}a",
                self.values[0], self.values[1], self.values[2]
            ),
        }
    }

    /// Excitation in words, for `dataset.json`.
    pub fn description(&self) -> String {
        match self.kind.as_str() {
            "forc" => format!(
                "FORC reversal sweep, {} Hz full-range triangle rate",
                self.values[0]
            ),
            _ => format!(
                "sine {} Hz, {} ± {} A",
                self.values[0], self.values[2], self.values[1]
            ),
        }
    }
}

/// A complete measurement record.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Start state of every experiment (`dataset.json` name).
    pub start_state: String,
    /// The experiments, in order.
    pub experiments: Vec<RecordedExperiment>,
}

/// Reads a record from decoded log lines, line by line.
#[derive(Debug, Default)]
pub struct RecordParser {
    rate_hz: Option<f64>,
    start_state: String,
    announced: usize,
    experiments: Vec<RecordedExperiment>,
    /// `(lost, sensor faults)` from the end line.
    end: Option<(u64, u64)>,
}

fn words_after<'a>(line: &'a str, tag: &str) -> Option<Vec<&'a str>> {
    let at = line.split_whitespace().position(|w| w == tag)?;
    Some(line.split_whitespace().skip(at + 1).collect())
}

fn num<T: std::str::FromStr>(w: Option<&&str>, what: &str) -> Result<T> {
    let w = w.with_context(|| format!("{what} missing"))?;
    w.parse()
        .map_err(|_| anyhow::anyhow!("{what}: `{w}` is not a number"))
}

impl RecordParser {
    /// Takes one log line (`number` for errors); lines without a `MEAS` tag are ignored.
    pub fn line(&mut self, number: usize, line: &str) -> Result<()> {
        self.parse_line(line)
            .with_context(|| format!("log line {number}: `{}`", line.trim()))
    }

    /// Whether the end line has been read.
    pub fn ended(&self) -> bool {
        self.end.is_some()
    }

    fn parse_line(&mut self, line: &str) -> Result<()> {
        if let Some(w) = words_after(line, "MEAS-BEGIN") {
            ensure!(self.rate_hz.is_none(), "a second MEAS-BEGIN");
            let rate: f64 = num(w.first(), "control rate")?;
            ensure!(rate.is_finite() && rate > 0.0, "control rate {rate} Hz");
            self.rate_hz = Some(rate);
            self.announced = num(w.get(2), "experiment count")?;
            self.start_state = w.get(4).unwrap_or(&"negative-saturation").to_string();
        } else if let Some(w) = words_after(line, "MEAS-EXP") {
            ensure!(self.rate_hz.is_some(), "MEAS-EXP before MEAS-BEGIN");
            let k: usize = num(w.first(), "experiment index")?;
            ensure!(
                k == self.experiments.len(),
                "experiment {k} announced, expected {}",
                self.experiments.len()
            );
            let ticks: usize = num(w.get(1), "tick count")?;
            let kind = w.get(2).context("experiment kind missing")?.to_string();
            ensure!(
                kind == "forc" || kind == "sine",
                "experiment kind `{kind}` (forc or sine)"
            );
            let mut values = [0.0; 3];
            for (i, v) in values.iter_mut().enumerate() {
                *v = num(w.get(3 + i), "experiment setting")?;
            }
            self.experiments.push(RecordedExperiment {
                kind,
                values,
                ticks,
                samples: vec![None; ticks],
            });
        } else if let Some(w) = words_after(line, "MEAS-END") {
            self.end = Some((
                num(w.first(), "lost ticks")?,
                num(w.get(2), "sensor faults")?,
            ));
        } else if let Some(w) = words_after(line, "MEAS") {
            let k: usize = num(w.first(), "experiment")?;
            let first: u32 = num(w.get(1), "first tick")?;
            let list = w.get(2..).unwrap_or(&[]).join(" ");
            let list = list
                .trim()
                .strip_prefix('[')
                .and_then(|l| l.strip_suffix(']'))
                .context("the bytes are not a [..] list")?;
            let bytes: Vec<u8> = list
                .split(',')
                .map(str::trim)
                .filter(|b| !b.is_empty())
                .map(|b| b.parse::<u8>().map_err(|_| anyhow::anyhow!("byte `{b}`")))
                .collect::<Result<_>>()?;
            let experiment = u8::try_from(k).map_err(|_| anyhow::anyhow!("experiment {k}"))?;
            let e = self
                .experiments
                .get_mut(k)
                .with_context(|| format!("batch of experiment {k}, which was not announced"))?;
            let samples = decode_batch(experiment, first, &bytes)
                .map_err(|b| anyhow::anyhow!("{} bytes are not whole ticks", b.0))?;
            for s in samples {
                let slot = e.samples.get_mut(s.tick as usize).with_context(|| {
                    format!(
                        "tick {} beyond the announced {} of experiment {k}",
                        s.tick, e.ticks
                    )
                })?;
                ensure!(slot.is_none(), "tick {} of experiment {k} repeated", s.tick);
                *slot = Some(s);
            }
        }
        Ok(())
    }

    /// The complete record, or what is missing.
    pub fn finish(self) -> Result<Record> {
        let rate_hz = self
            .rate_hz
            .context("no MEAS-BEGIN line: not a measurement log")?;
        ensure!(
            self.experiments.len() == self.announced,
            "{} experiments announced, {} described",
            self.announced,
            self.experiments.len()
        );
        let (lost, faults) = self
            .end
            .context("no MEAS-END line: the record stopped before the programme ended")?;
        ensure!(
            lost == 0,
            "the board lost {lost} tick(s): the probe did not drain the RTT record fast enough \
             (the programme ended early at 0 A); use a faster probe or a lower control rate"
        );
        ensure!(
            faults == 0,
            "the board latched {faults} sensor fault(s): the record stops there (check the \
             sensor wiring and the `sensor` section)"
        );
        for (k, e) in self.experiments.iter().enumerate() {
            if let Some(t) = e.samples.iter().position(Option::is_none) {
                let missing = e.samples.iter().filter(|s| s.is_none()).count();
                bail!(
                    "experiment {k} ({}): {missing} of {} ticks missing, the first at tick {t}",
                    e.name(k),
                    e.ticks
                );
            }
            for s in e.samples.iter().flatten() {
                ensure!(
                    s.current_a.is_finite() && s.reading_m.is_finite(),
                    "experiment {k} ({}), tick {}: current {} A, reading {} m",
                    e.name(k),
                    s.tick,
                    s.current_a,
                    s.reading_m
                );
            }
        }
        Ok(Record {
            rate_hz,
            start_state: self.start_state,
            experiments: self.experiments,
        })
    }
}

/// Parses a whole log.
pub fn parse(lines: &[String]) -> Result<Record> {
    let mut p = RecordParser::default();
    for (i, l) in lines.iter().enumerate() {
        p.line(i + 1, l)?;
    }
    p.finish()
}

/// Writes the dataset folder: one `t_s,current_a,displacement_m` file per experiment (with the
/// `coil_current_a` column when the record holds the current monitor's reading of every tick;
/// a record with it for some ticks only is refused) and `dataset.json` (start state, each
/// file's excitation).
pub fn write_dataset(record: &Record, dir: &Path) -> Result<()> {
    use maglab_dataset::dataset_info::{DatasetInfo, FileInfo, StartState};
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let start = StartState::parse(&record.start_state)
        .map_err(|e| anyhow::anyhow!("start state `{}`: {e}", record.start_state))?;
    let mut info = DatasetInfo {
        start_state: Some(start),
        files: Default::default(),
    };
    for (k, e) in record.experiments.iter().enumerate() {
        let t: Vec<f64> = (0..e.ticks).map(|i| i as f64 / record.rate_hz).collect();
        let i: Vec<f64> = e
            .samples
            .iter()
            .flatten()
            .map(|s| s.current_a as f64)
            .collect();
        let y: Vec<f64> = e
            .samples
            .iter()
            .flatten()
            .map(|s| s.reading_m as f64)
            .collect();
        let coil: Vec<f64> = e
            .samples
            .iter()
            .flatten()
            .map(|s| s.coil_current_a as f64)
            .filter(|c| c.is_finite())
            .collect();
        ensure!(
            coil.is_empty() || coil.len() == y.len(),
            "{}: the record holds the coil current for {} of its {} ticks",
            e.name(k),
            coil.len(),
            y.len()
        );
        let file = format!("{}.csv", e.name(k));
        let coil = (!coil.is_empty()).then_some(coil.as_slice());
        maglab_dataset::data::write_measurement(&dir.join(&file), &t, &i, &y, coil)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        info.files.insert(
            file,
            FileInfo {
                start_state: None,
                excitation: Some(e.description()),
            },
        );
    }
    info.write(dir).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

/// `cargo xtask record`'s options: `-o DIR (--log FILE | -- COMMAND ARGS...)`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset folder to write.
    #[arg(short, long, value_name = "DIR")]
    out: PathBuf,
    /// A saved defmt log of the measurement run.
    #[arg(long, value_name = "FILE", conflicts_with = "command")]
    log: Option<PathBuf>,
    /// The command that prints the decoded log (after `--`), e.g. `probe-rs run --chip
    /// STM32F446RETx out/nucleo/firmware-nucleo-measure.elf`.
    #[arg(last = true, value_name = "COMMAND")]
    command: Vec<String>,
}

/// `cargo xtask record -o DIR (--log FILE | -- COMMAND ARGS...)`.
pub fn run(_ctx: &crate::util::Ctx, args: &Args) -> Result<()> {
    let (out, log, command) = (args.out.clone(), args.log.clone(), args.command.clone());
    let mut parser = RecordParser::default();
    match (log, command.is_empty()) {
        (Some(path), true) => {
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("reading {}", path.display()))?;
            for (i, l) in text.lines().enumerate() {
                parser.line(i + 1, l)?;
            }
        }
        (None, false) => {
            let mut cmd = Command::new(&command[0]);
            cmd.args(&command[1..]).stdout(Stdio::piped());
            println!("$ {}", display(&cmd));
            let mut child = cmd
                .spawn()
                .with_context(|| format!("cannot start `{}`", command[0]))?;
            let stdout = child.stdout.take().context("the command's stdout")?;
            let mut result = Ok(());
            let mut last_report = std::time::Instant::now();
            for (i, l) in BufReader::new(stdout).lines().enumerate() {
                let l = l.context("reading the command's output")?;
                if !l.contains("MEAS ") {
                    println!("{l}");
                }
                result = parser.line(i + 1, &l);
                if result.is_err() || parser.ended() {
                    break;
                }
                if last_report.elapsed().as_secs() >= 5 {
                    println!("  … recording (line {})", i + 1);
                    last_report = std::time::Instant::now();
                }
            }
            // The board idles at 0 A after the programme; the probe session is not needed.
            let _ = child.kill();
            let _ = child.wait();
            result?;
        }
        _ => bail!("give exactly one of --log FILE or -- COMMAND ARGS..."),
    }
    let record = parser.finish()?;
    write_dataset(&record, &out)?;
    let ticks: usize = record.experiments.iter().map(|e| e.ticks).sum();
    println!(
        "wrote {}: {} experiments, {ticks} ticks at {} Hz (start state {})",
        out.display(),
        record.experiments.len(),
        record.rate_hz,
        record.start_state
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use magctl::record::RecordBatch;

    fn batch_line(b: &RecordBatch) -> String {
        format!(
            "INFO  MEAS {} {} {:?}",
            b.experiment(),
            b.first_tick(),
            b.bytes()
        )
    }

    fn log(ticks: u32, skip: Option<u32>, lost: u32) -> Vec<String> {
        log_with_coil_current(ticks, skip, lost, |_| f32::NAN)
    }

    fn log_with_coil_current(
        ticks: u32,
        skip: Option<u32>,
        lost: u32,
        coil_current_a: impl Fn(u32) -> f32,
    ) -> Vec<String> {
        let mut lines = vec![
            "INFO  MEAS-BEGIN 10000 Hz 1 experiments negative-saturation".to_string(),
            "└─ firmware_nucleo::firmware::log_programme @ src/bin/firmware_nucleo.rs:1".into(),
            format!("INFO  MEAS-EXP 0 {ticks} sine 20 0.15 0.55"),
        ];
        let mut b = RecordBatch::new();
        for t in 0..ticks {
            if Some(t) == skip {
                continue;
            }
            let s = MeasuredSample {
                experiment: 0,
                tick: t,
                current_a: t as f32,
                reading_m: 1e-6 * t as f32,
                flags: 64,
                coil_current_a: coil_current_a(t),
            };
            if !b.push(&s) {
                lines.push(batch_line(&b));
                b.clear();
                assert!(b.push(&s));
            }
        }
        lines.push(batch_line(&b));
        lines.push(format!("INFO  MEAS-END {lost} lost 0 sensor-faults"));
        lines
    }

    #[test]
    fn a_complete_log_gives_every_tick_in_order() {
        let r = parse(&log(105, None, 0)).unwrap();
        assert_eq!(r.rate_hz, 10_000.0);
        let e = &r.experiments[0];
        assert_eq!(e.name(0), "00_sine_00020.0hz_amp0.150a_bias0.550a");
        for (t, s) in e.samples.iter().enumerate() {
            assert_eq!(s.unwrap().current_a, t as f32);
        }
    }

    #[test]
    fn the_coil_current_goes_into_its_column_when_every_tick_has_it() {
        let dir = std::env::temp_dir().join(format!("xtask-record-coil-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let r = parse(&log_with_coil_current(105, None, 0, |t| {
            0.5 + 1e-3 * t as f32
        }))
        .unwrap();
        write_dataset(&r, &dir).unwrap();
        let m = maglab_dataset::data::load_dataset(&dir).unwrap();
        let coil = m.measurements[0]
            .coil_current_a
            .as_ref()
            .expect("the column");
        assert_eq!(coil[7], (0.5 + 1e-3 * 7.0f32) as f64);
        // Without a monitor: no column.
        write_dataset(&parse(&log(105, None, 0)).unwrap(), &dir).unwrap();
        let m = maglab_dataset::data::load_dataset(&dir).unwrap();
        assert!(m.measurements[0].coil_current_a.is_none());
        // For some ticks only: refused.
        let some = parse(&log_with_coil_current(105, None, 0, |t| {
            if t < 50 {
                f32::NAN
            } else {
                1.0
            }
        }))
        .unwrap();
        let e = write_dataset(&some, &dir).unwrap_err().to_string();
        assert!(e.contains("55 of its 105 ticks"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_missing_tick_a_lost_tick_or_a_missing_end_is_refused_with_the_reason() {
        let e = parse(&log(105, Some(42), 0)).unwrap_err().to_string();
        assert!(e.contains("first at tick 42"), "{e}");
        let e = parse(&log(105, None, 3)).unwrap_err().to_string();
        assert!(e.contains("lost 3 tick"), "{e}");
        let mut l = log(105, None, 0);
        l.pop();
        let e = parse(&l).unwrap_err().to_string();
        assert!(e.contains("no MEAS-END"), "{e}");
        let mut l = log(105, None, 0);
        l[3] = l[3].replace(", ", ", x");
        let e = format!("{:#}", parse(&l).unwrap_err());
        assert!(e.contains("log line 4"), "{e}");
    }
}
