//! Fuzz targets as plain functions of a byte slice. Each must return normally for every input:
//! a panic (or an abort, a hang) is the bug the fuzzer looks for. The cargo-fuzz harness in
//! `fuzz/` (nightly, libFuzzer, `cargo xtask fuzz`) calls them; `tests/corpus_smoke.rs` replays
//! the kept corpus and seeded random inputs through them on stable, in `cargo xtask test`.
//!
//! | target | what it feeds |
//! | --- | --- |
//! | [`params_validator`] | any text to the parameter-file parser and validator |
//! | [`measurement_csv`] | any bytes as a measurement CSV file to the dataset reader |
//! | [`preisach_fit_input`] | any bytes as a `preisach-fit` CSV, with column names, row filter, initial state and unexcited option taken from the input |
//! | [`core_numerics`] | arbitrary f32 values (NaN, ±∞, subnormals included) to the core's forward update, exact inverse, solve, dynamic-model step, control command and DAC code |

use magctl::inverse::{ControlLoop, InverseKind, LoopState};
use magctl::model::DynamicModel;
use magctl::output::DacScale;
use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
use magctl::trajectory::DesiredMotion;
use std::io::Write;
use std::path::PathBuf;

/// The fuzz target names, in the order of the table above (corpus folders and harness binaries
/// carry these names).
pub const TARGETS: [&str; 4] = [
    "params_validator",
    "measurement_csv",
    "preisach_fit_input",
    "core_numerics",
];

/// Runs target `name` on `data`; false for an unknown name.
pub fn run(name: &str, data: &[u8]) -> bool {
    match name {
        "params_validator" => params_validator(data),
        "measurement_csv" => measurement_csv(data),
        "preisach_fit_input" => preisach_fit_input(data),
        "core_numerics" => core_numerics(data),
        _ => return false,
    }
    true
}

/// Any text to `ActuatorParams::parse` (which validates); an accepted file must also convert to
/// the core's f32 types and round-trip through its own JSON.
pub fn params_validator(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(p) = actuator_params::ActuatorParams::parse(&text, "fuzz.json") {
        let again = actuator_params::ActuatorParams::parse(&p.to_json_pretty(), "again.json");
        assert!(again.is_ok(), "a valid file must re-read: {again:?}");
    }
}

/// A scratch file for the readers that take a path (one per thread and process), removed with
/// its folder when dropped: a replay of the corpus writes thousands of inputs, and nothing of
/// them is worth keeping once the reader returned.
struct Scratch {
    path: PathBuf,
}

