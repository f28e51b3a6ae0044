//! The measurement record: what the firmware streams to the host while it plays the
//! identification programme itself ([`crate::programme`]) — every tick's applied current, its
//! reading of the displacement sensor and the command flags — packed into batches that thread
//! mode logs with defmt (`MEAS <first tick> <bytes>`; over RTT on the NUCLEO, semihosting under
//! QEMU). The host recorder (`cargo xtask record`) decodes the lines with [`decode_batch`] and
//! writes the dataset folder.
//!
//! The interrupt never logs: it pushes a [`MeasuredSample`] into a bounded single-producer
//! single-consumer ring ([`RecordQueue`]: a power-of-two capacity and two atomic counters —
//! `heapless::spsc` was the first choice, but its index arithmetic divides by a run-time
//! capacity, a panic path the firmware's link-time no-panic proof rejects), never waiting; when the queue is full
//! (the host is not draining the log fast enough) the push fails, the firmware counts it and ends
//! the programme at 0 A, and the host reports the ticks that are missing — a record is complete
//! or it is refused, never silently thinned.
//!
//! Wire format of one batch (little endian): `SAMPLE_BYTES` = 13 bytes per tick, ticks
//! consecutive from the line's first tick: current applied (f32, A), reading (f32, m; NaN after a
//! sensor fault), flags (u8, [`crate::inverse::CommandFlags`]), the coil current the amplifier's
//! current monitor read on the same trigger (f32, A; NaN where the bench has no monitor).

use crate::inverse::{ControlLoop, LoopState, TickOutput};
use crate::programme::{IdentificationProgramme, ProgrammeState};
use crate::sensor::SensorFault;
use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

/// Bytes per recorded tick.
pub const SAMPLE_BYTES: usize = 13;
/// Ticks per batch: one defmt frame of 13·14 = 182 payload bytes plus ≤ 9 of header, ≤ 219
/// bytes after rzCOBS framing (worst case +1/7): fits the QEMU logger's 256-byte frame buffer.
pub const BATCH_SAMPLES: usize = 14;
/// Capacity of the interrupt → thread-mode queue, ticks (51 ms at 10 kHz); a power of two.
pub const QUEUE_SAMPLES: usize = 512;
const _: () = assert!(QUEUE_SAMPLES.is_power_of_two() && QUEUE_SAMPLES <= 1 << 16);

/// One recorded tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredSample {
    /// Experiment of the programme.
    pub experiment: u8,
    /// Recorded tick within the experiment.
    pub tick: u32,
    /// Current applied to the coil (after the output limiter), A.
    pub current_a: f32,
    /// The firmware's reading of the displacement sensor, m (NaN after a sensor fault).
    pub reading_m: f32,
    /// Command flags.
    pub flags: u8,
    /// The coil current read on the same trigger, A (NaN: the bench has no current monitor).
    pub coil_current_a: f32,
}

const EMPTY: MeasuredSample = MeasuredSample {
    experiment: 0,
    tick: 0,
    current_a: 0.0,
    reading_m: 0.0,
    flags: 0,
    coil_current_a: f32::NAN,
};

/// The interrupt → thread-mode queue of recorded ticks: a ring of [`QUEUE_SAMPLES`] slots,
/// written only through its [`Producer`] and read only through its [`Consumer`]
/// ([`split`](Self::split) hands out one of each). `written` and `read` count ticks (wrapping);
/// a slot is the producer's while `written − read < QUEUE_SAMPLES`, the consumer's after the
/// producer's release-store of `written` and until its own release-store of `read`.
pub struct RecordQueue {
    slots: [UnsafeCell<MeasuredSample>; QUEUE_SAMPLES],
    written: AtomicU32,
    read: AtomicU32,
}

// SAFETY: a slot is accessed by one side at a time (see the type's docs); the counters are
// atomics with release/acquire ordering.
unsafe impl Sync for RecordQueue {}

impl Default for RecordQueue {
    fn default() -> Self {
        Self::new()
    }
}

impl RecordQueue {
    /// An empty queue.
    pub const fn new() -> Self {
        RecordQueue {
            slots: [const { UnsafeCell::new(EMPTY) }; QUEUE_SAMPLES],
            written: AtomicU32::new(0),
            read: AtomicU32::new(0),
        }
    }

    /// The two ends (the queue is borrowed for as long as they live: one producer, one
    /// consumer).
    pub fn split(&mut self) -> (Producer<'_>, Consumer<'_>) {
        (Producer { queue: self }, Consumer { queue: self })
    }

