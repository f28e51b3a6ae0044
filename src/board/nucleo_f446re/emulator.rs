//! The NUCLEO image's emulator build (feature `emulator-netduinoplus2`): the virtual bench's
//! plant link (`magctl::link`, `docs/hil.md`) on USART2 (PA2/PA3, the ST-LINK's virtual COM
//! port on the NUCLEO; QEMU `netduinoplus2`'s second serial port), polled, every wait bounded.
//!
//! In this build the control interrupt takes its sensor sample from the link instead of ADC1
//! (QEMU's STM32 ADC returns a counter): [`PlantLink::sample`] waits for the plant's frame of
//! the tick, [`PlantLink::send_command`] answers with the command. The plant is then the clock:
//! the interrupt restarts TIM2's period when the frame has arrived
//! (`ControlTimer::restart_period`), so the overrun check measures the handler's own work, not
//! the host's latency. After a link fault the link gives `Missing` at once and the interrupt
//! runs on TIM2 alone, as on the board when the ADC stops answering.
//!
//! USART registers (RM0390 §25.6, the same on the F405): SR (RXNE bit 5, TXE bit 7), DR, CR1
//! (UE bit 13, TE bit 3, RE bit 2). The baud rate is left at its reset value: the emulator's
//! character device does not use it.

use crate::link::{CommandFrame, EndAck, EndAckWatch, Sample, SampleAssembler, SampleFrame};
use stm32f4::stm32f446 as pac;

const APB1ENR_USART2EN: u32 = 1 << 17;
const AHB1ENR_GPIOAEN: u32 = 1 << 0;
/// Alternate function 7 = USART2 on PA2 (TX) and PA3 (RX).
const AF_USART2: u32 = 7;
const SR_RXNE: u16 = 1 << 5;
const SR_TXE: u16 = 1 << 7;
const CR1_UE_TE_RE: u16 = (1 << 13) | (1 << 3) | (1 << 2);

/// Polls of the receive flag per sample frame before the link counts as silent. Each poll is a
/// device access, which QEMU serves outside its translated code (about 3.5 µs of host time on
/// the CI machine): about 4 s, where a plant answers within milliseconds.
pub const MAX_LINK_POLLS: u32 = 1 << 20;
/// The same bound for the first frame (the plant program's start-up: about a minute).
pub const MAX_FIRST_LINK_POLLS: u32 = 1 << 24;
/// Polls of the transmit flag per byte.
pub const MAX_TX_POLLS: u32 = 1 << 16;

/// The plant link on USART2.
pub struct PlantLink {
    regs: &'static pac::usart1::RegisterBlock,
    assembler: SampleAssembler,
    /// The tick whose sample comes next.
    seq: u16,
    /// The link has failed (a silent link or a bad frame): no more waiting.
    failed: bool,
}

// SAFETY: the handle is the only user of USART2 (see its constructor); moving it to the
// interrupt that uses it (through `HandOff`) moves that ownership.
unsafe impl Send for PlantLink {}

impl PlantLink {
    /// Enables USART2 on PA2/PA3 (8N1, transmitter and receiver). Call once.
    pub fn new(rcc: &pac::RCC) -> Self {
        // SAFETY: fixed peripheral addresses; USART2 and PA2/PA3 have no other user.
        let regs: &'static pac::usart1::RegisterBlock = unsafe { &*pac::USART2::ptr() };
        let gpioa: &'static pac::gpioa::RegisterBlock = unsafe { &*pac::GPIOA::ptr() };
        // SAFETY (all `bits` writes): field values from RM0390, documented above.
        rcc.ahb1enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | AHB1ENR_GPIOAEN) });
        rcc.apb1enr()
            .modify(|r, w| unsafe { w.bits(r.bits() | APB1ENR_USART2EN) });
        gpioa.afrl().modify(|r, w| unsafe {
            w.bits((r.bits() & !(0xFF << 8)) | (AF_USART2 << 8) | (AF_USART2 << 12))
        });
        gpioa
            .moder()
            .modify(|r, w| unsafe { w.bits((r.bits() & !(0xF << 4)) | (0b1010 << 4)) });
        regs.cr1().write(|w| unsafe { w.bits(CR1_UE_TE_RE) });
        PlantLink {
            regs,
            assembler: SampleAssembler::new(),
            seq: 0,
            failed: false,
        }
    }

    /// Whether the link has failed.
    pub fn failed(&self) -> bool {
        self.failed
    }

    fn try_read(&mut self) -> Option<u8> {
        if self.regs.sr().read().bits() & SR_RXNE != 0 {
            Some(self.regs.dr().read().bits() as u8)
        } else {
            None
        }
    }

    fn write_all(&mut self, bytes: &[u8], max_polls: u32) -> bool {
        for &b in bytes {
            let mut ready = false;
            for _ in 0..max_polls {
                if self.regs.sr().read().bits() & SR_TXE != 0 {
                    ready = true;
                    break;
                }
            }
            if !ready {
                return false;
            }
            // SAFETY: a byte into the data register.
            self.regs.dr().write(|w| unsafe { w.bits(b as u16) });
        }
        true
    }

    /// The plant's sample of the coming tick, waiting at most [`MAX_LINK_POLLS`] polls
    /// ([`MAX_FIRST_LINK_POLLS`] for the first); `None` once the link has failed (silent, a
    /// wrong sync byte, kind or sequence number: `docs/hil.md`, "Faults").
    pub fn sample(&mut self) -> Option<Sample> {
        if self.failed {
            return None;
        }
        let polls = if self.seq == 0 {
            MAX_FIRST_LINK_POLLS
        } else {
            MAX_LINK_POLLS
        };
        for _ in 0..polls {
            if let Some(frame) = self.try_read().and_then(|b| self.assembler.push(b)) {
                return self.decoded(frame.as_slice());
            }
        }
        self.failed = true;
        None
    }

    /// The sample of a received frame (a coil current in it is not used: the tracking image
    /// reads the displacement only).
    fn decoded(&mut self, frame: &[u8]) -> Option<Sample> {
        match SampleFrame::decode(frame, self.seq) {
            Ok(f) => {
                self.seq = self.seq.wrapping_add(1);
                Some(f.sample)
            }
            Err(_) => {
                self.failed = true;
                None
            }
        }
    }

    /// Sends a command frame (`B`, `C` or `E`); after a link fault only one short try (the
    /// plant may be gone).
    pub fn send_command(&mut self, frame: &CommandFrame) {
        let polls = if self.failed { 64 } else { MAX_TX_POLLS };
        if !self.write_all(&frame.encode(), polls) {
            self.failed = true;
        }
    }

    /// Waits at most [`MAX_LINK_POLLS`] polls for the bench host's acknowledgement of the `E`
    /// frame (`magctl::link::EndAck`), dropping whatever else arrives; whether it came.
    pub fn await_end_ack(&mut self, ack: EndAck) -> bool {
        let mut watch = EndAckWatch::new(ack);
        for _ in 0..MAX_LINK_POLLS {
            if self.try_read().is_some_and(|b| watch.push(b)) {
                return true;
            }
        }
        false
    }
}
