//! One virtual-bench run's settings ([`HilRun`], with the fault it injects and the board it
//! runs on) and what it produced ([`HilResult`]).

use super::Programme;
use anyhow::{bail, Context, Result};
use magctl::link::CommandFrame;
use std::path::PathBuf;
use std::sync::Arc;

/// A fault the bridge injects into the plant → firmware stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Inject {
    /// The sample of this tick becomes NaN metres.
    Nan(u32),
    /// The sample of this tick becomes an ADC count beyond the converter's range.
    Range(u32),
    /// No sample is forwarded from this tick on.
    Silent(u32),
    /// This tick's frame gets a wrong sync byte.
    Garbage(u32),
}

impl Inject {
    pub(super) fn parse(text: &str) -> Result<Self> {
        let (kind, at) = text
            .split_once('@')
            .with_context(|| format!("--inject `{text}`: expected KIND@TICK"))?;
        let at: u32 = at
            .parse()
            .with_context(|| format!("--inject `{text}`: tick `{at}` is not a number"))?;
        Ok(match kind {
            "nan" => Inject::Nan(at),
            "range" => Inject::Range(at),
            "silent" => Inject::Silent(at),
            "garbage" => Inject::Garbage(at),
            k => bail!("--inject `{text}`: unknown kind `{k}` (nan, range, silent, garbage)"),
        })
    }
}

/// Which firmware image and QEMU machine run the bench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Board {
    /// `firmware-hil` on `mps2-an386` (the plant link on UART0; instruction counts exact).
    Mps2,
    /// The NUCLEO image (`firmware-nucleo`, its emulator build) on `netduinoplus2`: the board's
    /// TIM2, SPI1, watchdog and start-up code, the plant link on USART2 (docs/firmware.md).
    Nucleo,
}

/// One run's settings.
#[derive(Debug, Clone)]
pub struct HilRun {
    /// The image and machine.
    pub board: Board,
    /// NUCLEO image only: poll the clock flags after the HSE's as on the chip (`clocks=board`;
    /// the emulator never sets them: the start-up halts at 0 A, exit 9).
    pub board_clock_flags: bool,
    /// External plant command (`sh -c`), or the default plant.
    pub plant_cmd: Option<String>,
    /// Effects of the default plant.
    pub effects: Vec<String>,
    /// Sensor noise of the default plant, m.
    pub noise_m: Option<f64>,
    /// Random prior history levels of the default plant.
    pub prior_history: usize,
    /// Seed of the default plant (noise, prior history).
    pub seed: u64,
    /// Control ticks.
    pub ticks: u32,
    /// `static` or `dynamic`.
    pub inverse: String,
    /// Injected fault.
    pub inject: Option<Inject>,
    /// Expected firmware exit status.
    pub expect_exit: i32,
    /// Run the firmware's start-up conditioning (default).
    pub conditioning: bool,
    /// Run the parameter file's displacement feedback (default); `false` passes `feedback=off`.
    pub feedback: bool,
    /// Parameter file of the default plant (default: the baked parameters).
    pub plant_params: Option<PathBuf>,
    /// The default plant's own rod (`maglab hil-plant --rod FAMILY:FACTOR`): a Preisach measure
    /// on the plant's grid instead of the file's.
    pub plant_rod: Option<String>,
    /// The default plant's current monitor (`maglab hil-plant --coil-current-noise-a`): every
    /// sample frame carries the coil current (link version 2), and a measurement's dataset has
    /// the `coil_current_a` column.
    pub plant_coil_current_noise_a: Option<f64>,
    /// Measurement mode: the programme to stream and where to write the dataset folder.
    pub measure: Option<(Arc<Programme>, PathBuf)>,
    /// Streamed measurement of only the programme's first ticks (no dataset written).
    pub measure_ticks: Option<u32>,
    /// Local measurement (`mode=measure-local`): the firmware plays its compiled-in programme
    /// and logs the record (`MEAS` lines), which is checked against the link and written here.
    pub measure_local: Option<PathBuf>,
    /// Firmware ELF to run instead of the default build (e.g. one baked with identified
    /// parameters).
    pub elf: Option<PathBuf>,
    /// Output directory.
    pub out: PathBuf,
}

impl HilRun {
    /// Default settings writing into `out`.
    pub fn new(out: PathBuf) -> Self {
        HilRun {
            board: Board::Mps2,
            board_clock_flags: false,
            plant_cmd: None,
            effects: Vec::new(),
            noise_m: None,
            prior_history: 0,
            seed: 1,
            ticks: 10_000,
            inverse: "dynamic".into(),
            inject: None,
            expect_exit: 0,
            conditioning: true,
            feedback: true,
            plant_params: None,
            plant_rod: None,
            plant_coil_current_noise_a: None,
            measure: None,
            measure_ticks: None,
            measure_local: None,
            elf: None,
            out,
        }
    }
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct HilResult {
    /// Command frames received.
    pub commands: usize,
    /// Tracking RMS and max error, % of the desired peak-to-peak, and what it was measured on.
    pub tracking: Option<(f64, f64, &'static str)>,
    /// Wall time of the QEMU run, s.
    pub wall_s: f64,
    /// The summary text.
    pub summary: String,
    /// The command frames, in tick order.
    pub frames: Vec<CommandFrame>,
    /// The tracking interrupts' instructions: min, median, max.
    pub instructions: (f64, f64, f64),
}
