//! Virtual-bench firmware for QEMU's `mps2-an386`: the control loop in lock-step with a plant
//! program over the CMSDK UART0 (`cargo xtask hil`; protocol in `docs/hil.md`, frames in
//! `magctl::link`).
//!
//! Every control tick:
//! 1. thread mode receives the plant's sensor frame for tick `k` (the reading at `t_k`), waiting
//!    at most [`MAX_LINK_POLLS`] polls of the UART; this stands in for the ADC conversion the
//!    control timer triggers on the board;
//! 2. it pends the control interrupt (TIMER0's vector, IRQ 8), which reads the sample (count →
//!    metres and the validity checks of the `sensor` section), runs one `ControlLoop` tick
//!    (trajectory, inverse, limiter; a bad sample latches a sensor fault and ramps the coil to
//!    0 A), writes the DAC frame over SPI and leaves the command for the link; its instruction
//!    count (SysTick / 25.6) travels in the command frame;
//! 3. thread mode sends the command frame; the plant holds that current over `[t_k, t_{k+1}]`
//!    and answers with the reading at `t_{k+1}`.
//!
//! The plant is the clock: the firmware runs a tick when its sample arrives, so the exchanged data
//! do not depend on host speed (the run is deterministic under `-icount` for a deterministic
//! plant). On the board the control timer is the clock and the same handler runs on its
//! interrupt.
//!
//! Before the first tick the firmware sends a `B` frame (control rate, tick count); after the last
//! an `E` frame with its exit status, and it exits once the bench host has acknowledged that frame
//! (`magctl::link::EndAck`, at most [`MAX_LINK_POLLS`] polls).
//!
//! **Faults** (`docs/hil.md`): a silent link (no complete frame within [`MAX_LINK_POLLS`]), a
//! frame with a wrong sync byte, kind or sequence number is a *link fault*: the sample of that
//! tick is `Missing`, the loop latches a sensor fault and the firmware keeps ticking on its own
//! (no more waiting) until the command has ramped to 0 A at the slew limit, then ends: exit 8. A
//! sample outside the ADC's range or the valid range, or a non-finite one, is a *sensor fault*:
//! with the feedback on, the loop falls back to the feedforward alone (flags `SENSOR_FAULT |
//! FEEDFORWARD`); with it off (`feedback=off` or the parameter file), the coil ramps to 0 A and
//! holds it, every command flagged; the plant keeps the clock to the end of the run: exit 7. A
//! clean run exits 0; a failed self-check (a command other than 0 A after the ramp ended, an
//! unflagged command after a fault, an SPI timeout) exits 3.
//!
//! **Start-up conditioning** (`magctl::inverse::Conditioning`): the first ticks ramp the coil to
//! the negative current limit (a rod the coil saturates) or through the rod's reach, top then
//! bottom (a rod it cannot), hold, ramp to the controller's first current and hold, so the rod's
//! memory is the one the controller assumes whatever its history; those commands carry the
//! `CONDITIONING` flag (32). `condition=off` skips it (to measure what it is worth). Every exit
//! status is listed in docs/hil.md ("Exit status").
//!
//! **Measurement mode** (`mode=measure`): instead of tracking, the firmware plays an
//! identification programme streamed by the bench host — a programme frame (`R`, the current
//! of the tick) before every sample frame — through the output limiter to the DAC, and returns
//! in each command frame the current it applied and its own reading of the tick's sample (in
//! metres, checked against the ADC's range only: identification drives the rod over its whole
//! stroke), flagged `MEASURE` (64). The host writes the dataset folder (`cargo xtask hil
//! --measure`). No conditioning: the programme carries its own.
//!
//! **Local measurement** (`mode=measure-local`): the firmware plays the compiled-in programme
//! itself (`magctl::programme`, as the NUCLEO measurement image does) — no programme frames —
//! and records every tick as the board does: the interrupt queues it (`magctl::record`), thread
//! mode logs the batches with defmt (`MEAS …` lines, here over semihosting, on the board over
//! RTT), which `cargo xtask record` turns into the dataset folder. The command frames still carry
//! the current and the reading, so the bench checks the record against the link.
//!
//! Command line (semihosting): `ticks=N` tracking or programme ticks (default: one second at the
//! control rate), `inverse=static` (default dynamic), `condition=off`, `mode=measure`,
//! `mode=measure-local` (its tick count is the programme's), `feedback=off` (feedforward only,
//! whatever the parameter file says).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "firmware-hil is Cortex-M firmware: build it with `--target thumbv7em-none-eabihf \
         --features board-mps2-an386`, or run `cargo xtask hil`"
    );
    std::process::exit(2);
}

#[cfg(target_os = "none")]
pub use firmware::*;

#[cfg(target_os = "none")]
mod firmware {
    use core::sync::atomic::{AtomicU32, Ordering};
    use cortex_m::peripheral::{syst::SystClkSource, NVIC, SYST};
    use magctl::board::command_line::{ArgError, CommandLine};
    use magctl::board::handoff::HandOff;
    use magctl::board::mps2_an386::uart::{CmsdkUart, UART0_BASE};
    use magctl::board::mps2_an386::{take_dac, Dac, Timer0Irq};
    use magctl::board::semihosting;
    use magctl::board::tick_mailbox::TickMailbox;
    use magctl::inverse::{
        CommandFlags, Conditioning, ConditioningState, ControlLoop, InverseKind, LoopState,
    };
    use magctl::link::{
        CommandFrame, EndAck, EndAckWatch, ProgrammeFrame, Sample, SampleAssembler, SampleFrame,
        KIND_BEGIN, KIND_END,
    };
    use magctl::output::{CurrentOutput, DacScale};
    use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
    use magctl::programme::IdentificationProgramme;
    use magctl::record::{RecordDrain, RecordQueue, Recorder};
    use magctl::sensor::SensorFault;

    /// Preisach memory capacity (reversal points) of the controller.
    const CAPACITY: usize = magctl::preisach::DEFAULT_CAPACITY;
    /// Polls of the UART receive buffer per sample frame before the link counts as silent
    /// (~6 instructions each: ≈ 100 s of virtual time under `-icount shift=10`, a few seconds of
    /// host time; on a board this would be one control period).
    pub const MAX_LINK_POLLS: u32 = 1 << 24;
    /// The same bound for the first frame of a run: 16× longer (about a minute of host time),
    /// for plant programs that take a while to start (an interpreter, a simulation package).
    pub const MAX_FIRST_LINK_POLLS: u32 = 1 << 28;
    /// Polls of the UART transmit buffer per byte before a send counts as failed.
    pub const MAX_TX_POLLS: u32 = 1 << 16;
    /// Exit status: a sensor fault was latched and handled (ramp to 0 A, held, flagged).
    pub const EXIT_SENSOR_FAULT: u32 = 7;
    /// Exit status: a link fault was handled (ramp to 0 A on the firmware's own clock).
    pub const EXIT_LINK_FAULT: u32 = 8;
    /// Exit status: a self-check failed.
    pub const EXIT_CHECK_FAILED: u32 = 3;

    /// The control interrupt's state.
    struct App {
        control: ControlLoop<'static>,
        kind: InverseKind,
        /// Measurement mode: play the streamed programme instead of tracking.
        measure: bool,
        /// Local measurement: the compiled-in programme and the record's producer.
        recorder: Option<Recorder<'static>>,
        state: LoopState<CAPACITY>,
        /// The start-up conditioning sequence, while it runs.
        conditioning: Option<(Conditioning, ConditioningState)>,
        dac: Dac,
        spi_timeouts: u32,
    }

    static APP: HandOff<App> = HandOff::new();

    /// The tick in flight between thread mode and the interrupt (`magctl::board::tick_mailbox`).
    static MAILBOX: TickMailbox = TickMailbox::new();
    /// The programme's current of the coming tick (measurement mode), f32 bits.
    static PROGRAMME_BITS: AtomicU32 = AtomicU32::new(0);

    /// The control interrupt (TIMER0's vector, IRQ 8, pended by the link when a sample arrived).
    ///
    /// **Deadline**: one control period on the board. Under QEMU the plant is the clock (module
    /// docs), so there is no overrun to detect here; the handler's instruction count goes to the
    /// host with every command and is checked there.
    /// **Work**: the sample (count → metres, checks), one `ControlLoop::tick_sensed`, one DAC frame,
    /// the command into the mailbox. No allocation, no panic path (`panic-never` build).
    ///
    /// # Safety
    /// Called only by the hardware through the vector table.
    #[unsafe(no_mangle)]
    pub unsafe extern "C" fn TIMER0() {
        let entry = SYST::get_current();
        // SAFETY: this interrupt is APP's only user once it has been given.
        let Some(app) = (unsafe { APP.get_mut() }) else {
            return;
        };
        let sensor = app.control.sensor();
        let sample = MAILBOX.sample();
        let out = if app.measure {
            let reading = match sample {
                Some(Sample::Count(c)) => sensor.reading_m(c),
                Some(Sample::Metres(m)) => Ok(m),
                None => Err(SensorFault::Missing),
            };
            match &mut app.recorder {
                Some(recorder) => recorder.tick(
                    &app.control,
                    &mut app.state,
                    reading,
                    MAILBOX.coil_current_a(),
                ),
                None => {
                    let programme_a = f32::from_bits(PROGRAMME_BITS.load(Ordering::Relaxed));
                    app.control
                        .measure_sensed(&mut app.state, programme_a, reading)
                }
            }
        } else {
            tracking_tick(app, sample)
        };
        if app.dac.write_current(out.current_a).is_err() {
            app.spi_timeouts = app.spi_timeouts.saturating_add(1);
        }
        let exit = SYST::get_current();
        let ticks = entry.wrapping_sub(exit) & 0x00FF_FFFF;
        // SysTick ticks per instruction = 25.6 = 128 / 5 under `-icount shift=10`.
        let instructions = (ticks * 5 / 128).min(u16::MAX as u32) as u16;
        MAILBOX.post_command(&out, instructions);
    }

    /// One tracking tick (conditioning first while it runs) on `sample`.
    #[inline(always)]
    fn tracking_tick(app: &mut App, sample: Option<Sample>) -> magctl::inverse::TickOutput {
        let sensor = app.control.sensor();
        let sample = match sample {
            Some(Sample::Count(c)) => sensor.displacement_m(c),
            Some(Sample::Metres(m)) => sensor.check_m(m),
            None => Err(SensorFault::Missing),
        };
        match &mut app.conditioning {
            Some((c, seq)) if !seq.done() => {
                app.control
                    .condition_sensed(app.kind, c, seq, &mut app.state, sample)
            }
            _ => app.control.tick_sensed(app.kind, &mut app.state, sample),
        }
    }

    /// The poll bound of a frame of tick `seq` (the first tick gets the start-up allowance; a
    /// run longer than 2¹⁶ ticks gives it again at each wrap, harmlessly).
    fn polls_for(seq: u16) -> u32 {
        if seq == 0 {
            MAX_FIRST_LINK_POLLS
        } else {
            MAX_LINK_POLLS
        }
    }

    /// Receives the next frame of tick `seq` (8 or 12 bytes, by its kind) and decodes it with
    /// `decode` (bounded wait: a silent link, a wrong sync byte, kind or sequence number is
    /// `Err`).
    fn receive<T, E>(
        uart: &mut CmsdkUart,
        assembler: &mut SampleAssembler,
        seq: u16,
        decode: impl Fn(&[u8], u16) -> Result<T, E>,
    ) -> Result<T, ()> {
        for _ in 0..polls_for(seq) {
            if let Some(byte) = uart.try_read() {
                if let Some(frame) = assembler.push(byte) {
                    return decode(frame.as_slice(), seq).map_err(|_| ());
                }
            }
        }
        Err(())
    }

    /// Runs one control interrupt on `sample` (and the coil current read on its trigger) and
    /// returns its command frame.
    fn run_tick(
        sample: Option<Sample>,
        coil_current_a: Option<f32>,
        seq: u16,
    ) -> Option<CommandFrame> {
        MAILBOX.post_sample(sample, coil_current_a);
        NVIC::pend(Timer0Irq);
        // The pended interrupt preempts thread mode at once; these barriers make sure it has run.
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        MAILBOX.command(seq)
    }

    /// What the command line asks for (`ticks=N mode=track|measure|measure-local
    /// inverse=dynamic|static condition=on|off feedback=on|off`, each optional).
    struct Arguments {
        tracking_ticks: u32,
        /// Measurement mode (the host streams the programme, or the firmware plays it).
        measure: bool,
        /// The firmware plays the programme itself and records it (`mode=measure-local`).
        local: bool,
        condition: bool,
        feedback_off: bool,
        kind: InverseKind,
    }

    /// The command line's [`Arguments`]; an unknown word or value is logged by name and is an
    /// error (the run exits 4).
    fn parse_command_line(line: &[u8], rate_hz: f32) -> Result<Arguments, ()> {
        let args = CommandLine::new(line);
        let parsed = (|| {
            args.check(&[b"ticks", b"mode", b"inverse", b"condition", b"feedback"])?;
            let mode = args
                .choice(b"mode", &[b"track", b"measure", b"measure-local"])?
                .unwrap_or(0);
            let off = |key: &[u8]| args.choice(key, &[b"on", b"off"]).map(|v| v == Some(1));
            Ok(Arguments {
                tracking_ticks: args.number(b"ticks")?.unwrap_or(rate_hz as u32),
                measure: mode >= 1,
                local: mode == 2,
                condition: mode == 0 && !off(b"condition")?,
                feedback_off: off(b"feedback")?,
                kind: match args.choice(b"inverse", &[b"dynamic", b"static"])? {
                    Some(1) => InverseKind::Static,
                    _ => InverseKind::Dynamic,
                },
            })
        })();
        parsed.map_err(|e: ArgError<'_>| {
            defmt::error!("command line: cannot use `{=[u8]:a}`", e.word());
        })
    }

    /// Logs every ready batch of the record; with `flush`, the last partial one too
    /// (semihosting blocks until the host took the line).
    fn log_batches(drain: &mut RecordDrain<'static>, flush: bool) {
        magctl::record::log::batches(drain, flush, || true);
    }

    /// The guard's test (`cargo xtask qemu`): recurses until the stack reaches the guard; the run
    /// must end with the stack-overflow status, never return.
    #[cfg(feature = "stack-overflow-canary")]
    #[inline(never)]
    #[allow(unconditional_recursion)]
    fn overflow_the_stack(depth: u32) -> u32 {
        let frame = core::hint::black_box([depth; 64]);
        overflow_the_stack(depth + 1).wrapping_add(frame[(depth % 64) as usize])
    }

    fn end(uart: &mut CmsdkUart, seq: u16, status: u32) -> ! {
        let frame = CommandFrame {
            kind: KIND_END,
            seq,
            value: 0.0,
            desired_m: 0.0,
            flags: 0,
            aux: status as u16,
            aux32: 0,
        };
        // The run's last frame: the link gets the long bound (a loaded host may take a while to
        // drain the socket) and the frame must have left the UART before QEMU exits. A link that
        // does not take it within the bound is reported on the semihosting log.
        let sent = uart
            .write_all(&frame.encode(), MAX_LINK_POLLS)
            .and_then(|()| uart.flush(MAX_LINK_POLLS));
        if sent.is_err() {
            defmt::warn!("the end frame did not leave the UART within its bound");
            semihosting::exit(status)
        }
        // Exit only once the bench host has read `E` (its acknowledgement, `magctl::link::EndAck`),
        // reading and dropping whatever else arrives meanwhile: QEMU's socket, closed with bytes
        // unread, is reset, and the reset can drop the frames the host has not received yet.
        // Bounded like any receive; a host that never acknowledges is reported, the exit status
        // is the run's.
        let mut watch = EndAckWatch::new(EndAck {
            seq,
            status: status as u16,
        });
        let mut acknowledged = false;
        for _ in 0..MAX_LINK_POLLS {
            if uart.try_read().is_some_and(|byte| watch.push(byte)) {
                acknowledged = true;
                break;
            }
        }
        if !acknowledged {
            defmt::warn!("the bench host did not acknowledge the end frame within its bound");
        }
        semihosting::exit(status)
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        // First: the stack's high-water mark is measured against this paint.
        magctl::board::stack::paint();
        // Then the guard below the stack: an overflow faults instead of overwriting the statics.
        magctl::board::stack::guard();
        #[cfg(feature = "stack-overflow-canary")]
        overflow_the_stack(0);
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            semihosting::exit(4)
        };
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(0x00FF_FFFF);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();
        let rate_hz = BAKED_PARAMETERS.control.sample_rate_hz;
        let mut line_buf = [0u8; 128];
        let n = semihosting::command_line(&mut line_buf);
        let line = line_buf.get(..n).unwrap_or(&[]);
        let Ok(args) = parse_command_line(line, rate_hz) else {
            semihosting::exit(4)
        };
        let Arguments {
            tracking_ticks,
            measure,
            local,
            condition,
            feedback_off,
            kind,
        } = args;
        let control = match ControlLoop::new(&BAKED_MEASURE, &BAKED_PARAMETERS) {
            Ok(c) if feedback_off => {
                let off = c.feedback().off();
                c.with_feedback(off)
            }
            Ok(c) => c,
            Err(_) => {
                defmt::error!("invalid control settings in the baked parameters");
                semihosting::exit(5)
            }
        };
        let Some(scale) = DacScale::new(BAKED_PARAMETERS.control.current_limit_a) else {
            semihosting::exit(5)
        };
        // SAFETY: SPI0 and the chip-select pin are owned by nothing else.
        let mut dac = unsafe { take_dac(scale) };
        // 0 A first, whatever the DAC held before this reset.
        if dac.write_current(0.0).is_err() {
            defmt::error!("the DAC cannot be written (SPI timeout)");
            semihosting::exit(6)
        }
        let mut uart = unsafe { CmsdkUart::new(UART0_BASE, 16) };
        let state: LoopState<CAPACITY> = control.init(kind);
        // The sequence the loop's first memory assumes: saturation, or the sweep of the reach
        // of a rod the coil cannot saturate (never refused).
        let conditioning = if condition {
            let c = *control.conditioning();
            Some((c, control.conditioning_sequence(0.0, &state)))
        } else {
            None
        };
        let conditioning_ticks = conditioning.map_or(0, |(c, seq)| c.remaining_ticks(&seq));
        let mut ticks = tracking_ticks.saturating_add(conditioning_ticks);
        let mut drain = None;
        let recorder = if local {
            let Ok(programme) = IdentificationProgramme::for_parameters(
                control.limiter(),
                &BAKED_PARAMETERS,
                &BAKED_MEASURE,
            ) else {
                defmt::error!("the identification programme cannot run with the baked parameters");
                semihosting::exit(5)
            };
            let Some(queue) = cortex_m::singleton!(: RecordQueue = RecordQueue::new()) else {
                semihosting::exit(4)
            };
            let (producer, consumer) = queue.split();
            drain = Some(RecordDrain::new(consumer));
            // The programme, then the ramp to 0 A at the slew limit.
            let l = control.limiter();
            let ramp = libm::ceilf(l.limit_a() / l.max_step_a()) as u32 + 2;
            ticks = programme.total_ticks(0.0).saturating_add(ramp);
            magctl::record::log::programme(&programme, rate_hz);
            Some(Recorder::new(programme, producer))
        } else {
            None
        };
        defmt::info!(
            "firmware-hil: {=u32} conditioning + {=u32} {=str} ticks at {=f32} Hz, {=str} inverse, lock-step over UART0",
            conditioning_ticks,
            tracking_ticks,
            if measure { "measurement" } else { "tracking" },
            rate_hz,
            if kind == InverseKind::Dynamic {
                "dynamic"
            } else {
                "static"
            }
        );
        let app = App {
            control,
            kind,
            measure,
            recorder,
            state,
            conditioning,
            dac,
            spi_timeouts: 0,
        };
        if APP.give(app).is_err() {
            semihosting::exit(4)
        }
        // SAFETY: APP is published (release) before the interrupt can run.
        unsafe { NVIC::unmask(Timer0Irq) };

        let begin = CommandFrame {
            kind: KIND_BEGIN,
            seq: 0,
            value: rate_hz,
            desired_m: 0.0,
            flags: 0,
            aux: 0,
            aux32: ticks,
        };
        if uart.write_all(&begin.encode(), MAX_TX_POLLS).is_err() {
            defmt::error!("the link does not take bytes");
            semihosting::exit(EXIT_LINK_FAULT)
        }
        // After a link fault the firmware is its own clock until the ramp to 0 A has ended
        // (bounded: the ramp from the current limit takes `limit / max_step` ticks).
        let ramp_ticks = {
            let l = control.limiter();
            libm::ceilf(l.limit_a() / l.max_step_a()) as u32 + 2
        };
        let run = Run {
            ticks,
            ramp_ticks,
            measure,
            local,
        };
        let outcome = lock_step(&mut uart, &mut drain, &run);
        finish(uart, drain, outcome)
    }

    /// The run's length and mode.
    struct Run {
        /// Ticks of the run (conditioning, tracking or the programme).
        ticks: u32,
        /// Ticks the ramp to 0 A takes after a link fault.
        ramp_ticks: u32,
        /// Measurement mode.
        measure: bool,
        /// The firmware plays the programme itself.
        local: bool,
    }

    /// What the lock-step loop saw.
    struct Outcome {
        tick: u32,
        link_fault_at: Option<u32>,
        sensor_fault_at: Option<u32>,
        check_failed: bool,
        min_instr: u16,
        max_instr: u16,
        ramp_done: bool,
        fell_back: bool,
    }

    /// The lock-step loop: per tick, the programme's current (streamed measurement) and the
    /// sample from the plant, the control interrupt, the command frame back; a missing frame is
    /// a link fault, after which the firmware ticks on its own until the coil is at 0 A.
    fn lock_step(
        uart: &mut CmsdkUart,
        drain: &mut Option<RecordDrain<'static>>,
        run: &Run,
    ) -> Outcome {
        let Run {
            ticks,
            ramp_ticks,
            measure,
            local,
        } = *run;
        let mut assembler = SampleAssembler::new();
        let mut link_fault_at: Option<u32> = None;
        let mut sensor_fault_at: Option<u32> = None;
        let mut check_failed = false;
        let (mut min_instr, mut max_instr) = (u16::MAX, 0u16);
        let mut ramp_done = false;
        let mut fell_back = false;
        let mut tick: u32 = 0;
        while tick < ticks || (link_fault_at.is_some() && !ramp_done && tick < ticks + ramp_ticks) {
            let seq = tick as u16;
            if measure && !local && link_fault_at.is_none() {
                match receive(uart, &mut assembler, seq, ProgrammeFrame::decode) {
                    Ok(p) => PROGRAMME_BITS.store(p.current_a.to_bits(), Ordering::Relaxed),
                    Err(()) => link_fault_at = Some(tick),
                }
            }
            let (sample, coil_current_a) = if link_fault_at.is_none() {
                match receive(uart, &mut assembler, seq, SampleFrame::decode) {
                    Ok(frame) => (Some(frame.sample), frame.coil_current_a),
                    Err(()) => {
                        link_fault_at = Some(tick);
                        (None, None)
                    }
                }
            } else {
                (None, None)
            };
            let Some(cmd) = run_tick(sample, coil_current_a, seq) else {
                defmt::error!("the control interrupt did not run at tick {=u32}", tick);
                semihosting::exit(EXIT_CHECK_FAILED)
            };
            min_instr = min_instr.min(cmd.aux);
            max_instr = max_instr.max(cmd.aux);
            let flags = CommandFlags(cmd.flags);
            let faulted = flags.has(CommandFlags::SENSOR_FAULT);
            if faulted && sensor_fault_at.is_none() {
                sensor_fault_at = Some(tick);
            }
            if sensor_fault_at.is_some() {
                if !faulted {
                    check_failed = true;
                }
                if flags.has(CommandFlags::FEEDFORWARD) {
                    // Feedback on: the loop tracks on the feedforward alone to the end.
                    fell_back = true;
                } else {
                    if ramp_done && cmd.value != 0.0 {
                        check_failed = true;
                    }
                    ramp_done |= cmd.value == 0.0;
                }
            }
            if let Some(d) = drain {
                log_batches(d, false);
            }
            if link_fault_at.is_none() {
                if uart.write_all(&cmd.encode(), MAX_TX_POLLS).is_err() {
                    link_fault_at = Some(tick);
                }
            } else {
                // The plant may be gone: try once, never wait long.
                let _ = uart.write_all(&cmd.encode(), 64);
                if ramp_done {
                    tick += 1;
                    break;
                }
            }
            tick += 1;
        }
        Outcome {
            tick,
            link_fault_at,
            sensor_fault_at,
            check_failed,
            min_instr,
            max_instr,
            ramp_done,
            fell_back,
        }
    }

    /// Ends the run: the record's last batches, the counts, the exit status (docs/hil.md).
    fn finish(mut uart: CmsdkUart, mut drain: Option<RecordDrain<'static>>, o: Outcome) -> ! {
        let Outcome {
            tick,
            link_fault_at,
            sensor_fault_at,
            mut check_failed,
            min_instr,
            max_instr,
            ramp_done,
            fell_back,
        } = o;
        NVIC::mask(Timer0Irq);
        // SAFETY: the interrupt is masked: thread mode is APP's only user now.
        let spi_timeouts = unsafe { APP.get_mut() }.map_or(0, |a| a.spi_timeouts);
        if let Some(d) = &mut drain {
            log_batches(d, true);
            // SAFETY: as above.
            let (lost, faults) = unsafe { APP.get_mut() }.map_or((0, 0), |a| {
                (
                    a.recorder.as_ref().map_or(0, |r| r.lost()),
                    a.state.core.counters.sensor_faults,
                )
            });
            defmt::info!("MEAS-END {=u32} lost {=u32} sensor-faults", lost, faults);
        }
        defmt::info!(
            "ticks {=u32}; interrupt instructions min {=u16} max {=u16}; SPI timeouts {=u32}; stack high-water {=u32} B",
            tick,
            min_instr,
            max_instr,
            spi_timeouts,
            magctl::board::stack::high_water_bytes() as u32
        );
        if spi_timeouts > 0 {
            check_failed = true;
        }
        let status = if check_failed {
            EXIT_CHECK_FAILED
        } else if let Some(at) = link_fault_at {
            defmt::warn!(
                "link fault at tick {=u32}: coil ramped to 0 A on the firmware's clock ({=bool}), flagged",
                at,
                ramp_done
            );
            if ramp_done {
                EXIT_LINK_FAULT
            } else {
                EXIT_CHECK_FAILED
            }
        } else if let Some(at) = sensor_fault_at {
            defmt::warn!(
                "sensor fault at tick {=u32}: feedforward fallback ({=bool}) or coil ramped to 0 A ({=bool}) and held, every command flagged",
                at,
                fell_back,
                ramp_done
            );
            if ramp_done || fell_back {
                EXIT_SENSOR_FAULT
            } else {
                EXIT_CHECK_FAILED
            }
        } else {
            0
        };
        end(&mut uart, tick as u16, status)
    }
}
