//! `maglab hil-plant`: the bench plant as a plant program of the virtual bench — it speaks the
//! lock-step link of `docs/hil.md` on stdin (command frames from the firmware) and stdout (sensor
//! frames to it). `cargo xtask hil` runs it as the default plant; any other program speaking the
//! same frames can stand in (`--plant-cmd`).
//!
//! The plant is `maglab-plant` (its own f64 Preisach evaluation and RK4 integrator, effects as in
//! `maglab rig --effect`); each command is held over one control period (a DAC with a zero-order
//! hold). The sensor sample of tick `k` is the plant's sensor output at `t_k − sample_delay_s` (the
//! parameter file's `sensor` section; plus its own dynamics and delay when a sensor effect is on)
//! plus white noise, quantized to the ADC count of the parameter
//! file's `sensor` section (or sent in metres with `--metres`).
//!
//! `--coil-current-noise-a A` makes it a bench with a current monitor as well: every sample
//! frame carries the coil current at the sample's instant (the amplifier's output, with that
//! white noise) in link version 2's `T`/`U` frames (`docs/hil.md`).
//!
//! `--log FILE` writes one row per tick: `tick,t_s,current_a,desired_m,y_m,sample_m,count,flags,
//! instructions` (`y_m`: the rod's true displacement at the end of the tick's period, what the
//! command's `desired_m` aims at; `sample_m`: the reading sent at the start of the period).

use crate::params_io;
use anyhow::{bail, Context, Result};
use clap::Args as ClapArgs;
use magctl::link::{
    CommandFrame, Sample, SampleFrame, COMMAND_FRAME_BYTES, KIND_BEGIN, KIND_COMMAND, KIND_END,
};
use magctl::sensor::SensorScale;
use maglab_dataset::StartState;

/// The rod's state before the firmware starts (`--start`): it then conditions the rod itself.
const HIL_STARTS: [StartState; 3] = [
    StartState::NegativeSaturation,
    StartState::PositiveSaturation,
    StartState::Demagnetized,
];
use maglab_plant::{Effect, Plant, Rod};
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::io::{Read, Write};
use std::path::PathBuf;

/// Arguments of `maglab hil-plant`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The plant's parameter file (default: the parameters baked into this build).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// An effect of the plant, `name` or `name:key=value,...` (repeatable; `maglab rig
    /// --list-effects`).
    #[arg(long = "effect")]
    pub effects: Vec<String>,
    /// The rod's own Preisach measure instead of the parameter file's: `FAMILY:FACTOR[:C:S]`
    /// (gaussian, lognormal, bimodal, skewed; the plane FACTOR times wider than the coil reaches
    /// at the current limit; coercivity C ± S kA/m; `maglab_plant::rods`).
    #[arg(long, value_name = "FAMILY:FACTOR")]
    pub rod: Option<String>,
    /// White sensor noise (standard deviation), m.
    #[arg(long, default_value_t = 0.05e-6)]
    pub noise_m: f64,
    /// Seed of the noise and of `--prior-history`.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The plant's magnetic state before the first tick: negative-saturation,
    /// positive-saturation, demagnetized (all at rest at 0 A).
    #[arg(long, default_value = "negative-saturation")]
    pub start: String,
    /// Before the run, drive the plant through this many random current levels (each held
    /// 5 ms, within ±the current limit) and back to 0 A: an unknown prior history.
    #[arg(long, default_value_t = 0)]
    pub prior_history: usize,
    /// Send displacements in metres (`M` frames) instead of ADC counts (`S` frames).
    #[arg(long)]
    pub metres: bool,
    /// Also send the coil current a current monitor reads on the sample's trigger, with this
    /// white noise (standard deviation), A: link version 2's `T` (counts) or `U` (metres)
    /// frames.
    #[arg(long, value_name = "A")]
    pub coil_current_noise_a: Option<f64>,
    /// Write the per-tick log here (CSV).
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
}

fn read_frame(input: &mut impl Read) -> Result<Option<CommandFrame>> {
    let mut b = [0u8; COMMAND_FRAME_BYTES];
    let mut got = 0;
    while got < b.len() {
        match input.read(&mut b[got..]) {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => bail!("the link closed inside a frame ({got} of {COMMAND_FRAME_BYTES} bytes)"),
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e).context("reading the link"),
        }
    }
    CommandFrame::decode(&b)
        .map(Some)
        .map_err(|e| anyhow::anyhow!("bad command frame {b:02x?}: {e:?}"))
}

