//! Measurement mode of the virtual bench: the identification programme the host streams (or
//! the firmware plays itself), the record checked against the link, and the dataset folder.

use super::link_log::TickRow;
use anyhow::{ensure, Context, Result};
use magctl::inverse::CommandFlags;
use magctl::params::BAKED_PARAMETERS;
use std::path::Path;

/// An identification programme: every tick's current and the experiments it records.
#[derive(Debug, Clone, PartialEq)]
pub struct Programme {
    /// Current of every tick, A (conditioning included).
    pub current_a: Vec<f32>,
    /// Recorded experiments: file stem, description, and the tick of each recorded sample (with
    /// a coil heat budget the FORC sweep's samples are interrupted by unrecorded pauses).
    pub experiments: Vec<(String, String, Vec<usize>)>,
}

/// The identification programme `maglab identify` needs, built from the *nominal* (baked)
/// parameters — all a bench user knows before identifying — by the core's generator
/// (`magctl::programme`, the one the firmware plays itself in `mode=measure-local` and on the
/// NUCLEO measurement image): the FORC sweep (reversals on every grid line, 5 % beyond the grid,
/// clipped to the current limit by the firmware's limiter; over the reach, for a file that has
/// one) and biased sines, each experiment preceded by the start-up conditioning sequence (then
/// slowly to its first current — the start state `negative-saturation` or `conditioned` of
/// `dataset.json`).
pub fn identification_programme() -> Result<Programme> {
    let programme = core_programme()?;
    let mut prog = Programme {
        current_a: Vec::new(),
        experiments: Vec::new(),
    };
    let mut state = programme.start(0.0);
    while let Some(t) = programme.step(&mut state) {
        if t.sample == Some(0) {
            let e = programme
                .experiment(t.experiment)
                .context("the programme's experiment table")?;
            let (kind, a, b, c) = e.kind.fields();
            let described = crate::record::RecordedExperiment {
                kind: kind.to_string(),
                values: [a as f64, b as f64, c as f64],
                ticks: e.ticks as usize,
                samples: Vec::new(),
            };
            prog.experiments.push((
                described.name(t.experiment),
                described.description(),
                Vec::with_capacity(e.ticks as usize),
            ));
        }
        if t.sample.is_some() {
            let tick = prog.current_a.len();
            prog.experiments
                .last_mut()
                .context("a recorded tick before its experiment's first")?
                .2
                .push(tick);
        }
        prog.current_a.push(t.current_a);
    }
    Ok(prog)
}

/// The core's identification programme for the baked parameters.
pub(super) fn core_programme() -> Result<magctl::programme::IdentificationProgramme> {
    let p = &BAKED_PARAMETERS;
    let measure = &magctl::params::BAKED_MEASURE;
    let limiter = magctl::inverse::OutputLimiter::new(&p.control)
        .map_err(|e| anyhow::anyhow!("control settings: {e:?}"))?;
    magctl::programme::IdentificationProgramme::for_parameters(&limiter, p, measure)
        .map_err(|e| anyhow::anyhow!("identification programme: {e:?}"))
}

/// Ticks of a local measurement run: the programme, then the ramp to 0 A (as firmware-hil
/// counts them).
pub(super) fn local_programme_ticks() -> Result<u32> {
    let limiter = magctl::inverse::OutputLimiter::new(&BAKED_PARAMETERS.control)
        .map_err(|e| anyhow::anyhow!("control settings: {e:?}"))?;
    let ramp = (limiter.limit_a() / limiter.max_step_a()).ceil() as u32 + 2;
    Ok(core_programme()?.total_ticks(0.0) + ramp)
}

/// Checks every tick of the firmware's record against the command frame of the same tick
/// (bit for bit: the current applied, the reading, the flags); returns the ticks checked.
pub(super) fn check_record_against_link(
    record: &crate::record::Record,
    rows: &[TickRow],
) -> Result<usize> {
    let programme = core_programme()?;
    let mut state = programme.start(0.0);
    let mut tick = 0usize;
    let mut checked = 0usize;
    while let Some(t) = programme.step(&mut state) {
        if let Some(k) = t.sample {
            let s = record
                .experiments
                .get(t.experiment)
                .and_then(|e| e.samples.get(k as usize))
                .copied()
                .flatten()
                .with_context(|| format!("record: experiment {} tick {k} missing", t.experiment))?;
            let c = rows
                .get(tick)
                .and_then(|r| r.command)
                .with_context(|| format!("no command frame for tick {tick}"))?;
            ensure!(
                s.current_a.to_bits() == c.value.to_bits()
                    && s.reading_m.to_bits() == c.desired_m.to_bits()
                    && s.flags == c.flags,
                "tick {tick} (experiment {} tick {k}): record ({} A, {} m, flags {}) differs from the link ({} A, {} m, flags {})",
                t.experiment,
                s.current_a,
                s.reading_m,
                s.flags,
                c.value,
                c.desired_m,
                c.flags
            );
            checked += 1;
        }
        tick += 1;
    }
    Ok(checked)
}

/// Writes the dataset folder of a measurement run: one `t_s,current_a,displacement_m` file per
/// experiment (the current the firmware applied and its reading of the tick's sample), with the
/// `coil_current_a` column when the plant's current monitor read every tick (link version 2's
/// sample frames), and `dataset.json` (the programme's start state, `negative-saturation` or
/// `conditioned`, and the excitation of each file). A run whose plant sent the coil current for
/// some ticks only is refused.
pub(super) fn write_dataset(programme: &Programme, rows: &[TickRow], dir: &Path) -> Result<()> {
    use maglab_dataset::dataset_info::{DatasetInfo, FileInfo, StartState};
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let rate_hz = BAKED_PARAMETERS.control.sample_rate_hz as f64;
    let start = StartState::parse(core_programme()?.start_state_name())
        .map_err(|e| anyhow::anyhow!("the programme's start state: {e}"))?;
    let mut info = DatasetInfo {
        start_state: Some(start),
        files: Default::default(),
    };
    for (name, description, ticks) in &programme.experiments {
        let len = ticks.len();
        let mut t = Vec::with_capacity(len);
        let mut i = Vec::with_capacity(len);
        let mut y = Vec::with_capacity(len);
        let mut coil = Vec::with_capacity(len);
        for (k, &tick) in ticks.iter().enumerate() {
            let row = rows.get(tick);
            let c = row
                .and_then(|r| r.command)
                .with_context(|| format!("{name}: no command frame for tick {tick}"))?;
            if let Some(i) = row.and_then(|r| r.coil_current_a) {
                coil.push(i as f64);
            }
            ensure!(
                c.flags & CommandFlags::MEASURE != 0 && c.desired_m.is_finite(),
                "{name}: tick {tick} has no valid reading (flags {})",
                c.flags
            );
            t.push(k as f64 / rate_hz);
            i.push(c.value as f64);
            y.push(c.desired_m as f64);
        }
        ensure!(
            coil.is_empty() || coil.len() == t.len(),
            "{name}: the plant sent the coil current for {} of its {} ticks (link version 2 frames \
             for some ticks only)",
            coil.len(),
            t.len()
        );
        let file = format!("{name}.csv");
        let coil = (!coil.is_empty()).then_some(coil.as_slice());
        maglab_dataset::data::write_measurement(&dir.join(&file), &t, &i, &y, coil)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        info.files.insert(
            file,
            FileInfo {
                start_state: None,
                excitation: Some(description.clone()),
            },
        );
    }
    info.write(dir).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