impl Scratch {
    fn new(name: &str, data: &[u8]) -> Self {
        let dir = std::env::temp_dir().join(format!("maglab-fuzz-{}", std::process::id()));
        let _ = std::fs::create_dir_all(&dir);
        let path =
            dir.join(format!("{:?}-{name}", std::thread::current().id()).replace(['(', ')'], ""));
        if let Ok(mut f) = std::fs::File::create(&path) {
            let _ = f.write_all(data);
        }
        Scratch { path }
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        // Fails while another thread's file is still there; the last one out removes it.
        if let Some(dir) = self.path.parent() {
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// Any bytes as one measurement file (`t_s,current_a,displacement_m`).
pub fn measurement_csv(data: &[u8]) {
    let scratch = Scratch::new("measurement.csv", data);
    let path = &scratch.path;
    if let Ok(m) = maglab_dataset::data::load_measurement(path) {
        assert_eq!(m.t_s.len(), m.current_a.len());
        assert!(m.step_s.is_finite() && m.step_s > 0.0, "step {}", m.step_s);
    }
}

/// Any bytes as a `preisach-fit` input: the first line of the input (up to 200 bytes) gives the
/// options (`input|output|group|filter|initial|unexcited`, `|`-separated), the rest is the CSV.
pub fn preisach_fit_input(data: &[u8]) {
    use maglab_identify::columns::{read_columns, ColumnSpec, RowFilter};
    let split = data.iter().take(200).position(|&b| b == b'\n').unwrap_or(0);
    let options = String::from_utf8_lossy(&data[..split]);
    let mut fields = options.split('|');
    let mut next = || fields.next().unwrap_or("").to_string();
    let (input, output, group, filter_text, initial, unexcited, lines) =
        (next(), next(), next(), next(), next(), next(), next());
    let _ = maglab_dataset::StartState::parse_among(
        &initial,
        &maglab_identify::memory::PREISACH_STARTS,
    );
    let _ = maglab_identify::fit::Unexcited::parse(&unexcited);
    let _ = maglab_identify::lines::LineChoice::parse(&lines);
    let filter = if filter_text.is_empty() {
        RowFilter::All
    } else {
        match RowFilter::parse(&filter_text) {
            Ok(f) => f,
            Err(_) => return,
        }
    };
    let spec = ColumnSpec {
        input,
        output,
        group: (!group.is_empty()).then_some(group),
        filter,
    };
    let scratch = Scratch::new("fit.csv", data.get(split + 1..).unwrap_or(&[]));
    let path = &scratch.path;
    if let Ok(table) = read_columns(path, &spec) {
        assert!(table.selected_rows() <= table.rows());
        // The line chooser on whatever the file holds: the grid over the data range (as
        // `preisach-fit` builds it) has finite, strictly increasing lines from h_min to h_max.
        let (lo, hi) = table.input_range();
        if lo.is_finite() && hi.is_finite() && lo < hi && (hi - lo).is_finite() {
            let range = maglab_identify::design::Grid::around(lo, hi, 0.02);
            let experiments: Vec<maglab_identify::design::Experiment<'_>> = table
                .series
                .iter()
                .map(|s| maglab_identify::design::Experiment {
                    label: &s.label,
                    input: &s.input,
                    output: &s.output,
                    selected: &s.selected,
                    initial: maglab_dataset::StartState::Periodic,
                    weights: None,
                })
                .collect();
            let grid = maglab_identify::lines::choose_grid(
                range.h_min,
                range.h_max,
                maglab_identify::lines::LineChoice::EqualOutput,
                &experiments,
            );
            let l = grid.lines();
            assert!(l.iter().all(|h| h.is_finite()), "{l:?}");
            assert!(
                l.windows(2).all(|w| w[0] < w[1]) || grid.lines.is_none(),
                "{l:?}"
            );
            assert_eq!((l[0], l[l.len() - 1]), (range.h_min, range.h_max));
        }
    }
}

/// Reads f32 values (little endian) from the input, cycling when it runs out.
struct Floats<'a> {
    data: &'a [u8],
    at: usize,
}

impl Floats<'_> {
    fn next(&mut self) -> f32 {
        if self.data.len() < 4 {
            return 0.0;
        }
        if self.at + 4 > self.data.len() {
            self.at = 0;
        }
        let mut b = [0u8; 4];
        b.copy_from_slice(&self.data[self.at..self.at + 4]);
        self.at += 4;
        f32::from_le_bytes(b)
    }
}

/// Grid lines over the baked range from 25 fuzz floats (interval widths `|x|` limited to
/// `[1e-3, 1e3]`, non-finite as 1, scaled to the range), or `None` when f32 rounding leaves two
/// lines equal (the parameter file's validation rejects that case).
fn fuzzed_lines(f: &mut Floats<'_>) -> Option<[f32; magctl::preisach::LEVELS + 1]> {
    use magctl::preisach::LEVELS;
    let p = &BAKED_PARAMETERS.preisach;
    let widths: Vec<f64> = (0..LEVELS)
        .map(|_| {
            let x = f.next() as f64;
            if x.is_finite() {
                x.abs().clamp(1e-3, 1e3)
            } else {
                1.0
            }
        })
        .collect();
    let total: f64 = widths.iter().sum();
    let (lo, hi) = (p.h_min_a_per_m as f64, p.h_max_a_per_m as f64);
    let mut lines = [0.0f32; LEVELS + 1];
    let mut acc = 0.0;
    for k in 0..=LEVELS {
        lines[k] = (lo + (hi - lo) * acc / total) as f32;
        if k < LEVELS {
            acc += widths[k];
        }
    }
    lines[0] = p.h_min_a_per_m;
    lines[LEVELS] = p.h_max_a_per_m;
    lines.windows(2).all(|w| w[0] < w[1]).then_some(lines)
}

/// Arbitrary f32 inputs to the core's update paths; checks they stay total and bounded. An input
/// whose first byte is odd runs on a grid with fuzzed lines instead of the baked one.
pub fn core_numerics(data: &[u8]) {
    let lined;
    let m = if data.first().is_some_and(|b| b & 1 == 1) {
        let mut f = Floats { data, at: 0 };
        match fuzzed_lines(&mut f) {
            Some(lines) => {
                lined = magctl::preisach::PreisachMeasure::with_lines(
                    &BAKED_PARAMETERS.preisach.weights_a_per_m,
                    &lines,
                );
                &lined
            }
            None => &BAKED_MEASURE,
        }
    } else {
        &BAKED_MEASURE
    };
    let ms = m.saturation_a_per_m();
    let bound = ms * (1.0 + 1e-5) + 1.0;
    let mut f = Floats { data, at: 0 };
    let steps = (data.len() / 4).min(256);
    let mut state = m.demagnetized::<64>();
    let step_s = 1.0 / BAKED_PARAMETERS.control.sample_rate_hz;
    let model = DynamicModel::new(m, &BAKED_PARAMETERS.actuator, step_s);
    let mut plant = model.equilibrium::<64>(m.demagnetized(), 0.0);
    let control = ControlLoop::new(m, &BAKED_PARAMETERS).expect("baked parameters are valid");
    let mut loop_state: LoopState<64> = control.init(InverseKind::Dynamic);
    let dac = DacScale::new(BAKED_PARAMETERS.control.current_limit_a).expect("valid limit");
    for _ in 0..steps {
        let x = f.next();
        match m.apply(&mut state, x) {
            Ok(out) => assert!(out.is_finite() && out.abs() <= bound, "apply({x}) = {out}"),
            Err(_) => assert!(!x.is_finite()),
        }
        let target = f.next();
        if let Ok(s) = m.invert(&mut state, target) {
            assert!(
                s.m_a_per_m.abs() <= bound && s.h_a_per_m.is_finite(),
                "{s:?}"
            );
        }
        let (a, r) = (f.next(), f.next());
        if let Ok(s) = m.solve(&mut state, a, r) {
            assert!(s.m_a_per_m.abs() <= bound, "solve({a}, {r}) = {s:?}");
        }
        let current = f.next();
        let out = model.step(&mut plant, current);
        let _ = out;
        let desired = DesiredMotion {
            displacement_m: f.next(),
            velocity_m_per_s: f.next(),
            acceleration_m_per_s2: f.next(),
        };
        let tick = control.command_with_fast(InverseKind::Dynamic, &mut loop_state, &desired);
        let limit = BAKED_PARAMETERS.control.current_limit_a;
        assert!(
            tick.current_a.is_finite() && tick.current_a.abs() <= limit,
            "command {} for {desired:?}",
            tick.current_a
        );
        let _ = dac.code(f.next());
    }
}