/// The run's plant effects and start state, parsed, and its noise levels checked: every
/// argument is checked before the link is read.
fn checked_arguments(args: &Args) -> Result<(Vec<Effect>, StartState)> {
    let effects = args
        .effects
        .iter()
        .map(|t| Effect::parse(t).map_err(|e| anyhow::anyhow!("--effect {t}: {e}")))
        .collect::<Result<Vec<_>>>()?;
    if !(args.noise_m.is_finite() && args.noise_m >= 0.0) {
        bail!("--noise-m must be >= 0, got {}", args.noise_m);
    }
    if let Some(n) = args.coil_current_noise_a {
        if !(n.is_finite() && n >= 0.0) {
            bail!("--coil-current-noise-a must be >= 0, got {n}");
        }
    }
    let start = StartState::parse_among(&args.start, &HIL_STARTS)
        .map_err(|e| anyhow::anyhow!("--start: {e}"))?;
    Ok((effects, start))
}

/// Waits for the firmware's B frame: `(tick rate, Hz; ticks of the run)`.
fn await_begin(input: &mut impl Read) -> Result<(f64, u32)> {
    let Some(begin) = read_frame(input)? else {
        bail!("the link closed before the firmware's B frame");
    };
    if begin.kind != KIND_BEGIN {
        bail!(
            "expected a B frame first, got kind {:?}",
            begin.kind as char
        );
    }
    Ok((begin.value as f64, begin.aux32))
}

/// The plant of `args` (`--rod`) at `rate_hz` started in `start`, driven through
/// `--prior-history` random levels when asked (drawn from `rng`).
fn started_plant(
    args: &Args,
    loaded: &params_io::LoadedParams,
    (effects, start): (&[Effect], StartState),
    rate_hz: f64,
    rng: &mut rand::rngs::StdRng,
) -> Result<Plant> {
    let mut plant = match &args.rod {
        Some(text) => {
            let rod = Rod::parse(text).map_err(|e| anyhow::anyhow!("--rod: {e}"))?;
            Plant::with_rod(&loaded.file, &rod, effects, rate_hz)
        }
        None => Plant::new(&loaded.file, effects, rate_hz),
    }
    .map_err(|e| anyhow::anyhow!(e))?;
    plant.start(start, 0.0).map_err(|e| anyhow::anyhow!(e))?;
    if args.prior_history > 0 {
        let limit_a = loaded.params.control.current_limit_a as f64;
        let hold = (0.005 * rate_hz).ceil() as usize;
        for _ in 0..args.prior_history {
            let i = rng.random_range(-limit_a..=limit_a);
            for _ in 0..hold {
                plant.advance(i, i);
            }
            plant.trim_history(0.01);
        }
        for _ in 0..4 * hold {
            plant.advance(0.0, 0.0);
        }
        plant
            .start(StartState::Previous, 0.0)
            .map_err(|e| anyhow::anyhow!(e))?;
    }
    Ok(plant)
}

/// The bench's instruments: the displacement sensor (the file's conversion delay, white noise,
/// the ADC's counts or metres) and, with `--coil-current-noise-a`, the current monitor.
struct Instruments {
    scale: SensorScale,
    delay_s: f64,
    /// The sensor's noise σ, m.
    sensor_noise_m: f64,
    sensor_noise: Normal<f64>,
    /// The sensor noise's stream: `--seed`'s, after `--prior-history` drew from it.
    sensor_rng: rand::rngs::StdRng,
    metres: bool,
    /// The monitor's noise σ, A (`None`: no monitor).
    monitor_noise_a: Option<f64>,
    monitor_noise: Normal<f64>,
    /// The monitor's noise comes from a stream of its own, so that the displacement noise
    /// stays that of a run without the monitor.
    monitor_rng: rand::rngs::StdRng,
}

impl Instruments {
    /// The instruments of `args`; `sensor_rng` the stream of the sensor's noise.
    fn new(
        args: &Args,
        loaded: &params_io::LoadedParams,
        sensor_rng: rand::rngs::StdRng,
    ) -> Result<Self> {
        Ok(Self {
            scale: SensorScale::new(&loaded.params.sensor),
            delay_s: loaded.file.sensor.sample_delay_s,
            sensor_noise_m: args.noise_m,
            sensor_noise: Normal::new(0.0, args.noise_m.max(f64::MIN_POSITIVE))
                .map_err(|e| anyhow::anyhow!("noise: {e}"))?,
            sensor_rng,
            metres: args.metres,
            monitor_noise_a: args.coil_current_noise_a,
            monitor_noise: Normal::new(
                0.0,
                args.coil_current_noise_a
                    .unwrap_or(0.0)
                    .max(f64::MIN_POSITIVE),
            )
            .map_err(|e| anyhow::anyhow!("coil current noise: {e}"))?,
            monitor_rng: rand::rngs::StdRng::seed_from_u64(args.seed ^ 0xc011_c0de),
        })
    }

