//! Control firmware for the NUCLEO-F446RE (STM32F446RE, Cortex-M4F at 180 MHz).
//!
//! TIM2's update interrupt fires at the JSON's control rate (`control.sample_rate_hz`, 10 kHz by
//! default), reads the displacement sensor (ADC1 on PA0/A0, scaled and checked by the `sensor`
//! section; a bad or missing sample latches a sensor fault and ramps the coil to 0 A) and runs
//! one control step — Van der Pol trajectory → dynamic inverse → output limiter
//! — with the same `magctl::inverse::ControlLoop` as the QEMU firmware and the host, then writes
//! the current command to the SPI DAC (`magctl::output::SpiDac` over embedded-hal, SPI1 + PB6
//! chip select; wiring in `magctl::board::nucleo_f446re`), then feeds the independent watchdog.
//! Thread mode logs a status line over RTT (defmt) once per second of control time: interrupts
//! run, cycles per interrupt (DWT cycle counter, min / max), overruns, limiter and fault
//! counters, SPI timeouts, staircase merges.
//!
//! Start-up (`docs/safety.md`): the DAC powers up at 0 A; the first thing `main` does is write 0 A
//! again on the reset clock (a reset does not reset the DAC), then it starts the watchdog with
//! its start-up timeout (2.8–7.7 s), brings up the clocks with every wait bounded (the internal
//! oscillator when the HSE does not come up; a PLL that does not lock halts at 0 A), ramps to the
//! controller's initial current at the slew limit, shortens the watchdog to its run timeout and
//! hands the state to the interrupt.
//!
//! **Measurement image** (feature `measurement-mode`, `cargo xtask nucleo` builds it as
//! `out/nucleo/firmware-nucleo-measure.elf`): instead of tracking, the interrupt plays the
//! compiled-in identification programme (`magctl::programme`: conditioning, FORC sweep, biased
//! sines) through the output limiter and records every tick — applied current, sensor reading
//! (checked only against the ADC's range), flags — into a bounded queue (`magctl::record`);
//! thread mode logs the batches over RTT when they fit (`MEAS …` lines, never truncated), and
//! `cargo xtask record` turns probe-rs's output into the dataset folder `maglab identify` reads.
//! If the probe does not drain the record fast enough the queue fills, the tick is counted as
//! lost and the programme ends at 0 A (`MEAS-END` reports it; the recorder refuses an
//! incomplete record). After the programme the coil ramps to 0 A and stays there.
//!
//! Flash and run with probe-rs (`probe-rs run --chip STM32F446RETx <elf>`, docs/firmware.md); the
//! fatal paths (panic, HardFault, unexpected interrupt) command 0 A and halt at a breakpoint
//! (`magctl::board::nucleo_f446re::fatal`).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "firmware-nucleo is Cortex-M firmware: build it with `--target thumbv7em-none-eabihf \
         --features board-nucleo-f446re`"
    );
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod firmware {
    use core::sync::atomic::{AtomicU32, Ordering};
    use cortex_m::peripheral::DWT;
    use embedded_hal_bus::spi::{ExclusiveDevice, NoDelay};
    use magctl::board::handoff::HandOff;
    use magctl::board::nucleo_f446re::adc::DisplacementAdc;
    use magctl::board::nucleo_f446re::spi::{ChipSelect, Spi1};
    use magctl::board::nucleo_f446re::timer::ControlTimer;
    use magctl::board::nucleo_f446re::watchdog::{self, Watchdog};
    use magctl::board::nucleo_f446re::{clocks, rtt, spi};
    use magctl::inverse::{CommandFlags, ControlLoop, InverseKind, LoopState};
    use magctl::output::{CurrentOutput, DacScale, SpiDac};
    use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
    #[cfg(feature = "measurement-mode")]
    use magctl::record::{RecordDrain, RecordQueue, Recorder};
    use stm32f4::stm32f446::{self as pac, interrupt, Interrupt};

    /// Preisach memory capacity (reversal points) of the controller.
    const CAPACITY: usize = magctl::preisach::DEFAULT_CAPACITY;
    /// The inverse the interrupt runs (the paper's Figure 7 controller; `InverseKind::Static`
    /// gives the Figure 8 baseline).
    const INVERSE: InverseKind = InverseKind::Dynamic;

    /// Consecutive DAC writes that may time out before the interrupt stops feeding the
    /// watchdog (1 ms at 10 kHz): a DAC that cannot be written leaves the coil at its last
    /// current, so the chip resets into the 0 A start-up instead.
    const DAC_TIMEOUTS_BEFORE_RESET: u32 = 10;
    /// Bound on the start-up ramp's steps (0.1 s at 10 kHz).
    const MAX_RAMP_STEPS: u32 = 1_000;

    type Dac = SpiDac<ExclusiveDevice<Spi1, ChipSelect, NoDelay>>;

    struct App {
        control: ControlLoop<'static>,
        state: LoopState<CAPACITY>,
        dac: Dac,
        timer: ControlTimer,
        adc: DisplacementAdc,
        watchdog: Watchdog,
        consecutive_dac_timeouts: u32,
        /// Measurement image: the programme being played and the record's producer.
        #[cfg(feature = "measurement-mode")]
        recorder: Recorder<'static>,
    }

    /// The interrupt's state, handed over by `main` before TIM2 is unmasked.
    static APP: HandOff<App> = HandOff::new();

    /// Interrupts run.
    static TICKS: AtomicU32 = AtomicU32::new(0);
    /// Interrupts that ended after the next timer update was already pending.
    static OVERRUNS: AtomicU32 = AtomicU32::new(0);
    /// DAC writes that timed out (SPI controller not ready within its poll bound).
    static SPI_TIMEOUTS: AtomicU32 = AtomicU32::new(0);
    /// Staircase merges of the controller's Preisach memory (mirrored each interrupt).
    static MERGES: AtomicU32 = AtomicU32::new(0);
    /// Rejected sensor samples (the first latches the fault; mirrored each interrupt).
    static SENSOR_FAULTS: AtomicU32 = AtomicU32::new(0);
    /// Measurement image: ticks that did not fit into the record queue, and whether the
    /// programme has ended (mirrored each interrupt).
    #[cfg(feature = "measurement-mode")]
    static RECORD_LOST: AtomicU32 = AtomicU32::new(0);
    #[cfg(feature = "measurement-mode")]
    static RECORD_ENDED: core::sync::atomic::AtomicBool =
        core::sync::atomic::AtomicBool::new(false);
    /// Fewest / most core cycles spent in one interrupt (DWT).
    static MIN_CYCLES: AtomicU32 = AtomicU32::new(u32::MAX);
    static MAX_CYCLES: AtomicU32 = AtomicU32::new(0);
    /// Limiter counters mirrored for thread mode (the loop's own counters live in `APP`).
    static FLAGGED: [AtomicU32; 4] = [
        AtomicU32::new(0),
        AtomicU32::new(0),
        AtomicU32::new(0),
        AtomicU32::new(0),
    ];

    /// The control interrupt (TIM2 update, at `control.sample_rate_hz`).
    ///
    /// **Deadline**: the next TIM2 update, one control period (100 µs at 10 kHz = 18,000 cycles)
    /// after this one; the DAC frame is sent inside the handler, so the new current is on the
    /// coil within the handler's run time of the period's start (jitter = run-time variation).
    /// **Overrun**: detected at the end of the handler when TIM2's update flag is already set
    /// again; counted ([`OVERRUNS`], logged every second). The pending interrupt then runs at
    /// once (late, no step skipped).
    /// **Work**: one `ControlLoop::tick_sensed` with the displacement feedback (the virtual bench
    /// measures it with the sensor read and the DAC frame: BENCHMARKS.md, 1,071 instructions
    /// median and 1,386 worst case on the robustness matrix, far inside the 18,000-cycle period), one 24-bit SPI frame (2.1 µs at 11.25 MHz; every status wait bounded by
    /// `polled_spi::MAX_STATUS_POLLS`, a timeout is counted), the watchdog feed, counter updates.
    /// No allocation, no logging, no unbounded wait, no panic path (link-time proof with
    /// `--features panic-never`).
    /// **Watchdog**: fed at the end of every interrupt unless the DAC has timed out
    /// [`DAC_TIMEOUTS_BEFORE_RESET`] times in a row; a stalled or starved interrupt resets the
    /// chip within `watchdog::TIMEOUT_MAX_MS`.
    #[interrupt]
    fn TIM2() {
        let entry = DWT::cycle_count();
        // SAFETY: this interrupt is APP's only user once TIM2 is unmasked.
        let Some(app) = (unsafe { APP.get_mut() }) else {
            return;
        };
        app.timer.clear();
        // The sensor sample of this period (bounded wait), scaled and checked; a missing sample
        // latches the sensor fault and the command ramps to 0 A; a bad one (out of range,
        // stuck) makes the loop fall back to the feedforward alone (feedback on) or ramps to 0 A
        // (feedback off).
        #[cfg(not(feature = "measurement-mode"))]
        let out = {
            let sample = app
                .adc
                .sample()
                .and_then(|count| app.control.sensor().displacement_m(count));
            app.control.tick_sensed(INVERSE, &mut app.state, sample)
        };
        // Measurement image: the programme's current; the reading is checked only against the
        // ADC's range (identification drives the rod over its whole stroke).
        #[cfg(feature = "measurement-mode")]
        let out = {
            let reading = app
                .adc
                .sample()
                .and_then(|count| app.control.sensor().reading_m(count));
            let out = app.recorder.tick(&app.control, &mut app.state, reading);
            RECORD_LOST.store(app.recorder.lost(), Ordering::Relaxed);
            RECORD_ENDED.store(app.recorder.ended(), Ordering::Release);
            out
        };
        SENSOR_FAULTS.store(app.state.core.counters.sensor_faults, Ordering::Relaxed);
        if app.dac.write_current(out.current_a).is_err() {
            SPI_TIMEOUTS.fetch_add(1, Ordering::Relaxed);
            app.consecutive_dac_timeouts = app.consecutive_dac_timeouts.saturating_add(1);
        } else {
            app.consecutive_dac_timeouts = 0;
        }
        if app.consecutive_dac_timeouts < DAC_TIMEOUTS_BEFORE_RESET {
            app.watchdog.feed();
        }
        MERGES.store(app.state.merges(), Ordering::Relaxed);
        #[cfg(feature = "panic-never-canary")]
        {
            // Negative control of the link-time proof: a bounds check the optimizer cannot remove.
            let table = [0u32; 4];
            TICKS.fetch_add(table[(out.flags.0 % 5) as usize], Ordering::Relaxed);
        }
        for (bit, counter) in [
            CommandFlags::U_CLAMPED,
            CommandFlags::CURRENT_LIMITED,
            CommandFlags::SLEW_LIMITED,
            CommandFlags::FAULT,
        ]
        .iter()
        .zip(FLAGGED.iter())
        {
            if out.flags.has(*bit) {
                counter.fetch_add(1, Ordering::Relaxed);
            }
        }
        if app.timer.pending() {
            OVERRUNS.fetch_add(1, Ordering::Relaxed);
        }
        let cycles = DWT::cycle_count().wrapping_sub(entry);
        MIN_CYCLES.fetch_min(cycles, Ordering::Relaxed);
        MAX_CYCLES.fetch_max(cycles, Ordering::Relaxed);
        TICKS.fetch_add(1, Ordering::Relaxed);
    }

    /// Logs the ready batches of the record while they fit in the RTT ring (a batch that does
    /// not fit waits in the drain for the probe; the queue behind it keeps filling).
    #[cfg(feature = "measurement-mode")]
    fn log_batches(drain: &mut RecordDrain<'static>, flush: bool) {
        /// A batch's frame, worst case (header, payload, rzCOBS overhead, delimiter).
        const FRAME_BYTES_MAX: usize = 256;
        magctl::record::log::batches(drain, flush, || rtt::free_bytes() >= FRAME_BYTES_MAX);
    }

    /// Start-up steps 1–3 of `docs/safety.md`: 0 A to the DAC on the reset clock, the watchdog
    /// with its start-up timeout, the clocks with every wait bounded. Halts (0 A written) on a
    /// failure.
    fn start_safely(cp: &mut cortex_m::Peripherals, dp: &pac::Peripherals) -> (Dac, Watchdog) {
        let p = &BAKED_PARAMETERS;
        // 0 A before anything else, on the reset clock (the DAC keeps its code through an MCU
        // reset, a watchdog reset included); SPI1 just runs slower until the PLL is up.
        let Some(scale) = DacScale::new(p.control.current_limit_a) else {
            halt("invalid control.current_limit_a")
        };
        let (spi, cs) = spi::init(&dp.RCC);
        let Ok(device) = ExclusiveDevice::new_no_delay(spi, cs);
        let mut dac = SpiDac::new(device, scale);
        if dac.write_current(0.0).is_err() {
            halt("the DAC cannot be written (SPI timeout)");
        }
        // Then the watchdog, with its start-up timeout, before anything that can stall.
        let reset_by_watchdog = watchdog::take_reset_was_watchdog(&dp.RCC);
        let (watchdog, boot_configured) = Watchdog::start_for_boot(&dp.DBGMCU);
        match clocks::init(&dp.RCC, &dp.PWR, &dp.FLASH, || watchdog.feed()) {
            Ok(clocks::ClockSource::Hse) => {}
            Ok(clocks::ClockSource::Hsi) => defmt::warn!(
                "the 8 MHz HSE did not come up: running from the internal HSI (control rate within its 1 %)"
            ),
            Err(e) => halt(e.describe()),
        }
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        if reset_by_watchdog {
            defmt::warn!("reset by the independent watchdog: the control loop had stalled");
        }
        if !boot_configured {
            defmt::warn!(
                "watchdog start-up timeout not applied: running with its 512 ms reset timeout"
            );
        }
        (dac, watchdog)
    }

    fn halt(reason: &str) -> ! {
        defmt::error!("start-up failed: {=str}", reason);
        loop {
            cortex_m::asm::bkpt();
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take())
        else {
            halt("peripherals already taken")
        };
        let p = &BAKED_PARAMETERS;
        let (mut dac, watchdog) = start_safely(&mut cp, &dp);

        defmt::info!(
            "magctl firmware on NUCLEO-F446RE: {=u32} Hz core, control rate {=f32} Hz, Van der Pol mu {=f32}, {=f32} Hz scale",
            clocks::SYSCLK_HZ,
            p.control.sample_rate_hz,
            p.trajectory.van_der_pol_mu,
            p.trajectory.frequency_scale_hz
        );
        let control = match ControlLoop::new(&BAKED_MEASURE, p) {
            Ok(c) => c,
            Err(_) => halt("invalid control settings in the baked parameters"),
        };
        let state = control.init::<CAPACITY>(INVERSE);
        #[cfg(feature = "measurement-mode")]
        let (recorder, mut drain) = {
            let Ok(programme) = magctl::programme::IdentificationProgramme::new(
                control.limiter(),
                p.actuator.coil_factor_per_m,
                &BAKED_MEASURE,
                p.preisach.reach_a_per_m,
                p.control.sample_rate_hz,
            ) else {
                halt("the identification programme cannot run with the baked parameters")
            };
            let Some(queue) = cortex_m::singleton!(: RecordQueue = RecordQueue::new()) else {
                halt("record queue taken twice")
            };
            let (producer, consumer) = queue.split();
            magctl::record::log::programme(&programme, p.control.sample_rate_hz);
            (
                Recorder::new(programme, producer),
                RecordDrain::new(consumer),
            )
        };
        // The measurement programme starts from 0 A with its own conditioning: no ramp.
        #[cfg(feature = "measurement-mode")]
        let state = {
            let mut state = state;
            state.core.last_current_a = 0.0;
            state
        };
        let rate_hz = p.control.sample_rate_hz as u32;
        // Ramp from 0 A to the controller's initial current (the static current of the first
        // sample) at the slew limit, one step per control period (at most
        // I_max / (slew / rate) steps: 5 with the default file).
        let step_a = p.control.current_slew_limit_a_per_s / p.control.sample_rate_hz;
        let period_cycles = clocks::SYSCLK_HZ / rate_hz.max(1);
        let target_a = state.core.last_current_a;
        // Equal steps of at most `step_a`; `as u32` saturates (NaN gives 0 steps).
        let steps = (libm::ceilf(target_a.abs() / step_a) as u32).min(MAX_RAMP_STEPS);
        for k in 1..=steps {
            let current_a = target_a * (k as f32 / steps as f32);
            if dac.write_current(current_a).is_err() {
                halt("the DAC cannot be written (SPI timeout)");
            }
            let start = DWT::cycle_count();
            while DWT::cycle_count().wrapping_sub(start) < period_cycles {}
            watchdog.feed();
        }

        let Some(timer) = ControlTimer::new(&dp.RCC, rate_hz) else {
            halt("TIM2 cannot run at the control rate (must divide 90 MHz)")
        };
        let adc = DisplacementAdc::new(&dp.RCC);
        // The control interrupt feeds it from here on: the run timeout.
        if !watchdog.set_run_timeout() {
            defmt::warn!("watchdog run timeout not applied: the start-up timeout stays");
        }
        let app = App {
            control,
            state,
            dac,
            timer,
            adc,
            watchdog,
            consecutive_dac_timeouts: 0,
            #[cfg(feature = "measurement-mode")]
            recorder,
        };
        if APP.give(app).is_err() {
            halt("control state handed over twice");
        }
        // SAFETY: APP is published (release) before the interrupt can run.
        unsafe { cortex_m::peripheral::NVIC::unmask(Interrupt::TIM2) };

        let mut next_report = rate_hz;
        #[cfg(feature = "measurement-mode")]
        let mut record_open = true;
        loop {
            // Measurement image: drain the record into RTT while the programme runs (no sleep:
            // the queue holds 51 ms), then report how it ended, once.
            #[cfg(feature = "measurement-mode")]
            if record_open {
                let ended = RECORD_ENDED.load(Ordering::Acquire);
                log_batches(&mut drain, ended);
                if ended && drain.is_empty() {
                    defmt::info!(
                        "MEAS-END {=u32} lost {=u32} sensor-faults",
                        RECORD_LOST.load(Ordering::Relaxed),
                        SENSOR_FAULTS.load(Ordering::Relaxed)
                    );
                    record_open = false;
                }
                continue;
            }
            cortex_m::asm::wfi();
            let ticks = TICKS.load(Ordering::Relaxed);
            if ticks >= next_report {
                next_report = next_report.wrapping_add(rate_hz);
                defmt::info!(
                    "{=u32} interrupts; cycles/interrupt min {=u32} max {=u32}; overruns {=u32}; u clamped {=u32}, current limited {=u32}, slew limited {=u32}, faults {=u32}, SPI timeouts {=u32}, staircase merges {=u32}, sensor faults {=u32}, log bytes dropped {=u32}",
                    ticks,
                    MIN_CYCLES.load(Ordering::Relaxed),
                    MAX_CYCLES.load(Ordering::Relaxed),
                    OVERRUNS.load(Ordering::Relaxed),
                    FLAGGED[0].load(Ordering::Relaxed),
                    FLAGGED[1].load(Ordering::Relaxed),
                    FLAGGED[2].load(Ordering::Relaxed),
                    FLAGGED[3].load(Ordering::Relaxed),
                    SPI_TIMEOUTS.load(Ordering::Relaxed),
                    MERGES.load(Ordering::Relaxed),
                    SENSOR_FAULTS.load(Ordering::Relaxed),
                    rtt::DROPPED_BYTES.load(Ordering::Relaxed)
                );
            }
        }
    }
}
