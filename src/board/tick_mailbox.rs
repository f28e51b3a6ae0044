//! The lock-step bench's hand-over of one tick between thread mode and the control interrupt:
//! thread mode posts the plant's sample and pends the interrupt, the interrupt takes the sample
//! and posts its command, thread mode reads the command back for the link's frame. Used by both
//! QEMU benches (`firmware-hil` on `mps2-an386`, the NUCLEO image's emulator build).
//!
//! Lock-free and panic-free: each field is an atomic; the sample's kind is published with
//! release after its payload, the command's `ready` flag with release after the command, and
//! each side reads them with acquire. One tick is in flight at a time (thread mode waits for the
//! interrupt it pended), so no field is overwritten while the other side reads it.

use crate::inverse::TickOutput;
use crate::link::{CommandFrame, Sample, KIND_COMMAND, KIND_SAMPLE_COUNT, KIND_SAMPLE_METRES};
use core::sync::atomic::{AtomicBool, AtomicU16, AtomicU32, AtomicU8, Ordering};

/// One tick's sample (thread mode → interrupt) and command (interrupt → thread mode).
pub struct TickMailbox {
    /// The sample's frame kind, 0 when the sample is missing.
    sample_kind: AtomicU8,
    sample_bits: AtomicU32,
    /// The coil current read on the sample's trigger (f32 bits), valid when `coil_current_read`.
    coil_current_bits: AtomicU32,
    coil_current_read: AtomicBool,
    current_bits: AtomicU32,
    desired_bits: AtomicU32,
    flags: AtomicU8,
    aux: AtomicU16,
    ready: AtomicBool,
}

impl Default for TickMailbox {
    fn default() -> Self {
        Self::new()
    }
}

impl TickMailbox {
    /// An empty mailbox (for a `static`).
    pub const fn new() -> Self {
        TickMailbox {
            sample_kind: AtomicU8::new(0),
            sample_bits: AtomicU32::new(0),
            coil_current_bits: AtomicU32::new(0),
            coil_current_read: AtomicBool::new(false),
            current_bits: AtomicU32::new(0),
            desired_bits: AtomicU32::new(0),
            flags: AtomicU8::new(0),
            aux: AtomicU16::new(0),
            ready: AtomicBool::new(false),
        }
    }

    /// Thread mode: the coming tick's sample (`None`: missing) and the coil current read on its
    /// trigger (`None`: not measured); clears the last command.
    pub fn post_sample(&self, sample: Option<Sample>, coil_current_a: Option<f32>) {
        let (kind, bits) = match sample {
            Some(Sample::Count(c)) => (KIND_SAMPLE_COUNT, c),
            Some(Sample::Metres(m)) => (KIND_SAMPLE_METRES, m.to_bits()),
            None => (0, 0),
        };
        self.ready.store(false, Ordering::Relaxed);
        self.sample_bits.store(bits, Ordering::Relaxed);
        self.coil_current_bits
            .store(coil_current_a.unwrap_or(0.0).to_bits(), Ordering::Relaxed);
        self.coil_current_read
            .store(coil_current_a.is_some(), Ordering::Relaxed);
        self.sample_kind.store(kind, Ordering::Release);
    }

    /// The interrupt: the coil current read on the tick's trigger (`None`: not measured). Read
    /// after [`sample`](Self::sample), whose acquire orders it.
    #[inline(always)]
    pub fn coil_current_a(&self) -> Option<f32> {
        self.coil_current_read
            .load(Ordering::Relaxed)
            .then(|| f32::from_bits(self.coil_current_bits.load(Ordering::Relaxed)))
    }

    /// The interrupt: the tick's sample (`None`: missing).
    #[inline(always)]
    pub fn sample(&self) -> Option<Sample> {
        let kind = self.sample_kind.load(Ordering::Acquire);
        let bits = self.sample_bits.load(Ordering::Relaxed);
        match kind {
            KIND_SAMPLE_COUNT => Some(Sample::Count(bits)),
            KIND_SAMPLE_METRES => Some(Sample::Metres(f32::from_bits(bits))),
            _ => None,
        }
    }

    /// The interrupt: the tick's command and its `aux` word (the handler's instruction count on
    /// `mps2-an386`, 0 where it is not counted).
    #[inline(always)]
    pub fn post_command(&self, out: &TickOutput, aux: u16) {
        self.current_bits
            .store(out.current_a.to_bits(), Ordering::Relaxed);
        self.desired_bits
            .store(out.desired.displacement_m.to_bits(), Ordering::Relaxed);
        self.flags.store(out.flags.0, Ordering::Relaxed);
        self.aux.store(aux, Ordering::Relaxed);
        self.ready.store(true, Ordering::Release);
    }

    /// Thread mode: the command frame of tick `seq`, `None` if the interrupt has not posted one
    /// since the sample.
    pub fn command(&self, seq: u16) -> Option<CommandFrame> {
        self.ready.load(Ordering::Acquire).then(|| CommandFrame {
            kind: KIND_COMMAND,
            seq,
            value: f32::from_bits(self.current_bits.load(Ordering::Relaxed)),
            desired_m: f32::from_bits(self.desired_bits.load(Ordering::Relaxed)),
            flags: self.flags.load(Ordering::Relaxed),
            aux: self.aux.load(Ordering::Relaxed),
            aux32: 0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inverse::CommandFlags;
    use crate::trajectory::DesiredMotion;

    fn output(current_a: f32) -> TickOutput {
        TickOutput {
            desired: DesiredMotion {
                displacement_m: 1e-5,
                velocity_m_per_s: 0.0,
                acceleration_m_per_s2: 0.0,
            },
            current_a,
            h_a_per_m: 0.0,
            m_a_per_m: 0.0,
            flags: CommandFlags(CommandFlags::CONDITIONING),
        }
    }

    #[test]
    fn a_tick_goes_through_and_a_new_sample_clears_the_command() {
        let m = TickMailbox::new();
        for (sample, coil_current_a) in [
            (Some(Sample::Count(1234)), None),
            (Some(Sample::Metres(2.5e-6)), Some(0.75)),
            (None, None),
        ] {
            m.post_sample(sample, coil_current_a);
            assert_eq!(m.sample(), sample);
            assert_eq!(m.coil_current_a(), coil_current_a);
            assert_eq!(
                m.command(7),
                None,
                "no command before the interrupt posts one"
            );
            m.post_command(&output(0.5), 900);
            let c = m.command(7).expect("posted");
            assert_eq!(
                (c.kind, c.seq, c.value, c.flags, c.aux),
                (KIND_COMMAND, 7, 0.5, CommandFlags::CONDITIONING, 900)
            );
            assert_eq!(c.desired_m, 1e-5);
        }
    }
}