    fn slot(&self, counter: u32) -> Option<&UnsafeCell<MeasuredSample>> {
        self.slots.get(counter as usize & (QUEUE_SAMPLES - 1))
    }
}

/// The writing end (the interrupt).
pub struct Producer<'q> {
    queue: &'q RecordQueue,
}

impl Producer<'_> {
    /// Appends `s`, or gives it back when the queue is full (never waits, never overwrites).
    #[inline]
    pub fn enqueue(&mut self, s: MeasuredSample) -> Result<(), MeasuredSample> {
        let q = self.queue;
        let written = q.written.load(Ordering::Relaxed);
        let read = q.read.load(Ordering::Acquire);
        if written.wrapping_sub(read) as usize >= QUEUE_SAMPLES {
            return Err(s);
        }
        let Some(slot) = q.slot(written) else {
            return Err(s);
        };
        // SAFETY: the slot is free (written − read < capacity) and only this producer writes.
        unsafe { *slot.get() = s };
        q.written.store(written.wrapping_add(1), Ordering::Release);
        Ok(())
    }
}

/// The reading end (thread mode).
pub struct Consumer<'q> {
    queue: &'q RecordQueue,
}

impl Consumer<'_> {
    /// The oldest tick, if any.
    #[inline]
    pub fn dequeue(&mut self) -> Option<MeasuredSample> {
        let q = self.queue;
        let read = q.read.load(Ordering::Relaxed);
        let written = q.written.load(Ordering::Acquire);
        if read == written {
            return None;
        }
        // SAFETY: the slot was published by the producer's release-store of `written` and is
        // not written again before our release-store of `read`.
        let s = q.slot(read).map(|slot| unsafe { *slot.get() });
        q.read.store(read.wrapping_add(1), Ordering::Release);
        s
    }

    /// Ticks waiting.
    pub fn len(&self) -> usize {
        let q = self.queue;
        q.written
            .load(Ordering::Acquire)
            .wrapping_sub(q.read.load(Ordering::Relaxed)) as usize
    }

    /// Whether no tick is waiting.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A batch being filled in thread mode.
#[derive(Debug, Clone)]
pub struct RecordBatch {
    experiment: u8,
    first_tick: u32,
    len: usize,
    bytes: [u8; SAMPLE_BYTES * BATCH_SAMPLES],
}

impl Default for RecordBatch {
    fn default() -> Self {
        Self::new()
    }
}

impl RecordBatch {
    /// An empty batch.
    pub const fn new() -> Self {
        RecordBatch {
            experiment: 0,
            first_tick: 0,
            len: 0,
            bytes: [0; SAMPLE_BYTES * BATCH_SAMPLES],
        }
    }

