//! Control firmware for the NUCLEO-F446RE (STM32F446RE, Cortex-M4F at 180 MHz).
//!
//! TIM2's update interrupt fires at the JSON's control rate (`control.sample_rate_hz`, 10 kHz by
//! default) and runs one control step — Van der Pol trajectory → dynamic inverse → output limiter
//! — with the same `magctl::inverse::ControlLoop` as the QEMU firmware and the host, then writes
//! the current command to the SPI DAC (`magctl::output::SpiDac` over embedded-hal, SPI1 + PB6
//! chip select; wiring in `magctl::board::nucleo_f446re`). Thread mode logs a status line over
//! RTT (defmt) once per second of control time: interrupts run, cycles per interrupt (DWT cycle
//! counter, min / max), overruns, limiter and fault counters.
//!
//! Flash and run with probe-rs (`probe-rs run --chip STM32F446RETx <elf>`, see README); the
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
    use core::ptr::addr_of_mut;
    use core::sync::atomic::{AtomicU32, Ordering};
    use cortex_m::peripheral::DWT;
    use embedded_hal_bus::spi::{ExclusiveDevice, NoDelay};
    use magctl::board::nucleo_f446re::spi::{ChipSelect, Spi1};
    use magctl::board::nucleo_f446re::timer::ControlTimer;
    use magctl::board::nucleo_f446re::{clocks, rtt, spi};
    use magctl::inverse::{CommandFlags, ControlLoop, InverseKind, LoopState};
    use magctl::output::{CurrentOutput, DacScale, SpiDac};
    use magctl::params::{BAKED_MEASURE, BAKED_PARAMETERS};
    use stm32f4::stm32f446::{self as pac, interrupt, Interrupt};

    /// Preisach memory capacity (reversal points) of the controller.
    const CAPACITY: usize = magctl::preisach::DEFAULT_CAPACITY;
    /// The inverse the interrupt runs (the paper's Figure 7 controller; `InverseKind::Static`
    /// gives the Figure 8 baseline).
    const INVERSE: InverseKind = InverseKind::Dynamic;

    type Dac = SpiDac<ExclusiveDevice<Spi1, ChipSelect, NoDelay>>;

    struct App {
        control: ControlLoop<'static>,
        state: LoopState<CAPACITY>,
        dac: Dac,
        timer: ControlTimer,
    }

    static mut APP: Option<App> = None;

    /// Interrupts run.
    static TICKS: AtomicU32 = AtomicU32::new(0);
    /// Interrupts that ended after the next timer update was already pending.
    static OVERRUNS: AtomicU32 = AtomicU32::new(0);
    /// Failed DAC writes (SPI error).
    static DAC_ERRORS: AtomicU32 = AtomicU32::new(0);
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
    /// **Work**: one `ControlLoop` tick (the QEMU run measures ≤ 1,500 instructions for it plus
    /// the DAC frame), one 24-bit SPI frame (2.1 µs at 11.25 MHz), counter updates. No allocation,
    /// no logging, no panic path (link-time proof with `--features panic-never`).
    #[interrupt]
    fn TIM2() {
        let entry = DWT::cycle_count();
        let app = match unsafe { (*addr_of_mut!(APP)).as_mut() } {
            Some(app) => app,
            None => return,
        };
        app.timer.clear();
        let out = app.control.tick(INVERSE, &mut app.state);
        if app.dac.write_current(out.current_a).is_err() {
            DAC_ERRORS.fetch_add(1, Ordering::Relaxed);
        }
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
        clocks::init(&dp.RCC, &dp.PWR, &dp.FLASH);
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();

        let p = &BAKED_PARAMETERS;
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
        let Some(scale) = DacScale::new(p.control.current_limit_a) else {
            halt("invalid control.current_limit_a")
        };

        let (spi, cs) = spi::init(&dp.RCC);
        let Ok(device) = ExclusiveDevice::new_no_delay(spi, cs);
        let mut dac = SpiDac::new(device, scale);
        let state = control.init::<CAPACITY>(INVERSE);
        // Start from the controller's initial current (the static current of the first sample).
        if dac.write_current(state.core.last_current_a).is_err() {
            halt("DAC write failed");
        }

        let rate_hz = p.control.sample_rate_hz as u32;
        let Some(timer) = ControlTimer::new(&dp.RCC, rate_hz) else {
            halt("TIM2 cannot run at the control rate (must divide 90 MHz)")
        };
        unsafe {
            *addr_of_mut!(APP) = Some(App {
                control,
                state,
                dac,
                timer,
            });
            cortex_m::peripheral::NVIC::unmask(Interrupt::TIM2);
        }

        let mut next_report = rate_hz;
        loop {
            cortex_m::asm::wfi();
            let ticks = TICKS.load(Ordering::Relaxed);
            if ticks >= next_report {
                next_report = next_report.wrapping_add(rate_hz);
                defmt::info!(
                    "{=u32} interrupts; cycles/interrupt min {=u32} max {=u32}; overruns {=u32}; u clamped {=u32}, current limited {=u32}, slew limited {=u32}, faults {=u32}, DAC errors {=u32}, log bytes dropped {=u32}",
                    ticks,
                    MIN_CYCLES.load(Ordering::Relaxed),
                    MAX_CYCLES.load(Ordering::Relaxed),
                    OVERRUNS.load(Ordering::Relaxed),
                    FLAGGED[0].load(Ordering::Relaxed),
                    FLAGGED[1].load(Ordering::Relaxed),
                    FLAGGED[2].load(Ordering::Relaxed),
                    FLAGGED[3].load(Ordering::Relaxed),
                    DAC_ERRORS.load(Ordering::Relaxed),
                    rtt::DROPPED_BYTES.load(Ordering::Relaxed)
                );
            }
        }
    }
}