    /// The sensor's reading now: `(the frame's sample, the reading in m, its ADC count)`.
    fn sample(&mut self, plant: &Plant) -> (Sample, f64, u32) {
        let mut y = plant.sensor_at(plant.time_s() - self.delay_s);
        if self.sensor_noise_m > 0.0 {
            y += self.sensor_noise.sample(&mut self.sensor_rng);
        }
        if self.metres {
            (Sample::Metres(y as f32), y, 0)
        } else {
            let count = self.scale.count_of(y as f32);
            (Sample::Count(count), y, count)
        }
    }

    /// The current monitor's reading now: the coil current at the sample's instant with the
    /// monitor's noise.
    fn coil_current_a(&mut self, plant: &Plant) -> Option<f32> {
        let noise_a = self.monitor_noise_a?;
        let i = plant.coil_current_at(plant.time_s());
        let noise = if noise_a > 0.0 {
            self.monitor_noise.sample(&mut self.monitor_rng)
        } else {
            0.0
        };
        Some((i + noise) as f32)
    }
}

/// `--log`'s writer, its header written.
fn open_log(path: Option<&std::path::Path>) -> Result<Option<std::io::BufWriter<std::fs::File>>> {
    let Some(path) = path else {
        return Ok(None);
    };
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?,
    );
    writeln!(
        f,
        "tick,t_s,current_a,desired_m,y_m,sample_m,count,flags,instructions"
    )?;
    Ok(Some(f))
}

/// Writes one sample frame.
fn send(
    output: &mut impl Write,
    seq: u32,
    sample: Sample,
    coil_current_a: Option<f32>,
) -> Result<()> {
    let frame = SampleFrame {
        seq: seq as u16,
        sample,
        coil_current_a,
    };
    output.write_all(frame.encode().as_slice())?;
    output.flush()?;
    Ok(())
}

/// Runs the plant program: the B frame, then per command frame one control period of the
/// plant and the next sample frame, until the E frame.
pub fn run(args: &Args) -> Result<()> {
    let (effects, start) = checked_arguments(args)?;
    let loaded = params_io::load(args.params.as_deref())?;
    let mut input = std::io::stdin().lock();
    let mut output = std::io::stdout().lock();
    let (rate_hz, ticks) = await_begin(&mut input)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(args.seed);
    let mut plant = started_plant(args, &loaded, (&effects, start), rate_hz, &mut rng)?;
    let mut instruments = Instruments::new(args, &loaded, rng)?;
    let mut log = open_log(args.log.as_deref())?;
    let (mut sample, mut sample_m, mut count) = instruments.sample(&plant);
    send(&mut output, 0, sample, instruments.coil_current_a(&plant))?;
    let mut tick: u32 = 0;
    loop {
        let Some(frame) = read_frame(&mut input)? else {
            bail!("the link closed at tick {tick} without an E frame");
        };
        match frame.kind {
            KIND_END => {
                eprintln!(
                    "hil-plant: E frame after {tick} ticks, firmware status {}",
                    frame.aux
                );
                break;
            }
            KIND_COMMAND => {}
            k => bail!("unexpected frame kind {:?} at tick {tick}", k as char),
        }
        if frame.seq != tick as u16 {
            bail!(
                "command frame out of sequence: expected {}, got {}",
                tick as u16,
                frame.seq
            );
        }
        let i = frame.value as f64;
        if !i.is_finite() {
            bail!("non-finite current command at tick {tick}");
        }
        plant.advance(i, i);
        plant.trim_history(0.01);
        if let Some(f) = log.as_mut() {
            writeln!(
                f,
                "{tick},{:.7},{:e},{:e},{:e},{:e},{count},{},{}",
                tick as f64 / rate_hz,
                frame.value,
                frame.desired_m,
                plant.displacement_m(),
                sample_m,
                frame.flags,
                frame.aux
            )?;
        }
        tick += 1;
        (sample, sample_m, count) = instruments.sample(&plant);
        if tick < ticks {
            send(
                &mut output,
                tick,
                sample,
                instruments.coil_current_a(&plant),
            )?;
        }
    }
    if let Some(mut f) = log {
        f.flush()?;
    }
    Ok(())
}
