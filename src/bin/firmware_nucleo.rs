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
//! **Emulator build** (feature `emulator-netduinoplus2`, `cargo xtask hil --board nucleo`): the
//! same image for QEMU's `netduinoplus2` (STM32F405: the same TIM2, SPI1 and USART2). The sensor
//! sample comes from the virtual bench's plant link on USART2
//! (`magctl::board::nucleo_f446re::emulator`) instead of ADC1, each tick's command goes back on
//! it, the logs and the exit status (`docs/hil.md`) go over semihosting, and the clock flags the
//! emulator does not model are taken as set (`clocks=board` on the command line polls them as
//! on the chip: the PLL then never locks and the start-up halts at 0 A, exit 9). `ticks=N` sets
//! the tracking ticks (default one second). Everything else — the start-up order, the watchdog's
//! register writes, TIM2 and its flag, the SPI1 DAC frames, the fault paths — is the board's
//! code (docs/firmware.md lists what the emulator bypasses).
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

#[cfg(all(feature = "emulator-netduinoplus2", feature = "measurement-mode"))]
compile_error!("the emulator build runs the tracking image only");

#[cfg(target_os = "none")]
mod firmware {
    use core::sync::atomic::{AtomicU32, Ordering};
    use cortex_m::peripheral::DWT;
    use embedded_hal_bus::spi::{ExclusiveDevice, NoDelay};
    use magctl::board::handoff::HandOff;
    #[cfg(not(feature = "emulator-netduinoplus2"))]
    use magctl::board::nucleo_f446re::adc::DisplacementAdc;
    #[cfg(feature = "emulator-netduinoplus2")]
    use magctl::board::nucleo_f446re::emulator::PlantLink;
    use magctl::board::nucleo_f446re::fatal;
    #[cfg(feature = "measurement-mode")]
    use magctl::board::nucleo_f446re::rtt;
    use magctl::board::nucleo_f446re::spi::{ChipSelect, Spi1};
    use magctl::board::nucleo_f446re::timer::ControlTimer;
    use magctl::board::nucleo_f446re::watchdog::{self, Watchdog};
    use magctl::board::nucleo_f446re::{clocks, log_bytes_dropped, spi};
    use magctl::inverse::{CommandFlags, ControlLoop, InverseKind, LoopState};
    #[cfg(not(feature = "measurement-mode"))]
    use magctl::inverse::{Conditioning, ConditioningState};
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
    /// Exit status of a start-up halt under the emulator, by cause (`docs/hil.md`).
    const EXIT_ARGUMENTS: u32 = 4;
    const EXIT_PARAMETERS: u32 = 5;
    const EXIT_DAC: u32 = 6;
    const EXIT_CLOCKS: u32 = 9;

    type Dac = SpiDac<ExclusiveDevice<Spi1, ChipSelect, NoDelay>>;

