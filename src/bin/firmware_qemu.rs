//! Control firmware for QEMU's `mps2-an386` (Cortex-M4F), run by `cargo xtask qemu`.
//!
//! The CMSDK TIMER0 interrupt runs one control step (Van der Pol trajectory → inverse → limiter →
//! SPI DAC) and streams a record per interrupt to the host (semihosting file
//! `qemu_capture.bin`, layout in `magctl::board::mps2_an386::capture`). Four phases run in one
//! QEMU process, each from a fresh controller state:
//!
//! 1. dynamic inverse, fast exact Preisach inverse — one second of control time;
//! 2. static inverse, fast exact Preisach inverse — one second;
//! 4. merge stress: dynamic inverse, fast exact Preisach inverse, driven by a decaying 250 Hz
//!    oscillation (nested reversals: the 64-point staircase fills after 32 periods and every
//!    later reversal forces a merge) — [`MERGE_TICKS`] interrupts; the desired motion is computed
//!    after each interrupt's measurement window, so the count is the inverse, limiter, DAC frame
//!    and merges (the trajectory step, measured in phase 1, is not in it);
//! 3. dynamic inverse with the naive baseline (bisection over the 325-cell forward) —
//!    [`NAIVE_TICKS`] interrupts (each costs ~10⁵ instructions; only its instruction count is
//!    compared);
//! 5. dynamic inverse with the Everett-bisection baseline (the exact operator, bisection on the
//!    input, each trial one Everett forward evaluation on a copy of the memory; openCFS's
//!    approach) — [`EVERETT_TICKS`] interrupts;
//! 6. dynamic inverse with the relay-grid baseline (5,050 relays, one weighted sum per
//!    evaluation, bisection; mavasbel/matlab-preisach-model's approach) — [`RELAY_TICKS`]
//!    interrupts.
//!
//! Phases 3, 5 and 6 only give instruction counts (`preisach::baselines`).
//!
//! Start-up puts 0 A on the coil first (the DAC powers up there; this rewrites it after a reset
//! that left another code in the DAC), as on the real board (`docs/safety.md`).
//!
//! # Timing under QEMU
//!
//! `cargo xtask qemu` runs QEMU with `-icount shift=10,sleep=off`: every instruction advances the
//! virtual clock by 2¹⁰ ns, so the 25 MHz SysTick advances exactly 25.6 ticks per instruction
//! (checked at start-up by timing blocks of 1024 and 2048 `nop`s, sent as a phase-0 record) and
//! the virtual CPU runs ~977 k instructions per virtual second. The control *math* runs at the
//! JSON's sample rate (h = 1/10 kHz); the TIMER0 period is instead set to an instruction budget
//! ([`FAST_BUDGET_INSTRUCTIONS`], [`NAIVE_BUDGET_INSTRUCTIONS`]) so that the handler fits in it;
//! with `sleep=off` idle virtual time costs no host time. On the real board (firmware-nucleo) the
//! timer runs at the true control rate.
//!
//! Exit status: 0 after the four phases with no dropped record, no overrun, no fault, no SPI
//! timeout and at least one merge in the merge phase;
//! 3 if a check failed; 101 panic, 102 HardFault, 103 unexpected interrupt (see
//! `board::mps2_an386::panic`); 4-6 start-up failures; 7 after `inject=sensor-fault` when the
//! coil ramped to 0 A at the slew limit and held it, flagged. Fault injection for the tests:
//! `-semihosting-config ...,arg=inject=panic`, `arg=inject=hardfault` or
//! `arg=inject=sensor-fault` (the dynamic phase then reads a virtual sensor — the desired
//! displacement — with one out-of-range sample, and the run ends after it).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "firmware-qemu is Cortex-M firmware: build it with `--target thumbv7em-none-eabihf \
         --features board-mps2-an386`, or run `cargo xtask qemu`"
    );
    std::process::exit(2);
}

#[cfg(target_os = "none")]
pub use firmware::*;

#[cfg(target_os = "none")]
mod firmware {
    use core::sync::atomic::{AtomicBool, Ordering};
    use cortex_m::peripheral::{syst::SystClkSource, NVIC, SYST};
    use magctl::board::capture_phase::CapturePhase;
    use magctl::board::command_line::CommandLine;
    use magctl::board::handoff::HandOff;
    use magctl::board::mps2_an386::capture::{encode, Record, Ring};
    use magctl::board::mps2_an386::timer::CmsdkTimer;
    use magctl::board::mps2_an386::{take_dac, Dac, Timer0Irq, TIMER0_BASE, TIMER1_BASE};
    use magctl::board::semihosting::{self, HostFile};
    use magctl::inverse::{
        ControlLoop, EverettBisectionInverter, InverseKind, LoopCore, LoopState, NaiveLoopState,
        RelayGridInverter,
    };
    use magctl::model::DynamicModel;
    use magctl::output::{CurrentOutput, DacScale};
    use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
    use magctl::preisach::baselines::RelayGrid;
    use magctl::trajectory::DesiredMotion;

    /// Preisach memory capacity (reversal points) of the controller.
    const CAPACITY: usize = magctl::preisach::DEFAULT_CAPACITY;
    /// Dynamic-phase interrupt that receives the injected sensor fault (`inject=sensor-fault`).
    pub const SENSOR_FAULT_TICK: u32 = 2_500;
    /// Interrupts of the naive phase.
    pub const NAIVE_TICKS: u32 = 1_000;
    /// Interrupts of the Everett-bisection phase.
    pub const EVERETT_TICKS: u32 = 1_000;
    /// Interrupts of the relay-grid phase (each costs ~10⁶ instructions).
    pub const RELAY_TICKS: u32 = 200;
    /// TIMER0 period in the relay-grid phase, in instructions.
    pub const RELAY_BUDGET_INSTRUCTIONS: u32 = 1 << 23;
    /// Interrupts of the merge-stress phase (0.4 s of control time: 100 periods at
    /// [`MERGE_STRESS_HZ`], 200 nested reversals into a 64-point staircase).
    pub const MERGE_TICKS: u32 = 4_000;
    /// Frequency of the merge-stress oscillation, Hz.
    pub const MERGE_STRESS_HZ: f32 = 250.0;
    /// Its amplitude decays by this factor over the phase (so every reversal is nested in the
    /// previous one).
    pub const MERGE_STRESS_DECAY: f32 = 400.0;
    /// TIMER0 period in the fast phases, in instructions (≈ 5.5 × the 1,500-instruction goal).
    pub const FAST_BUDGET_INSTRUCTIONS: u32 = 8_192;
    /// TIMER0 period in the naive phase, in instructions.
    pub const NAIVE_BUDGET_INSTRUCTIONS: u32 = 1 << 21;
    /// SysTick ticks per instruction under `-icount shift=10`: 1024 ns × 25 MHz = 25.6 = 128/5.
    const fn budget_ticks(instructions: u32) -> u32 {
        instructions / 5 * 128
    }

    const PHASE_CALIBRATION: u8 = CapturePhase::Calibration.code();
    const PHASE_DYNAMIC: u8 = CapturePhase::Dynamic.code();
    const PHASE_STATIC: u8 = CapturePhase::Static.code();
    const PHASE_NAIVE: u8 = CapturePhase::Naive.code();
    const PHASE_MERGE: u8 = CapturePhase::Merge.code();
    const PHASE_EVERETT: u8 = CapturePhase::EverettBisection.code();
    const PHASE_RELAY: u8 = CapturePhase::RelayGrid.code();
    /// After the last phase (no record carries it).
    const PHASE_DONE: u8 = 7;

    /// `repr(C)` with the baselines' large states last: Thumb loads reach 4 KiB from a base
    /// register, so the fields the controller's own path touches stay within one offset of the
    /// state's address (a 5 KiB relay grid in front of them costs the dynamic phase ~55
    /// instructions per interrupt in address arithmetic).
    #[repr(C)]
    struct App {
        control: ControlLoop<'static>,
        phase: u8,
        tick: u32,
        phase_ticks: u32,
        fast: LoopState<CAPACITY>,
        dac: Dac,
        timer0: CmsdkTimer,
        timer1: CmsdkTimer,
        overruns: u32,
        faults: u32,
        spi_timeouts: u32,
        /// Merges at the end of the merge phase.
        merges: u32,
        /// Desired motion of the next merge-phase interrupt.
        next_desired: DesiredMotion,
        min_ticks: [u32; 7],
        max_ticks: [u32; 7],
        /// `inject=sensor-fault`: the dynamic phase reads a virtual sensor (the desired
        /// displacement, valid) and one out-of-range sample; the run then ends.
        inject_sensor_fault: bool,
        /// Interrupts from the fault until the command first reached 0 A.
        ticks_to_zero: Option<u32>,
        /// A command other than 0 A after it had reached 0, or a command without the flag.
        ramp_violated: bool,
        /// The command at the fault, A.
        current_at_fault_a: f32,
        naive: NaiveLoopState<CAPACITY>,
        relay_core: LoopCore,
        relay: RelayGrid<'static>,
    }

    /// The interrupt's state, handed over by `main` before TIMER0 is unmasked.
    static APP: HandOff<App> = HandOff::new();
    static RING: Ring = Ring::new();
    static DONE: AtomicBool = AtomicBool::new(false);

    /// The control interrupt (TIMER0, IRQ 8).
    ///
    /// **Deadline**: the next TIMER0 expiry, one period after this one (the control period on real
    /// hardware; the instruction budget under QEMU, see the crate docs).
    /// **Overrun**: detected at the end of the handler when TIMER0's interrupt status is already
    /// set again (the timer expired while we were running); it is counted (the count goes into
    /// every record and the exit status). The pending interrupt then runs immediately, i.e. late:
    /// no step is skipped, the DAC update jitters by the overrun.
    /// **Work**: SysTick and TIMER1 read at entry; one `ControlLoop` tick; one DAC frame; SysTick
    /// and TIMER1 read again; one 40-byte record into the ring (the ring push, ~60 instructions of
    /// test instrumentation, is after the second read and not counted). No allocation, no panic
    /// path (proved at link time by the `panic-never` build).
    ///
    /// # Safety
    /// Called only by the hardware through the vector table; it is the only code touching `APP`
    /// once the timer runs (thread mode reads it again only after `DONE` and masking TIMER0).
    #[unsafe(no_mangle)]
    pub unsafe extern "C" fn TIMER0() {
        let systick_entry = SYST::get_current();
        // SAFETY: this interrupt is APP's only user while TIMER0 is unmasked.
        let Some(app) = (unsafe { APP.get_mut() }) else {
            return;
        };
        let timer1_entry = app.timer1.value();
        app.timer0.clear();
        let out = match app.phase {
            PHASE_DYNAMIC if app.inject_sensor_fault => sensor_fault_tick(app),
            PHASE_DYNAMIC => app.control.tick(InverseKind::Dynamic, &mut app.fast),
            PHASE_STATIC => app.control.tick(InverseKind::Static, &mut app.fast),
            PHASE_NAIVE => app.control.tick_naive(InverseKind::Dynamic, &mut app.naive),
            PHASE_MERGE => {
                let desired = app.next_desired;
                app.control
                    .command_with_fast(InverseKind::Dynamic, &mut app.fast, &desired)
            }
            PHASE_EVERETT => everett_tick(app),
            PHASE_RELAY => relay_tick(app),
            _ => {
                app.timer0.stop();
                return;
            }
        };
        let code = match app.dac.write_current(out.current_a) {
            Ok(code) => code,
            Err(_) => {
                app.spi_timeouts = app.spi_timeouts.saturating_add(1);
                DacScale::ZERO_CURRENT_CODE
            }
        };
        #[cfg(feature = "panic-never-canary")]
        {
            // Negative control of the link-time proof: a bounds check the optimizer cannot remove.
            let table = [0u8; 4];
            app.faults += table[(app.tick % 5) as usize] as u32;
        }
        let systick_exit = SYST::get_current();
        let timer1_exit = app.timer1.value();
        if app.timer0.pending() {
            app.overruns = app.overruns.saturating_add(1);
        }
        // SysTick is a 24-bit down counter; TIMER1 (32-bit, same clock) resolves the wraps.
        let short = systick_entry.wrapping_sub(systick_exit) & 0x00FF_FFFF;
        let coarse = timer1_entry.wrapping_sub(timer1_exit);
        let wraps = coarse.wrapping_sub(short).wrapping_add(1 << 23) >> 24;
        let ticks = short.wrapping_add(wraps << 24);
        let slot = app.phase as usize;
        if let Some(m) = app.min_ticks.get_mut(slot) {
            *m = (*m).min(ticks);
        }
        if let Some(m) = app.max_ticks.get_mut(slot) {
            *m = (*m).max(ticks);
        }
        if out.flags.has(magctl::inverse::CommandFlags::FAULT) {
            app.faults = app.faults.saturating_add(1);
        }
        let d = out.desired;
        RING.push(&encode(
            app.phase,
            out.flags.0,
            app.tick,
            ticks,
            [
                out.current_a,
                d.displacement_m,
                d.velocity_m_per_s,
                d.acceleration_m_per_s2,
                out.h_a_per_m,
                out.m_a_per_m,
            ],
            code,
            app.overruns.min(u16::MAX as u32) as u16,
        ));
        app.tick += 1;
        if app.phase == PHASE_MERGE {
            app.next_desired = merge_stress_motion(app.tick);
        }
        if app.tick >= app.phase_ticks {
            next_phase(app);
        }
    }

    /// The merge-stress desired motion at interrupt `tick`: `c + A e^(−t/τ) sin(ω t)` in the
    /// trajectory's band, with its first two derivatives.
    fn merge_stress_motion(tick: u32) -> DesiredMotion {
        let t = &BAKED_PARAMETERS.trajectory;
        let rate_hz = BAKED_PARAMETERS.control.sample_rate_hz;
        let time_s = tick as f32 / rate_hz;
        let tau_s = MERGE_TICKS as f32 / rate_hz / libm::logf(MERGE_STRESS_DECAY);
        let omega = 2.0 * core::f32::consts::PI * MERGE_STRESS_HZ;
        let centre_m = 0.5 * (t.displacement_min_m + t.displacement_max_m);
        let amplitude_m =
            0.45 * (t.displacement_max_m - t.displacement_min_m) * libm::expf(-time_s / tau_s);
        let (sin, cos) = (libm::sinf(omega * time_s), libm::cosf(omega * time_s));
        DesiredMotion {
            displacement_m: centre_m + amplitude_m * sin,
            velocity_m_per_s: amplitude_m * (omega * cos - sin / tau_s),
            acceleration_m_per_s2: amplitude_m
                * ((1.0 / (tau_s * tau_s) - omega * omega) * sin - 2.0 * omega / tau_s * cos),
        }
    }

    /// One dynamic-phase interrupt of the `inject=sensor-fault` run: the sample is the desired
    /// displacement (a valid reading) except at [`SENSOR_FAULT_TICK`], where it is the sensor's
    /// rail; records how the command ramps to 0 A after it.
    #[inline(never)]
    fn sensor_fault_tick(app: &mut App) -> magctl::inverse::TickOutput {
        let sensor = *app.control.sensor();
        let sample = if app.tick == SENSOR_FAULT_TICK {
            sensor.displacement_m(sensor.count_of(1.0))
        } else {
            let y = app
                .control
                .trajectory()
                .motion(&app.fast.core.trajectory)
                .displacement_m;
            sensor.check_m(y)
        };
        let before_a = app.fast.core.last_current_a;
        let out = app
            .control
            .tick_sensed(InverseKind::Dynamic, &mut app.fast, sample);
        if app.tick == SENSOR_FAULT_TICK {
            app.current_at_fault_a = before_a;
        }
        if app.tick >= SENSOR_FAULT_TICK {
            let flagged = out.flags.has(magctl::inverse::CommandFlags::SENSOR_FAULT);
            match app.ticks_to_zero {
                Some(_) if out.current_a != 0.0 => app.ramp_violated = true,
                None if out.current_a == 0.0 => {
                    app.ticks_to_zero = Some(app.tick - SENSOR_FAULT_TICK + 1)
                }
                _ => {}
            }
            if !flagged {
                app.ramp_violated = true;
            }
        }
        out
    }

    /// One interrupt with the Everett-bisection baseline (out of line, so that the baselines do
    /// not change how the compiler lays out the controller's own path).
    #[inline(never)]
    fn everett_tick(app: &mut App) -> magctl::inverse::TickOutput {
        let mut inverter = EverettBisectionInverter {
            measure: &BAKED_MEASURE,
            state: &mut app.fast.preisach,
        };
        app.control
            .tick_with(InverseKind::Dynamic, &mut inverter, &mut app.fast.core)
    }

    /// One interrupt with the relay-grid baseline (out of line, as above).
    #[inline(never)]
    fn relay_tick(app: &mut App) -> magctl::inverse::TickOutput {
        let mut inverter = RelayGridInverter {
            grid: &mut app.relay,
        };
        app.control
            .tick_with(InverseKind::Dynamic, &mut inverter, &mut app.relay_core)
    }

    fn next_phase(app: &mut App) {
        app.tick = 0;
        match app.phase {
            PHASE_DYNAMIC if app.inject_sensor_fault => {
                app.phase = PHASE_DONE;
                app.timer0.stop();
                DONE.store(true, Ordering::Release);
            }
            PHASE_DYNAMIC => {
                app.phase = PHASE_STATIC;
                app.fast = app.control.init(InverseKind::Static);
                app.timer0
                    .start(budget_ticks(FAST_BUDGET_INSTRUCTIONS), true);
            }
            PHASE_STATIC => {
                app.phase = PHASE_MERGE;
                app.phase_ticks = MERGE_TICKS;
                app.fast = app.control.init(InverseKind::Dynamic);
                app.next_desired = merge_stress_motion(0);
                app.timer0
                    .start(budget_ticks(FAST_BUDGET_INSTRUCTIONS), true);
            }
            PHASE_MERGE => {
                app.merges = app.fast.preisach.merges();
                app.phase = PHASE_NAIVE;
                app.phase_ticks = NAIVE_TICKS;
                app.naive = app.control.init_naive(InverseKind::Dynamic);
                app.timer0
                    .start(budget_ticks(NAIVE_BUDGET_INSTRUCTIONS), true);
            }
            PHASE_NAIVE => {
                app.phase = PHASE_EVERETT;
                app.phase_ticks = EVERETT_TICKS;
                app.fast = app.control.init(InverseKind::Dynamic);
                app.timer0
                    .start(budget_ticks(NAIVE_BUDGET_INSTRUCTIONS), true);
            }
            PHASE_EVERETT => {
                app.phase = PHASE_RELAY;
                app.phase_ticks = RELAY_TICKS;
                app.relay = RelayGrid::new(&BAKED_MEASURE);
                app.relay_core = app.control.initial_core(
                    InverseKind::Dynamic,
                    &mut RelayGridInverter {
                        grid: &mut app.relay,
                    },
                );
                app.timer0
                    .start(budget_ticks(RELAY_BUDGET_INSTRUCTIONS), true);
            }
            _ => {
                app.phase = PHASE_DONE;
                app.timer0.stop();
                DONE.store(true, Ordering::Release);
            }
        }
    }

    /// SysTick ticks spent on `N` back-to-back `nop`s plus the two reads around them.
    #[inline(always)]
    fn time_nops_1024() -> u32 {
        let a = SYST::get_current();
        unsafe { core::arch::asm!(".rept 1024", "nop", ".endr", options(nomem, nostack)) };
        let b = SYST::get_current();
        a.wrapping_sub(b) & 0x00FF_FFFF
    }

    #[inline(always)]
    fn time_nops_2048() -> u32 {
        let a = SYST::get_current();
        unsafe { core::arch::asm!(".rept 2048", "nop", ".endr", options(nomem, nostack)) };
        let b = SYST::get_current();
        a.wrapping_sub(b) & 0x00FF_FFFF
    }

    /// Instructions of one dynamic-model step (`magctl::model::DynamicModel::step`, the
    /// figure) on this core: 2000 steps of a 0.5 ± 0.45 A, 200 Hz sine at the control rate from the
    /// demagnetized state, each timed with SysTick minus the cost of the two reads
    /// (`read_overhead_ticks`, from the calibration). Returns (min, mean, max) instructions.
    /// Kept out of line: inlined into `main` beside the `nop` blocks it overflows a literal pool.
    #[inline(never)]
    fn measure_model_step(read_overhead_ticks: u32) -> (u32, u32, u32) {
        let step_s = 1.0 / BAKED_PARAMETERS.control.sample_rate_hz;
        let model = DynamicModel::new(&BAKED_MEASURE, &BAKED_PARAMETERS.actuator, step_s);
        let mut state = model.equilibrium::<64>(BAKED_MEASURE.demagnetized(), 0.5);
        let (mut min, mut max, mut sum) = (u32::MAX, 0u32, 0u64);
        const STEPS: u32 = 2000;
        for k in 0..STEPS {
            let phase = 2.0 * core::f32::consts::PI * 200.0 * step_s * k as f32;
            let current_a = core::hint::black_box(0.5 + 0.45 * libm::sinf(phase));
            let a = SYST::get_current();
            core::hint::black_box(model.step(&mut state, current_a));
            let b = SYST::get_current();
            let ticks = (a.wrapping_sub(b) & 0x00FF_FFFF).saturating_sub(read_overhead_ticks);
            let instructions = (ticks as f32 / 25.6) as u32;
            min = min.min(instructions);
            max = max.max(instructions);
            sum += instructions as u64;
        }
        (min, (sum / STEPS as u64) as u32, max)
    }

    /// Instructions per stage of the dynamic-inverse interrupt (trajectory step, inverse,
    /// limiter, DAC frame): 2,000 control steps run stage by stage in thread mode from a fresh
    /// state, each stage timed with SysTick minus the cost of the two reads. Returns
    /// `[min, mean, max]` per stage. Out of line for the same reason as [`measure_model_step`].
    #[inline(never)]
    fn measure_stages(
        read_overhead_ticks: u32,
        control: &ControlLoop<'static>,
        dac: &mut Dac,
    ) -> [[u32; 3]; 4] {
        let mut state: LoopState<CAPACITY> = control.init(InverseKind::Dynamic);
        let mut stats = [[u32::MAX, 0, 0]; 4];
        let mut sums = [0u64; 4];
        const STEPS: u32 = 2000;
        let instructions = |a: u32, b: u32| {
            ((a.wrapping_sub(b) & 0x00FF_FFFF).saturating_sub(read_overhead_ticks) as f32 / 25.6)
                as u32
        };
        for _ in 0..STEPS {
            let t0 = SYST::get_current();
            let desired = control.trajectory().step(&mut state.core.trajectory);
            let t1 = SYST::get_current();
            let mut inverter = magctl::inverse::FastInverter::<CAPACITY> {
                measure: &BAKED_MEASURE,
                state: &mut state.preisach,
            };
            let raw = control.dynamic().raw_command(
                &mut inverter,
                &mut state.core.memory,
                core::hint::black_box(&desired),
            );
            let t2 = SYST::get_current();
            let (current_a, _) = control
                .limiter()
                .apply(&mut state.core.last_current_a, core::hint::black_box(&raw));
            let t3 = SYST::get_current();
            let _ = dac.write_current(core::hint::black_box(current_a));
            let t4 = SYST::get_current();
            for (k, (a, b)) in [(t0, t1), (t1, t2), (t2, t3), (t3, t4)]
                .into_iter()
                .enumerate()
            {
                let n = instructions(a, b);
                if let (Some(st), Some(sum)) = (stats.get_mut(k), sums.get_mut(k)) {
                    st[0] = st[0].min(n);
                    st[2] = st[2].max(n);
                    *sum += n as u64;
                }
            }
        }
        for (st, sum) in stats.iter_mut().zip(sums) {
            st[1] = (sum / STEPS as u64) as u32;
        }
        stats
    }

    /// Handles `inject=hardfault` / `inject=panic` (they do not return); returns whether
    /// `inject=sensor-fault` was asked for.
    fn inject_faults_from_command_line() -> bool {
        let mut buf = [0u8; 128];
        let n = semihosting::command_line(&mut buf);
        let args = CommandLine::new(buf.get(..n).unwrap_or(&[]));
        let inject = args
            .check(&[b"inject"])
            .and_then(|()| args.choice(b"inject", &[b"sensor-fault", b"hardfault", b"panic"]));
        let inject = match inject {
            Ok(v) => v,
            Err(e) => {
                defmt::error!("command line: cannot use `{=[u8]:a}`", e.word());
                semihosting::exit(4)
            }
        };
        match inject {
            Some(0) => {
                defmt::info!(
                    "fault injection: an out-of-range sensor sample at dynamic-phase interrupt {=u32} (expect exit status 7)",
                    SENSOR_FAULT_TICK
                );
                return true;
            }
            Some(1) => {
                defmt::info!("fault injection: executing UDF (expect exit status 102)");
                cortex_m::asm::udf();
            }
            #[cfg(not(feature = "panic-never"))]
            Some(2) => {
                defmt::info!("fault injection: panicking (expect exit status 101)");
                core::panic!("injected panic");
            }
            _ => {}
        }
        false
    }

    fn drain(file: HostFile, chunk: &mut [Record; 32]) -> usize {
        let n = RING.pop_into(chunk);
        for r in chunk.iter().take(n) {
            if !file.write_all(r) {
                semihosting::exit(6);
            }
        }
        n
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        // First: the stack's high-water mark is measured against this paint.
        magctl::board::stack::paint();
        // Then the guard below the stack: an overflow faults instead of overwriting the statics.
        magctl::board::stack::guard();
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            semihosting::exit(4)
        };
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(0x00FF_FFFF);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();
        defmt::info!(
            "magctl firmware on mps2-an386: control rate {=f32} Hz",
            BAKED_PARAMETERS.control.sample_rate_hz
        );
        let inject_sensor_fault = inject_faults_from_command_line();

        let Some(file) = semihosting::create(b"qemu_capture.bin\0") else {
            defmt::error!("cannot open the capture file on the host");
            semihosting::exit(6)
        };
        let read_overhead_ticks = calibrate(file);
        let control = match ControlLoop::new(&BAKED_MEASURE, &BAKED_PARAMETERS) {
            // The injection run checks the feedback-off fault path (ramp to 0 A); the
            // feedback's own fallback is checked on the virtual bench (`cargo xtask hil`).
            Ok(c) if inject_sensor_fault => {
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
        let stages = measure_stages(read_overhead_ticks, &control, &mut dac);
        for (name, st) in ["trajectory", "inverse", "limiter", "dac"]
            .iter()
            .zip(stages)
        {
            defmt::info!(
                "stage {=str}: instructions min {=u32} mean {=u32} max {=u32}",
                name,
                st[0],
                st[1],
                st[2]
            );
        }
        if dac.write_current(0.0).is_err() {
            semihosting::exit(6)
        }
        let fast_ticks = BAKED_PARAMETERS.control.sample_rate_hz as u32; // one second
        let app = App {
            control,
            phase: PHASE_DYNAMIC,
            tick: 0,
            phase_ticks: fast_ticks,
            fast: control.init(InverseKind::Dynamic),
            naive: control.init_naive(InverseKind::Dynamic),
            relay: RelayGrid::new(&BAKED_MEASURE),
            relay_core: control.init::<CAPACITY>(InverseKind::Dynamic).core,
            dac,
            timer0: unsafe { CmsdkTimer::new(TIMER0_BASE) },
            timer1: unsafe { CmsdkTimer::new(TIMER1_BASE) },
            overruns: 0,
            faults: 0,
            spi_timeouts: 0,
            merges: 0,
            next_desired: merge_stress_motion(0),
            min_ticks: [u32::MAX; 7],
            max_ticks: [0; 7],
            inject_sensor_fault,
            ticks_to_zero: None,
            ramp_violated: false,
            current_at_fault_a: 0.0,
        };
        defmt::info!(
            "trajectory: Van der Pol mu {=f32}, {=f32} Hz scale, peak x {=f32}; {=u32} + {=u32} + {=u32} + {=u32} + {=u32} + {=u32} interrupts",
            BAKED_PARAMETERS.trajectory.van_der_pol_mu,
            BAKED_PARAMETERS.trajectory.frequency_scale_hz,
            app.control.trajectory().peak_x(),
            fast_ticks,
            fast_ticks,
            MERGE_TICKS,
            NAIVE_TICKS,
            EVERETT_TICKS,
            RELAY_TICKS
        );
        let mut app = app;
        app.timer1.start(u32::MAX, false);
        app.timer0
            .start(budget_ticks(FAST_BUDGET_INSTRUCTIONS), true);
        if APP.give(app).is_err() {
            semihosting::exit(4)
        }
        // SAFETY: APP is published (release) before the interrupt can run.
        unsafe { NVIC::unmask(Timer0Irq) };

        let mut chunk = [[0u8; 40]; 32];
        loop {
            if drain(file, &mut chunk) > 0 {
                continue;
            }
            if DONE.load(Ordering::Acquire) && RING.is_empty() {
                break;
            }
            cortex_m::interrupt::free(|_| {
                if RING.is_empty() && !DONE.load(Ordering::Acquire) {
                    cortex_m::asm::wfi();
                }
            });
        }
        NVIC::mask(Timer0Irq);
        file.close();
        report_and_exit()
    }

    /// The instruction counter's calibration (1024 extra `nop`s between two measurements, the
    /// phase-0 record) and the model step's cost; returns the SysTick ticks the two reads around
    /// a measured block cost.
    fn calibrate(file: semihosting::HostFile) -> u32 {
        // Calibration: 1024 extra instructions between the two measurements.
        let one = time_nops_1024();
        let two = time_nops_2048();
        let diff = two.wrapping_sub(one);
        defmt::info!(
            "calibration: 1024 nops = {=u32} SysTick ticks (expect 26214 = 1024 x 25.6)",
            diff
        );
        // The two SysTick reads around a measured block: what 1024 nops cost beyond 1024 x 25.6.
        let read_overhead_ticks = one.saturating_sub(26_214);
        let (step_min, step_mean, step_max) = measure_model_step(read_overhead_ticks);
        defmt::info!(
            "model step (DynamicModel::step, 200 Hz sine, 2000 steps): instructions min {=u32} mean {=u32} max {=u32}",
            step_min,
            step_mean,
            step_max
        );
        let mut cal = encode(PHASE_CALIBRATION, 0, 1024, diff, [0.0; 6], 0, 0);
        cal[4..8].copy_from_slice(&1024u32.to_le_bytes());
        if !file.write_all(&cal) {
            semihosting::exit(6);
        }

        read_overhead_ticks
    }

    /// The run's counts, and its exit status: 0 after the four phases with nothing dropped,
    /// overrun, faulted or timed out and at least one merge; 7 after an injected sensor fault
    /// ramped to 0 A within the slew limit; 3 otherwise.
    fn report_and_exit() -> ! {
        defmt::info!(
            "stack: high-water {=u32} B of the {=u32} B between the statics and the top of RAM",
            magctl::board::stack::high_water_bytes() as u32,
            magctl::board::stack::region_bytes() as u32
        );
        let dropped = RING.dropped.load(Ordering::Relaxed);
        // SAFETY: TIMER0 is masked and stopped: thread mode is APP's only user now.
        let Some(app) = (unsafe { APP.get_mut() }) else {
            semihosting::exit(4)
        };
        if app.inject_sensor_fault {
            let step_a = app.control.limiter().max_step_a();
            let allowed = libm::ceilf(libm::fabsf(app.current_at_fault_a) / step_a) as u32 + 1;
            let ticks = app.ticks_to_zero.unwrap_or(u32::MAX);
            defmt::info!(
                "sensor fault: {=f32} A at the fault, 0 A after {=u32} interrupts (slew limit allows {=u32}), held and flagged: {=bool}",
                app.current_at_fault_a,
                ticks,
                allowed,
                !app.ramp_violated
            );
            let ok = ticks <= allowed && !app.ramp_violated && app.current_at_fault_a != 0.0;
            semihosting::exit(if ok { 7 } else { 3 })
        }
        let c = &app.fast.core.counters;
        for (name, k) in [
            ("dynamic", 1usize),
            ("static", 2),
            ("merge", 4),
            ("naive", 3),
            ("everett-bisection", 5),
            ("relay-grid", 6),
        ] {
            let lo = app.min_ticks.get(k).copied().unwrap_or(0);
            let hi = app.max_ticks.get(k).copied().unwrap_or(0);
            defmt::info!(
                "{=str}: SysTick ticks per interrupt min {=u32} max {=u32} (instructions ~ ticks / 25.6)",
                name,
                lo,
                hi
            );
        }
        defmt::info!(
            "static phase counters: u clamped {=u32}, current limited {=u32}, slew limited {=u32}",
            c.u_clamped,
            c.current_limited,
            c.slew_limited
        );
        defmt::info!(
            "merge phase: {=u32} merges in {=u32} interrupts (staircase capacity {=u32})",
            app.merges,
            MERGE_TICKS,
            CAPACITY as u32
        );
        defmt::info!(
            "overruns {=u32}, dropped records {=u32}, faults {=u32}, SPI timeouts {=u32}, log bytes dropped {=u32}",
            app.overruns,
            dropped,
            app.faults,
            app.spi_timeouts,
            magctl::board::semihosting::logger::DROPPED_BYTES.load(Ordering::Relaxed)
        );
        let ok = app.overruns == 0
            && dropped == 0
            && app.faults == 0
            && app.spi_timeouts == 0
            && app.merges > 0;
        semihosting::exit(if ok { 0 } else { 3 })
    }
}