    /// Appends `s`; `false` (nothing appended) when the batch is full or `s` does not follow its
    /// last tick in the same experiment — log the batch, [`clear`](Self::clear) it and push
    /// again.
    pub fn push(&mut self, s: &MeasuredSample) -> bool {
        if self.len >= BATCH_SAMPLES
            || (self.len > 0
                && (s.experiment != self.experiment
                    || s.tick != self.first_tick.wrapping_add(self.len as u32)))
        {
            return false;
        }
        if self.len == 0 {
            self.experiment = s.experiment;
            self.first_tick = s.tick;
        }
        let at = self.len * SAMPLE_BYTES;
        let [c0, c1, c2, c3] = s.current_a.to_le_bytes();
        let [r0, r1, r2, r3] = s.reading_m.to_le_bytes();
        let [i0, i1, i2, i3] = s.coil_current_a.to_le_bytes();
        let encoded = [c0, c1, c2, c3, r0, r1, r2, r3, s.flags, i0, i1, i2, i3];
        match self.bytes.get_mut(at..at + SAMPLE_BYTES) {
            Some(slot) => {
                // Element by element: no length check the optimizer must remove (no-panic proof).
                for (to, from) in slot.iter_mut().zip(encoded) {
                    *to = from;
                }
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// Whether the batch holds [`BATCH_SAMPLES`] ticks.
    pub fn is_full(&self) -> bool {
        self.len >= BATCH_SAMPLES
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The experiment of the batch.
    pub fn experiment(&self) -> u8 {
        self.experiment
    }

    /// The first tick of the batch.
    pub fn first_tick(&self) -> u32 {
        self.first_tick
    }

    /// The encoded ticks.
    pub fn bytes(&self) -> &[u8] {
        self.bytes.get(..self.len * SAMPLE_BYTES).unwrap_or(&[])
    }

    /// Empties the batch.
    pub fn clear(&mut self) {
        self.len = 0;
    }
}

/// The interrupt's side of a measurement the firmware plays itself: the programme, its
/// progress and the queue's producer.
pub struct Recorder<'q> {
    programme: IdentificationProgramme,
    state: ProgrammeState,
    producer: Producer<'q>,
    lost: u32,
    ended: bool,
}

impl<'q> Recorder<'q> {
    /// Plays `programme` from 0 A, recording into `producer`.
    pub fn new(programme: IdentificationProgramme, producer: Producer<'q>) -> Self {
        Recorder {
            state: programme.start(0.0),
            programme,
            producer,
            lost: 0,
            ended: false,
        }
    }

    /// One control tick: the programme's next current through
    /// [`ControlLoop::measure_sensed`] (limiter, sensor-fault latch), the recorded tick (with
    /// `coil_current_a`, the current monitor's reading of the tick, when the bench has one) into
    /// the queue. After the programme's last tick, a full queue (the host is not draining the
    /// record: the tick is lost, counted, and the programme ends) or a sensor fault, the coil
    /// ramps to 0 A at the slew limit and stays there. Never waits; ~60 instructions beside the
    /// programme and the limiter.
    #[inline]
    pub fn tick<const N: usize>(
        &mut self,
        control: &ControlLoop<'_>,
        loop_state: &mut LoopState<N>,
        reading: Result<f32, SensorFault>,
        coil_current_a: Option<f32>,
    ) -> TickOutput {
        let step = if self.ended {
            None
        } else {
            self.programme.step(&mut self.state)
        };
        let Some(step) = step else {
            self.ended = true;
            return control.measure_sensed(loop_state, 0.0, reading);
        };
        let out = control.measure_sensed(loop_state, step.current_a, reading);
        if let Some(sample) = step.sample {
            let record = MeasuredSample {
                experiment: step.experiment as u8,
                tick: sample,
                current_a: out.current_a,
                reading_m: out.desired.displacement_m,
                flags: out.flags.0,
                coil_current_a: coil_current_a.unwrap_or(f32::NAN),
            };
            if self.producer.enqueue(record).is_err() {
                self.lost = self.lost.saturating_add(1);
                self.ended = true;
            }
        }
        if loop_state.core.sensor_fault.is_some() {
            self.ended = true;
        }
        out
    }

    /// Whether the programme has ended (completed, or cut short by a lost tick or a fault).
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// Ticks that did not fit into the queue (0 for a complete record).
    pub fn lost(&self) -> u32 {
        self.lost
    }
}

/// Thread mode's side: drains the queue into batches.
pub struct RecordDrain<'q> {
    consumer: Consumer<'q>,
    batch: RecordBatch,
    pending: Option<MeasuredSample>,
}

impl<'q> RecordDrain<'q> {
    /// Drains `consumer`.
    pub fn new(consumer: Consumer<'q>) -> Self {
        RecordDrain {
            consumer,
            batch: RecordBatch::new(),
            pending: None,
        }
    }

    /// Moves queued ticks into the batch; returns the batch when it is ready to log (full, or
    /// the next tick starts another experiment, or `flush` and it holds anything). Call
    /// [`logged`](Self::logged) once it has been written out.
    pub fn poll(&mut self, flush: bool) -> Option<&RecordBatch> {
        loop {
            let next = match self.pending.take() {
                Some(s) => s,
                None => match self.consumer.dequeue() {
                    Some(s) => s,
                    None => break,
                },
            };
            if !self.batch.push(&next) {
                self.pending = Some(next);
                return Some(&self.batch);
            }
            if self.batch.is_full() {
                return Some(&self.batch);
            }
        }
        (flush && !self.batch.is_empty()).then_some(&self.batch)
    }

    /// The batch returned by [`poll`](Self::poll) has been logged.
    pub fn logged(&mut self) {
        self.batch.clear();
    }

    /// Whether nothing is queued or batched.
    pub fn is_empty(&self) -> bool {
        self.batch.is_empty() && self.pending.is_none() && self.consumer.is_empty()
    }
}

/// A batch that cannot be decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadBatchLength(pub usize);

/// Decodes a batch logged with experiment `experiment` and first tick `first_tick`: its ticks in
/// order, or the length when it is not a whole number of ticks.
pub fn decode_batch(
    experiment: u8,
    first_tick: u32,
    bytes: &[u8],
) -> Result<impl Iterator<Item = MeasuredSample> + '_, BadBatchLength> {
    if bytes.len() % SAMPLE_BYTES != 0 {
        return Err(BadBatchLength(bytes.len()));
    }
    Ok(bytes
        .chunks_exact(SAMPLE_BYTES)
        .enumerate()
        .map(move |(i, c)| MeasuredSample {
            experiment,
            tick: first_tick.wrapping_add(i as u32),
            current_a: f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
            reading_m: f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            flags: c[8],
            coil_current_a: f32::from_le_bytes([c[9], c[10], c[11], c[12]]),
        }))
}

/// The record's defmt lines, as every firmware image that records logs them and `cargo xtask
/// record` decodes them: `MEAS-BEGIN <rate> Hz <experiments> experiments <start state>`, one
/// `MEAS-EXP <index> <ticks> <kind> <a> <b> <c>` per experiment, then `MEAS <experiment> <first
/// tick> <bytes>` per batch. Thread mode only: never from the interrupt.
#[cfg(target_os = "none")]
pub mod log {
    use super::RecordDrain;
    use crate::programme::{IdentificationProgramme, EXPERIMENTS};