    struct App {
        control: ControlLoop<'static>,
        state: LoopState<CAPACITY>,
        dac: Dac,
        timer: ControlTimer,
        #[cfg(not(feature = "emulator-netduinoplus2"))]
        adc: DisplacementAdc,
        watchdog: Watchdog,
        consecutive_dac_timeouts: u32,
        /// Tracking image: the start-up conditioning (`magctl::inverse::Conditioning`: from
        /// 0 A at the slew limit to saturation or through the reach, then to the controller's
        /// first current), run by the interrupt before the first tracking tick.
        #[cfg(not(feature = "measurement-mode"))]
        conditioning: (Conditioning, ConditioningState),
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
        #[cfg(all(
            not(feature = "measurement-mode"),
            not(feature = "emulator-netduinoplus2")
        ))]
        let sample = app
            .adc
            .sample()
            .and_then(|count| app.control.sensor().displacement_m(count));
        #[cfg(feature = "emulator-netduinoplus2")]
        let sample = bench::take_sample(&app.control);
        #[cfg(not(feature = "measurement-mode"))]
        let out = {
            let (c, seq) = &mut app.conditioning;
            if seq.done() {
                app.control.tick_sensed(INVERSE, &mut app.state, sample)
            } else {
                app.control
                    .condition_sensed(INVERSE, c, seq, &mut app.state, sample)
            }
        };
        // Measurement image: the programme's current; the reading is checked only against the
        // ADC's range (identification drives the rod over its whole stroke).
        #[cfg(feature = "measurement-mode")]
        let out = {
            let (count, monitor_count) = app.adc.sample_with_monitor();
            let reading = count.and_then(|count| app.control.sensor().reading_m(count));
            // The current monitor's reading of the same instant (the record holds NaN without
            // one, or for a conversion that did not finish).
            let coil_current_a = BAKED_PARAMETERS
                .current_monitor
                .zip(monitor_count)
                .and_then(|(m, count)| app.control.sensor().monitor_current_a(&m, count));
            let out = app
                .recorder
                .tick(&app.control, &mut app.state, reading, coil_current_a);
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
        #[cfg(feature = "emulator-netduinoplus2")]
        bench::put_command(&out);
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

    /// The emulator build's bench: thread mode runs the lock-step link (the plant's sample, the
    /// TIM2 interrupt pended on it, the command back) and ends the run.
    ///
    /// Why TIM2 is pended rather than left to expire: QEMU 7.2's STM32 timer model schedules each
    /// update at `now` plus an absolute time (`hw/timer/stm32f2xx_timer.c`), so its periods
    /// grow with the virtual clock until the alarm overflows and stalls the emulator. The
    /// emulator build therefore stops the counter and pends the TIM2 interrupt when the plant's
    /// sample has arrived, as the `mps2-an386` bench pends TIMER0; the handler and its flag
    /// handling are the board's.
    #[cfg(feature = "emulator-netduinoplus2")]
    mod bench {
        use magctl::board::nucleo_f446re::emulator::PlantLink;
        use magctl::board::tick_mailbox::TickMailbox;
        use magctl::inverse::{CommandFlags, ControlLoop, TickOutput};
        use magctl::link::{CommandFrame, EndAck, Sample, KIND_BEGIN, KIND_END};
        use magctl::sensor::SensorFault;
        use stm32f4::stm32f446::{Interrupt, NVIC};

        /// Exit status: a sensor fault was latched and handled (`docs/hil.md`).
        const EXIT_SENSOR_FAULT: u32 = 7;
        /// Exit status: a link fault was handled (the coil ramped to 0 A on the firmware's own
        /// ticks).
        const EXIT_LINK_FAULT: u32 = 8;
        /// Exit status: a self-check failed (the interrupt did not run, an SPI timeout, no 0 A
        /// after a fault's ramp).
        const EXIT_CHECK_FAILED: u32 = 3;

        /// The tick in flight between thread mode and the interrupt.
        static MAILBOX: TickMailbox = TickMailbox::new();

        /// The interrupt's side: the tick's sample, scaled and checked.
        #[inline(always)]
        pub fn take_sample(control: &ControlLoop<'static>) -> Result<f32, SensorFault> {
            let sensor = control.sensor();
            match MAILBOX.sample() {
                Some(Sample::Count(c)) => sensor.displacement_m(c),
                Some(Sample::Metres(m)) => sensor.check_m(m),
                None => Err(SensorFault::Missing),
            }
        }

        /// The interrupt's side: the tick's command, for the link (no instruction count here).
        #[inline(always)]
        pub fn put_command(out: &TickOutput) {
            MAILBOX.post_command(out, 0);
        }

        /// Pends the control interrupt on `sample` and returns its command frame for `tick`
        /// (`None` if the interrupt did not run).
        fn run_tick(sample: Option<Sample>, tick: u32) -> Option<CommandFrame> {
            MAILBOX.post_sample(sample, None);
            NVIC::pend(Interrupt::TIM2);
            // The pended interrupt preempts thread mode at once; the barriers make sure it ran.
            cortex_m::asm::dsb();
            cortex_m::asm::isb();
            MAILBOX.command(tick as u16)
        }

        /// The lock-step run: `B`, then per tick the plant's sample, the interrupt, the command
        /// back, for `ticks` ticks; after a link fault the firmware ticks on alone (at most
        /// `ramp_ticks`) until the coil is at 0 A. Returns the ticks run and the exit status
        /// before the SPI check (`docs/hil.md`).
        pub fn lock_step(
            link: &mut PlantLink,
            rate_hz: f32,
            ticks: u32,
            ramp_ticks: u32,
        ) -> (u32, u32) {
            link.send_command(&CommandFrame {
                kind: KIND_BEGIN,
                seq: 0,
                value: rate_hz,
                desired_m: 0.0,
                flags: 0,
                aux: 0,
                aux32: ticks,
            });
            let mut link_fault_at: Option<u32> = None;
            let mut sensor_faulted = false;
            let mut tick = 0u32;
            loop {
                let sample = link.sample();
                if sample.is_none() && link_fault_at.is_none() {
                    link_fault_at = Some(tick);
                }
                let Some(cmd) = run_tick(sample, tick) else {
                    defmt::error!("the control interrupt did not run at tick {=u32}", tick);
                    return (tick, EXIT_CHECK_FAILED);
                };
                sensor_faulted |= CommandFlags(cmd.flags).has(CommandFlags::SENSOR_FAULT);
                link.send_command(&cmd);
                tick += 1;
                match link_fault_at {
                    None if tick >= ticks => {
                        let status = if sensor_faulted { EXIT_SENSOR_FAULT } else { 0 };
                        return (tick, status);
                    }
                    Some(_) if cmd.value == 0.0 => return (tick, EXIT_LINK_FAULT),
                    Some(at) if tick > at.saturating_add(ramp_ticks) => {
                        return (tick, EXIT_CHECK_FAILED)
                    }
                    _ => {}
                }
            }
        }

        /// Sends `E` with `status`, waits (bounded) for the host's acknowledgement, exits.
        pub fn end(link: &mut PlantLink, tick: u32, status: u32) -> ! {
            link.send_command(&CommandFrame {
                kind: KIND_END,
                seq: tick as u16,
                value: 0.0,
                desired_m: 0.0,
                flags: 0,
                aux: status as u16,
                aux32: 0,
            });
            let ack = EndAck {
                seq: tick as u16,
                status: status as u16,
            };
            if !link.await_end_ack(ack) {
                defmt::warn!("the bench host did not acknowledge the end frame within its bound");
            }
            magctl::board::semihosting::exit(status)
        }
    }

    /// Emulator build: `ticks=N` (tracking ticks) and `clocks=emulated|board` from the
    /// semihosting command line; a bad word halts (exit 4).
    #[cfg(feature = "emulator-netduinoplus2")]
    fn emulator_arguments(rate_hz: f32) -> (u32, clocks::LockFlags) {
        use magctl::board::command_line::CommandLine;
        let mut buf = [0u8; 128];
        let n = magctl::board::semihosting::command_line(&mut buf);
        let args = CommandLine::new(buf.get(..n).unwrap_or(&[]));
        let parsed = (|| {
            args.check(&[b"ticks", b"clocks"])?;
            let ticks = args.number(b"ticks")?.unwrap_or(rate_hz as u32);
            let flags = match args.choice(b"clocks", &[b"emulated", b"board"])? {
                Some(1) => clocks::LockFlags::Polled,
                _ => clocks::LockFlags::AssumedSet,
            };
            Ok((ticks, flags))
        })();
        match parsed {
            Ok(v) => v,
            Err(e) => {
                let e: magctl::board::command_line::ArgError<'_> = e;
                defmt::error!("command line: cannot use `{=[u8]:a}`", e.word());
                fatal::stop(EXIT_ARGUMENTS)
            }
        }
    }

    /// Start-up steps 1–3 of `docs/safety.md`: 0 A to the DAC on the reset clock, the watchdog
    /// with its start-up timeout, the clocks with every wait bounded. Halts (0 A written) on a
    /// failure.
    fn start_safely(
        cp: &mut cortex_m::Peripherals,
        dp: &pac::Peripherals,
        lock_flags: clocks::LockFlags,
    ) -> (Dac, Watchdog) {
        let p = &BAKED_PARAMETERS;
        // 0 A before anything else, on the reset clock (the DAC keeps its code through an MCU
        // reset, a watchdog reset included); SPI1 just runs slower until the PLL is up.
        let Some(scale) = DacScale::new(p.control.current_limit_a) else {
            halt("invalid control.current_limit_a", EXIT_PARAMETERS)
        };
        let (spi, cs) = spi::init(&dp.RCC);
        let Ok(device) = ExclusiveDevice::new_no_delay(spi, cs);
        let mut dac = SpiDac::new(device, scale);
        if dac.write_current(0.0).is_err() {
            halt("the DAC cannot be written (SPI timeout)", EXIT_DAC);
        }
        defmt::info!("start-up: 0 A written to the DAC on the reset clock");
        // Then the watchdog, with its start-up timeout, before anything that can stall.
        let reset_by_watchdog = watchdog::take_reset_was_watchdog(&dp.RCC);
        let (watchdog, boot_configured) = Watchdog::start_for_boot(&dp.DBGMCU);
        match clocks::init(&dp.RCC, &dp.PWR, &dp.FLASH, lock_flags, || watchdog.feed()) {
            Ok(clocks::ClockSource::Hse) => {}
            Ok(clocks::ClockSource::Hsi) => defmt::warn!(
                "the 8 MHz HSE did not come up: running from the internal HSI (control rate within its 1 %)"
            ),
            Err(e) => halt(e.describe(), EXIT_CLOCKS),
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

    /// A start-up failure, after the DAC's 0 A: halts for the probe (the emulator build exits
    /// with `status`).
    fn halt(reason: &str, status: u32) -> ! {
        defmt::error!("start-up failed: {=str}; DAC at 0 A", reason);
        fatal::stop(status)
    }

    /// Emulator build: runs the lock-step link until the run ends, then reports and exits with
    /// the run's status.
    #[cfg(feature = "emulator-netduinoplus2")]
    fn emulated_run(mut link: PlantLink, rate_hz: f32, ticks: u32, ramp_ticks: u32) -> ! {
        let (ran, status) = bench::lock_step(&mut link, rate_hz, ticks, ramp_ticks);
        cortex_m::peripheral::NVIC::mask(Interrupt::TIM2);
        let spi_timeouts = SPI_TIMEOUTS.load(Ordering::Relaxed);
        defmt::info!(
            "ticks {=u32}; overruns {=u32}; SPI timeouts {=u32}; sensor faults {=u32}; log bytes dropped {=u32}; stack high-water {=u32} B",
            ran,
            OVERRUNS.load(Ordering::Relaxed),
            spi_timeouts,
            SENSOR_FAULTS.load(Ordering::Relaxed),
            log_bytes_dropped(),
            magctl::board::stack::high_water_bytes() as u32
        );
        let status = if spi_timeouts > 0 { 3 } else { status };
        bench::end(&mut link, ran, status)
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        // First: the stack's high-water mark is measured against this paint.
        magctl::board::stack::paint();
        // Then the guard below the stack: an overflow faults instead of overwriting the statics.
        magctl::board::stack::guard();
        let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take())
        else {
            halt("peripherals already taken", EXIT_ARGUMENTS)
        };
        let p = &BAKED_PARAMETERS;
        #[cfg(not(feature = "emulator-netduinoplus2"))]
        let lock_flags = clocks::LockFlags::Polled;
        #[cfg(feature = "emulator-netduinoplus2")]
        let (tracking_ticks, lock_flags) = emulator_arguments(p.control.sample_rate_hz);
        let (dac, watchdog) = start_safely(&mut cp, &dp, lock_flags);

        defmt::info!(
            "magctl firmware on NUCLEO-F446RE: {=u32} Hz core, control rate {=f32} Hz, Van der Pol mu {=f32}, {=f32} Hz scale",
            clocks::SYSCLK_HZ,
            p.control.sample_rate_hz,
            p.trajectory.van_der_pol_mu,
            p.trajectory.frequency_scale_hz
        );
        let control = match ControlLoop::new(&BAKED_MEASURE, p) {
            Ok(c) => c,
            Err(_) => halt(
                "invalid control settings in the baked parameters",
                EXIT_PARAMETERS,
            ),
        };
        let state = control.init::<CAPACITY>(INVERSE);
        #[cfg(feature = "measurement-mode")]
        let (recorder, drain) = {
            let Ok(programme) = magctl::programme::IdentificationProgramme::for_parameters(
                control.limiter(),
                p,
                &BAKED_MEASURE,
            ) else {
                halt(
                    "the identification programme cannot run with the baked parameters",
                    EXIT_PARAMETERS,
                )
            };
            let Some(queue) = cortex_m::singleton!(: RecordQueue = RecordQueue::new()) else {
                halt("record queue taken twice", EXIT_ARGUMENTS)
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
        // Tracking image: the start-up conditioning runs in the interrupt, from 0 A at the slew
        // limit to the state the controller's first memory assumes and then to its first current.
        #[cfg(not(feature = "measurement-mode"))]
        let conditioning = {
            let c = *control.conditioning();
            (c, control.conditioning_sequence(0.0, &state))
        };
        #[cfg(feature = "emulator-netduinoplus2")]
        let (link, ticks, ramp_ticks) = {
            let (c, seq) = conditioning;
            let l = control.limiter();
            let ramp_ticks = libm::ceilf(l.limit_a() / l.max_step_a()) as u32 + 2;
            let ticks = tracking_ticks.saturating_add(c.remaining_ticks(&seq));
            defmt::info!(
                "firmware-nucleo (emulator): {=u32} ticks at {=f32} Hz, lock-step over USART2",
                ticks,
                p.control.sample_rate_hz
            );
            (PlantLink::new(&dp.RCC), ticks, ramp_ticks)
        };
        let Some(timer) = ControlTimer::new(&dp.RCC, rate_hz) else {
            halt(
                "TIM2 cannot run at the control rate (must divide 90 MHz)",
                EXIT_PARAMETERS,
            )
        };
        // Emulator build: the counter stopped, the interrupt pended per sample (`bench`).
        #[cfg(feature = "emulator-netduinoplus2")]
        let timer = timer.stopped();
        // The measurement image converts the current monitor with the sensor when the file has
        // one (`current_monitor`); the tracking image never reads it.
        #[cfg(all(not(feature = "emulator-netduinoplus2"), feature = "measurement-mode"))]
        let adc = if p.current_monitor.is_some() {
            DisplacementAdc::with_current_monitor(&dp.RCC)
        } else {
            DisplacementAdc::new(&dp.RCC)
        };
        #[cfg(all(
            not(feature = "emulator-netduinoplus2"),
            not(feature = "measurement-mode")
        ))]
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
            #[cfg(not(feature = "emulator-netduinoplus2"))]
            adc,
            watchdog,
            consecutive_dac_timeouts: 0,
            #[cfg(not(feature = "measurement-mode"))]
            conditioning,
            #[cfg(feature = "measurement-mode")]
            recorder,
        };
        if APP.give(app).is_err() {
            halt("control state handed over twice", EXIT_ARGUMENTS);
        }
        // SAFETY: APP is published (release) before the interrupt can run.
        unsafe { cortex_m::peripheral::NVIC::unmask(Interrupt::TIM2) };
        #[cfg(feature = "emulator-netduinoplus2")]
        emulated_run(link, p.control.sample_rate_hz, ticks, ramp_ticks);

        #[cfg(not(feature = "emulator-netduinoplus2"))]
        thread_mode(
            rate_hz,
            #[cfg(feature = "measurement-mode")]
            drain,
        )
    }

    /// Thread mode on the board: the status line once per second of control time (the
    /// measurement image: the record's drain into RTT first).
    #[cfg(not(feature = "emulator-netduinoplus2"))]
    fn thread_mode(
        rate_hz: u32,
        #[cfg(feature = "measurement-mode")] mut drain: RecordDrain<'static>,
    ) -> ! {
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
                    log_bytes_dropped()
                );
            }
        }
    }
}