    /// Logs the programme's header lines (`MEAS-BEGIN`, one `MEAS-EXP` per experiment).
    pub fn programme(programme: &IdentificationProgramme, rate_hz: f32) {
        defmt::info!(
            "MEAS-BEGIN {=f32} Hz {=u32} experiments {=str}",
            rate_hz,
            EXPERIMENTS as u32,
            programme.start_state_name()
        );
        let mut k = 0;
        while let Some(e) = programme.experiment(k) {
            let (kind, a, b, c) = e.kind.fields();
            defmt::info!(
                "MEAS-EXP {=u32} {=u32} {=str} {=f32} {=f32} {=f32}",
                k as u32,
                e.ticks,
                kind,
                a,
                b,
                c
            );
            k += 1;
        }
    }

    /// Logs the ready batches (`MEAS` lines; with `flush`, the last partial one too) while
    /// `room()` says the log transport takes one more (a batch that does not fit waits in the
    /// drain; the queue behind it keeps filling).
    pub fn batches(drain: &mut RecordDrain<'_>, flush: bool, mut room: impl FnMut() -> bool) {
        while room() {
            let Some(b) = drain.poll(flush) else { break };
            defmt::info!(
                "MEAS {=u8} {=u32} {=[u8]}",
                b.experiment(),
                b.first_tick(),
                b.bytes()
            );
            drain.logged();
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn sample(tick: u32) -> MeasuredSample {
        MeasuredSample {
            experiment: 2,
            tick,
            current_a: tick as f32 * 0.25 - 1.0,
            reading_m: if tick == 5 {
                f32::NAN
            } else {
                tick as f32 * 1e-6
            },
            flags: (tick % 256) as u8,
            coil_current_a: if tick % 3 == 0 {
                f32::NAN
            } else {
                tick as f32 * 0.01
            },
        }
    }

    #[test]
    fn a_batch_round_trips_through_its_bytes_bit_for_bit() {
        let mut b = RecordBatch::new();
        for t in 3..3 + BATCH_SAMPLES as u32 {
            assert!(b.push(&sample(t)));
        }
        assert!(b.is_full());
        assert!(!b.push(&sample(3 + BATCH_SAMPLES as u32)), "full");
        let back: Vec<MeasuredSample> = decode_batch(b.experiment(), b.first_tick(), b.bytes())
            .unwrap()
            .collect();
        assert_eq!(back.len(), BATCH_SAMPLES);
        for (i, s) in back.iter().enumerate() {
            let want = sample(3 + i as u32);
            assert_eq!(s.tick, want.tick);
            assert_eq!(s.current_a.to_bits(), want.current_a.to_bits());
            assert_eq!(s.reading_m.to_bits(), want.reading_m.to_bits());
            assert_eq!(s.flags, want.flags);
            assert_eq!(s.coil_current_a.to_bits(), want.coil_current_a.to_bits());
        }
        b.clear();
        assert!(b.is_empty() && b.bytes().is_empty());
    }

    #[test]
    fn a_gap_in_the_ticks_ends_the_batch_and_a_torn_batch_is_refused() {
        let mut b = RecordBatch::new();
        assert!(b.push(&sample(10)));
        assert!(!b.push(&sample(12)), "tick 11 missing: not appended");
        let mut other = sample(11);
        other.experiment = 3;
        assert!(!b.push(&other), "another experiment: not appended");
        assert_eq!(b.bytes().len(), SAMPLE_BYTES);
        assert_eq!(
            decode_batch(0, 0, &[0u8; SAMPLE_BYTES + 2]).err(),
            Some(BadBatchLength(SAMPLE_BYTES + 2))
        );
    }

    #[test]
    fn a_played_programme_arrives_whole_and_in_order_through_queue_and_batches() {
        use crate::params::{BAKED_MEASURE, BAKED_PARAMETERS};
        use crate::programme::EXPERIMENTS;
        let p = &BAKED_PARAMETERS;
        let control = ControlLoop::new(&BAKED_MEASURE, p).unwrap();
        let mut state = control
            .init::<{ crate::preisach::DEFAULT_CAPACITY }>(crate::inverse::InverseKind::Dynamic);
        let programme = IdentificationProgramme::new(
            control.limiter(),
            p.actuator.coil_factor_per_m,
            &BAKED_MEASURE,
            p.preisach.reach_a_per_m,
            p.control.sample_rate_hz,
        )
        .unwrap();
        let mut q = RecordQueue::new();
        let (producer, consumer) = q.split();
        let mut recorder = Recorder::new(programme, producer);
        let mut drain = RecordDrain::new(consumer);
        let mut received: Vec<MeasuredSample> = Vec::new();
        let mut ticks = 0u32;
        while !recorder.ended() {
            // A reading that depends on the tick, so that order mistakes show.
            let out = recorder.tick(
                &control,
                &mut state,
                Ok(ticks as f32 * 1e-9),
                Some(ticks as f32 * 1e-3),
            );
            assert!(out.current_a.abs() <= control.limiter().limit_a());
            ticks += 1;
            // Thread mode drains every few ticks.
            if ticks % 7 == 0 {
                while let Some(b) = drain.poll(false) {
                    received
                        .extend(decode_batch(b.experiment(), b.first_tick(), b.bytes()).unwrap());
                    drain.logged();
                }
            }
        }
        while let Some(b) = drain.poll(true) {
            received.extend(decode_batch(b.experiment(), b.first_tick(), b.bytes()).unwrap());
            drain.logged();
        }
        assert!(drain.is_empty());
        assert_eq!(recorder.lost(), 0);
        assert_eq!(
            ticks,
            programme.total_ticks(0.0) + 1,
            "programme, then the end tick"
        );
        let mut k = 0;
        for e in 0..EXPERIMENTS {
            let n = programme.experiment(e).unwrap().ticks;
            for t in 0..n {
                let s = received[k];
                assert_eq!((s.experiment as usize, s.tick), (e, t));
                k += 1;
            }
        }
        assert_eq!(k, received.len());
        // Readings increase with the tick: nothing reordered.
        assert!(received.windows(2).all(|w| w[1].reading_m > w[0].reading_m));
    }

    #[test]
    fn an_undrained_record_ends_the_programme_and_counts_the_lost_tick() {
        use crate::params::{BAKED_MEASURE, BAKED_PARAMETERS};
        let p = &BAKED_PARAMETERS;
        let control = ControlLoop::new(&BAKED_MEASURE, p).unwrap();
        let mut state = control
            .init::<{ crate::preisach::DEFAULT_CAPACITY }>(crate::inverse::InverseKind::Dynamic);
        let programme = IdentificationProgramme::new(
            control.limiter(),
            p.actuator.coil_factor_per_m,
            &BAKED_MEASURE,
            p.preisach.reach_a_per_m,
            p.control.sample_rate_hz,
        )
        .unwrap();
        let mut q = RecordQueue::new();
        let (producer, _consumer) = q.split();
        let mut recorder = Recorder::new(programme, producer);
        let mut last = 1.0f32;
        for _ in 0..20_000 {
            last = recorder.tick(&control, &mut state, Ok(0.0), None).current_a;
        }
        assert!(recorder.ended());
        assert_eq!(
            recorder.lost(),
            1,
            "one tick lost, then the programme ended"
        );
        assert_eq!(last, 0.0, "the coil ramped to 0 A");
    }

    #[test]
    fn the_queue_refuses_rather_than_overwrites_when_full() {
        let mut q = RecordQueue::new();
        let (mut producer, mut consumer) = q.split();
        // Several laps around the ring: the counters wrap the slots correctly.
        for lap in 0..3u32 {
            let base = lap * QUEUE_SAMPLES as u32;
            for t in 0..QUEUE_SAMPLES as u32 {
                assert!(producer.enqueue(sample(base + t)).is_ok());
            }
            assert!(producer.enqueue(sample(9_999)).is_err(), "full");
            assert_eq!(consumer.len(), QUEUE_SAMPLES);
            for t in 0..QUEUE_SAMPLES as u32 {
                assert_eq!(consumer.dequeue().map(|s| s.tick), Some(base + t));
            }
            assert!(consumer.dequeue().is_none() && consumer.is_empty());
        }
    }
}
