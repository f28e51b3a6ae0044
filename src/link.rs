//! The lock-step plant link of the virtual bench (`cargo xtask hil`, `docs/hil.md`): the byte
//! frames the firmware and a plant program exchange once per control tick.
//!
//! One implementation for both ends: the firmware decodes [`SampleFrame`]s and encodes
//! [`CommandFrame`]s; the host plant (`maglab hil-plant`) does the reverse with the same code.
//! Everything is little-endian and fixed-size, so a plant written in any language needs only a
//! byte stream and a struct unpacker (`docs/hil.md` has the tables and a Python example).
//!
//! A frame starts with [`SYNC`]; its second byte says what it is. The sequence number is the
//! control tick modulo 2¹⁶. The decoders never panic: a wrong sync byte, an unknown kind or a
//! sequence number other than the expected one is an error value, which the firmware treats as a
//! broken link (`docs/hil.md`, "Faults").

/// First byte of every frame.
pub const SYNC: u8 = 0xA5;
/// Bytes of a sample frame without the coil current (plant → firmware), of a programme frame
/// and of the end acknowledgement (bench host → firmware).
pub const SAMPLE_FRAME_BYTES: usize = 8;
/// Bytes of a sample frame with the coil current ([`KIND_SAMPLE_COUNT_CURRENT`],
/// [`KIND_SAMPLE_METRES_CURRENT`]).
pub const SAMPLE_CURRENT_FRAME_BYTES: usize = 12;
/// The longest frame the firmware receives.
pub const MAX_RECEIVED_FRAME_BYTES: usize = SAMPLE_CURRENT_FRAME_BYTES;
/// Bytes of a command frame (firmware → plant).
pub const COMMAND_FRAME_BYTES: usize = 16;

/// Sample-frame kind: the payload is the ADC count (`u32`), scaled by the `sensor` section.
pub const KIND_SAMPLE_COUNT: u8 = b'S';
/// Sample-frame kind: the payload is the displacement in metres (`f32`), for a digital sensor
/// (checked against the valid range like a scaled count; NaN or ±∞ is a sensor fault).
pub const KIND_SAMPLE_METRES: u8 = b'M';
/// Sample-frame kind (link version 2): the ADC count (`u32`) and the coil current the amplifier's
/// current monitor read on the same trigger (`f32`, A).
pub const KIND_SAMPLE_COUNT_CURRENT: u8 = b'T';
/// Sample-frame kind (link version 2): the displacement in metres (`f32`) and the coil current
/// (`f32`, A).
pub const KIND_SAMPLE_METRES_CURRENT: u8 = b'U';
/// Programme-frame kind (bench host → firmware, measurement mode): the current to play this tick,
/// `f32` A. Sent by the bench host (`cargo xtask hil --measure`) before each sample frame, never
/// by a plant.
pub const KIND_PROGRAMME: u8 = b'R';
/// Command-frame kind: the firmware starts a run; payload `f32` = control rate, Hz; `aux` = the
/// number of ticks it will run.
pub const KIND_BEGIN: u8 = b'B';
/// Command-frame kind: the current command of one tick.
pub const KIND_COMMAND: u8 = b'C';
/// Command-frame kind: the firmware ends the run; `aux` = its exit status. The bench host (not
/// the plant) answers with an [`EndAck`].
pub const KIND_END: u8 = b'E';
/// Acknowledgement kind (bench host → firmware): the host has read the `E` frame, whose `seq`
/// and status it echoes ([`EndAck`]). Sent by the bench host (`cargo xtask hil`), never by a
/// plant.
pub const KIND_END_ACK: u8 = b'A';

/// What the plant sent for one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sample {
    /// An ADC count.
    Count(u32),
    /// A displacement, m.
    Metres(f32),
}

/// A decoded sample frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleFrame {
    /// Tick modulo 2¹⁶ this sample is for.
    pub seq: u16,
    /// The reading.
    pub sample: Sample,
    /// The coil current the current monitor read on the same trigger, A (link version 2's
    /// `T`/`U` frames; `None` for `S`/`M`).
    pub coil_current_a: Option<f32>,
}

/// A received frame: its bytes and how many of them it has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawFrame {
    bytes: [u8; MAX_RECEIVED_FRAME_BYTES],
    len: usize,
}

impl RawFrame {
    /// The frame's bytes.
    pub fn as_slice(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
}

/// The length of a received frame of kind `kind` (firmware's side): 12 bytes for the sample
/// frames with the coil current, 8 for every other kind the firmware understands, and 2 (the
/// sync and kind bytes alone) for a kind it does not, so that the decoder reports it at once.
pub fn received_frame_bytes(kind: u8) -> usize {
    match kind {
        KIND_SAMPLE_COUNT_CURRENT | KIND_SAMPLE_METRES_CURRENT => SAMPLE_CURRENT_FRAME_BYTES,
        KIND_SAMPLE_COUNT | KIND_SAMPLE_METRES | KIND_PROGRAMME | KIND_END_ACK => {
            SAMPLE_FRAME_BYTES
        }
        _ => 2,
    }
}

/// Why a received frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// The first byte is not [`SYNC`].
    Sync(u8),
    /// Unknown kind byte.
    Kind(u8),
    /// Sequence number other than the expected one (a lost or repeated frame).
    Sequence {
        /// Expected.
        expected: u16,
        /// Received.
        got: u16,
    },
}

impl SampleFrame {
    /// Encodes the frame (the plant's side): 8 bytes (`S`, `M`) or, with the coil current,
    /// 12 (`T`, `U`).
    pub fn encode(&self) -> RawFrame {
        let (kind, payload) = match (self.sample, self.coil_current_a) {
            (Sample::Count(c), None) => (KIND_SAMPLE_COUNT, c.to_le_bytes()),
            (Sample::Metres(m), None) => (KIND_SAMPLE_METRES, m.to_le_bytes()),
            (Sample::Count(c), Some(_)) => (KIND_SAMPLE_COUNT_CURRENT, c.to_le_bytes()),
            (Sample::Metres(m), Some(_)) => (KIND_SAMPLE_METRES_CURRENT, m.to_le_bytes()),
        };
        let s = self.seq.to_le_bytes();
        let i = self.coil_current_a.unwrap_or(0.0).to_le_bytes();
        RawFrame {
            bytes: [
                SYNC, kind, s[0], s[1], payload[0], payload[1], payload[2], payload[3], i[0], i[1],
                i[2], i[3],
            ],
            len: received_frame_bytes(kind),
        }
    }

    /// Decodes a frame and checks its sequence number against `expected_seq` (the firmware's
    /// side); a frame shorter than its kind's length is a kind error.
    pub fn decode(b: &[u8], expected_seq: u16) -> Result<Self, FrameError> {
        let (&sync, &kind) = match b {
            [sync, kind, ..] => (sync, kind),
            [sync] => return Err(FrameError::Sync(*sync)),
            [] => return Err(FrameError::Sync(0)),
        };
        if sync != SYNC {
            return Err(FrameError::Sync(sync));
        }
        let with_current = matches!(kind, KIND_SAMPLE_COUNT_CURRENT | KIND_SAMPLE_METRES_CURRENT);
        let word = |at: usize| -> Option<[u8; 4]> {
            Some([
                *b.get(at)?,
                *b.get(at + 1)?,
                *b.get(at + 2)?,
                *b.get(at + 3)?,
            ])
        };
        let (Some(seq), Some(payload)) = (b.get(2..4), word(4)) else {
            return Err(FrameError::Kind(kind));
        };
        let seq = u16::from_le_bytes([seq[0], seq[1]]);
        let sample = match kind {
            KIND_SAMPLE_COUNT | KIND_SAMPLE_COUNT_CURRENT => {
                Sample::Count(u32::from_le_bytes(payload))
            }
            KIND_SAMPLE_METRES | KIND_SAMPLE_METRES_CURRENT => {
                Sample::Metres(f32::from_le_bytes(payload))
            }
            k => return Err(FrameError::Kind(k)),
        };
        let coil_current_a = match (with_current, word(8)) {
            (false, _) => None,
            (true, Some(i)) => Some(f32::from_le_bytes(i)),
            (true, None) => return Err(FrameError::Kind(kind)),
        };
        if seq != expected_seq {
            return Err(FrameError::Sequence {
                expected: expected_seq,
                got: seq,
            });
        }
        Ok(SampleFrame {
            seq,
            sample,
            coil_current_a,
        })
    }
}

/// A programme frame (bench host → firmware, measurement mode): the current of one tick of an
/// identification programme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgrammeFrame {
    /// Tick modulo 2¹⁶.
    pub seq: u16,
    /// The current to play, A.
    pub current_a: f32,
}

impl ProgrammeFrame {
    /// Encodes the frame (the bench host's side).
    pub fn encode(&self) -> [u8; SAMPLE_FRAME_BYTES] {
        let s = self.seq.to_le_bytes();
        let c = self.current_a.to_le_bytes();
        [SYNC, KIND_PROGRAMME, s[0], s[1], c[0], c[1], c[2], c[3]]
    }

    /// Decodes a frame and checks its sequence number (the firmware's side).
    pub fn decode(b: &[u8], expected_seq: u16) -> Result<Self, FrameError> {
        let b: &[u8; SAMPLE_FRAME_BYTES] = match b {
            [SYNC, KIND_PROGRAMME, ..] => b
                .get(..SAMPLE_FRAME_BYTES)
                .and_then(|b| b.try_into().ok())
                .ok_or(FrameError::Kind(KIND_PROGRAMME))?,
            [SYNC, kind, ..] => return Err(FrameError::Kind(*kind)),
            [other, ..] => return Err(FrameError::Sync(*other)),
            [] => return Err(FrameError::Sync(0)),
        };
        let seq = u16::from_le_bytes([b[2], b[3]]);
        if seq != expected_seq {
            return Err(FrameError::Sequence {
                expected: expected_seq,
                got: seq,
            });
        }
        Ok(ProgrammeFrame {
            seq,
            current_a: f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
        })
    }
}

/// A command frame (firmware → plant).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandFrame {
    /// [`KIND_BEGIN`], [`KIND_COMMAND`] or [`KIND_END`].
    pub kind: u8,
    /// Tick modulo 2¹⁶.
    pub seq: u16,
    /// `C`: current to hold over the coming period, A. `B`: control rate, Hz. `E`: 0.
    pub value: f32,
    /// `C`: the desired displacement at the end of the coming period, m (for the plant's log);
    /// in measurement mode (flag `MEASURE`) the firmware's reading of this tick's sample, m (NaN
    /// if it was rejected).
    pub desired_m: f32,
    /// `C`: the command's flags (`inverse::CommandFlags` bits).
    pub flags: u8,
    /// `C`: instructions the control interrupt took for this command (SysTick / 25.6, saturated);
    /// `B`: ticks in the run (low 16 bits, see `aux32`); `E`: the exit status.
    pub aux: u16,
    /// `B`: ticks in the run; otherwise 0.
    pub aux32: u32,
}

impl CommandFrame {
    /// Encodes the frame: sync, kind, seq (u16), value (f32), desired (f32), flags (u8),
    /// reserved (u8, 0), aux (u16) — see `docs/hil.md`. `B` carries the tick count in the
    /// `desired` slot as a `u32` instead.
    pub fn encode(&self) -> [u8; COMMAND_FRAME_BYTES] {
        let s = self.seq.to_le_bytes();
        let v = self.value.to_le_bytes();
        let d = if self.kind == KIND_BEGIN {
            self.aux32.to_le_bytes()
        } else {
            self.desired_m.to_le_bytes()
        };
        let a = self.aux.to_le_bytes();
        [
            SYNC, self.kind, s[0], s[1], v[0], v[1], v[2], v[3], d[0], d[1], d[2], d[3],
            self.flags, 0, a[0], a[1],
        ]
    }

    /// Decodes a frame (the plant's side).
    pub fn decode(b: &[u8; COMMAND_FRAME_BYTES]) -> Result<Self, FrameError> {
        if b[0] != SYNC {
            return Err(FrameError::Sync(b[0]));
        }
        let kind = b[1];
        if !matches!(kind, KIND_BEGIN | KIND_COMMAND | KIND_END) {
            return Err(FrameError::Kind(kind));
        }
        let word = [b[8], b[9], b[10], b[11]];
        Ok(CommandFrame {
            kind,
            seq: u16::from_le_bytes([b[2], b[3]]),
            value: f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
            desired_m: if kind == KIND_BEGIN {
                0.0
            } else {
                f32::from_le_bytes(word)
            },
            flags: b[12],
            aux: u16::from_le_bytes([b[14], b[15]]),
            aux32: if kind == KIND_BEGIN {
                u32::from_le_bytes(word)
            } else {
                0
            },
        })
    }
}

/// Assembles received frames from a byte stream, one byte at a time (the firmware feeds it the
/// UART's received bytes; it never blocks and never allocates). The kind byte says how long
/// the frame is ([`received_frame_bytes`]).
#[derive(Debug, Clone, Default)]
pub struct SampleAssembler {
    buf: [u8; MAX_RECEIVED_FRAME_BYTES],
    len: usize,
}

impl SampleAssembler {
    /// An empty assembler.
    pub const fn new() -> Self {
        SampleAssembler {
            buf: [0; MAX_RECEIVED_FRAME_BYTES],
            len: 0,
        }
    }

    /// Adds a byte; returns the whole frame when this byte completed one. A first byte other
    /// than [`SYNC`] is returned at once as a one-byte frame, and a kind the firmware does not
    /// know as a two-byte one, so that the decoder reports the desynchronized link instead of
    /// waiting for more bytes.
    pub fn push(&mut self, byte: u8) -> Option<RawFrame> {
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
        }
        self.len += 1;
        let wanted = match self.len {
            1 if byte != SYNC => 1,
            1 => return None,
            _ => received_frame_bytes(self.buf[1]),
        };
        if self.len >= wanted {
            let frame = RawFrame {
                bytes: self.buf,
                len: self.len.min(MAX_RECEIVED_FRAME_BYTES),
            };
            self.len = 0;
            return Some(frame);
        }
        None
    }

    /// Bytes of an unfinished frame.
    pub fn pending(&self) -> usize {
        self.len
    }
}

/// The bench host's acknowledgement of the firmware's `E` frame (bench host → firmware).
///
/// QEMU closes its end of the link when the firmware exits. A socket closed with received bytes
/// still unread is reset instead of closed, and a reset can drop the bytes the host has not yet
/// received: measured under host load, 2 of 25 runs of a corrupted-frame fault (whose unread rest
/// stays in the firmware's receive path) lost the last command and the `E` frame. The firmware
/// therefore exits only once the host has said it read `E` (or after a bounded wait), reading
/// and discarding whatever else arrives meanwhile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EndAck {
    /// The `E` frame's sequence number.
    pub seq: u16,
    /// The `E` frame's exit status (its `aux` field).
    pub status: u16,
}

impl EndAck {
    /// Encodes the acknowledgement: `SYNC`, `'A'`, `seq`, status, `"OK"`.
    pub fn encode(&self) -> [u8; SAMPLE_FRAME_BYTES] {
        let s = self.seq.to_le_bytes();
        let t = self.status.to_le_bytes();
        [SYNC, KIND_END_ACK, s[0], s[1], t[0], t[1], b'O', b'K']
    }
}

/// Finds one expected [`EndAck`] in a byte stream that may carry anything before it (the rest of
/// a corrupted frame, a sample the plant sent after a fault): a window over the last eight
/// bytes, compared whole. Never blocks, never allocates.
#[derive(Debug, Clone)]
pub struct EndAckWatch {
    expected: [u8; SAMPLE_FRAME_BYTES],
    window: [u8; SAMPLE_FRAME_BYTES],
    seen: usize,
}

impl EndAckWatch {
    /// Watches for `ack`.
    pub fn new(ack: EndAck) -> Self {
        EndAckWatch {
            expected: ack.encode(),
            window: [0; SAMPLE_FRAME_BYTES],
            seen: 0,
        }
    }

    /// Adds a received byte; true when it completed the expected acknowledgement.
    pub fn push(&mut self, byte: u8) -> bool {
        for i in 0..SAMPLE_FRAME_BYTES - 1 {
            self.window[i] = self.window[i + 1];
        }
        self.window[SAMPLE_FRAME_BYTES - 1] = byte;
        self.seen = (self.seen + 1).min(SAMPLE_FRAME_BYTES);
        self.seen == SAMPLE_FRAME_BYTES && self.window == self.expected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_and_bad_frames_are_errors() {
        for sample in [
            Sample::Count(0),
            Sample::Count(4095),
            Sample::Metres(2.5e-5),
            Sample::Metres(-0.0),
        ] {
            let f = SampleFrame {
                seq: 513,
                sample,
                coil_current_a: None,
            };
            assert_eq!(SampleFrame::decode(f.encode().as_slice(), 513), Ok(f));
        }
        let nan = SampleFrame {
            seq: 7,
            sample: Sample::Metres(f32::NAN),
            coil_current_a: None,
        };
        match SampleFrame::decode(nan.encode().as_slice(), 7) {
            Ok(SampleFrame {
                sample: Sample::Metres(m),
                ..
            }) => assert!(m.is_nan()),
            other => panic!("{other:?}"),
        }
        let p = ProgrammeFrame {
            seq: 4,
            current_a: -1.25,
        };
        assert_eq!(ProgrammeFrame::decode(&p.encode(), 4), Ok(p));
        assert_eq!(
            SampleFrame::decode(&p.encode(), 4),
            Err(FrameError::Kind(KIND_PROGRAMME))
        );
        let f = SampleFrame {
            seq: 9,
            sample: Sample::Count(1),
            coil_current_a: None,
        };
        assert_eq!(
            ProgrammeFrame::decode(f.encode().as_slice(), 9),
            Err(FrameError::Kind(KIND_SAMPLE_COUNT))
        );
        assert_eq!(
            SampleFrame::decode(f.encode().as_slice(), 10),
            Err(FrameError::Sequence {
                expected: 10,
                got: 9
            })
        );
        let mut b = f.encode().as_slice().to_vec();
        b[0] = 0x5A;
        assert_eq!(SampleFrame::decode(&b, 9), Err(FrameError::Sync(0x5A)));
        let mut b = f.encode().as_slice().to_vec();
        b[1] = b'Z';
        assert_eq!(SampleFrame::decode(&b, 9), Err(FrameError::Kind(b'Z')));

        for c in [
            CommandFrame {
                kind: KIND_COMMAND,
                seq: 65535,
                value: -0.75,
                desired_m: 3e-5,
                flags: 6,
                aux: 812,
                aux32: 0,
            },
            CommandFrame {
                kind: KIND_BEGIN,
                seq: 0,
                value: 10_000.0,
                desired_m: 0.0,
                flags: 0,
                aux: 0,
                aux32: 100_000,
            },
            CommandFrame {
                kind: KIND_END,
                seq: 3,
                value: 0.0,
                desired_m: 0.0,
                flags: 0,
                aux: 8,
                aux32: 0,
            },
        ] {
            assert_eq!(CommandFrame::decode(&c.encode()), Ok(c));
        }
        let mut b = [0u8; COMMAND_FRAME_BYTES];
        b[0] = SYNC;
        b[1] = b'?';
        assert_eq!(CommandFrame::decode(&b), Err(FrameError::Kind(b'?')));
    }

    #[test]
    fn the_assembler_cuts_frames_of_either_length_and_reports_a_lost_sync_or_kind_at_once() {
        let mut a = SampleAssembler::new();
        for coil_current_a in [None, Some(0.8125)] {
            let f = SampleFrame {
                seq: 1,
                sample: Sample::Count(77),
                coil_current_a,
            };
            let bytes = f.encode();
            let len = bytes.as_slice().len();
            assert_eq!(len, if coil_current_a.is_some() { 12 } else { 8 });
            let mut got = None;
            for (i, &byte) in bytes.as_slice().iter().enumerate() {
                got = a.push(byte);
                assert_eq!(got.is_some(), i == len - 1);
            }
            let got = got.expect("a whole frame");
            assert_eq!(got.as_slice(), bytes.as_slice());
            assert_eq!(SampleFrame::decode(got.as_slice(), 1), Ok(f));
            assert_eq!(a.pending(), 0);
        }
        let bad = a
            .push(0x00)
            .expect("a wrong first byte is reported at once");
        assert_eq!(
            SampleFrame::decode(bad.as_slice(), 2),
            Err(FrameError::Sync(0x00)),
            "decoded as a sync error"
        );
        assert!(a.push(SYNC).is_none());
        let unknown = a.push(b'Q').expect("an unknown kind is reported at once");
        assert_eq!(
            SampleFrame::decode(unknown.as_slice(), 2),
            Err(FrameError::Kind(b'Q'))
        );
        // A frame of version 2 cut short is no frame.
        let cut = &SampleFrame {
            seq: 3,
            sample: Sample::Metres(1e-5),
            coil_current_a: Some(1.0),
        }
        .encode();
        assert_eq!(
            SampleFrame::decode(&cut.as_slice()[..8], 3),
            Err(FrameError::Kind(KIND_SAMPLE_METRES_CURRENT))
        );
    }

    #[test]
    fn the_end_acknowledgement_is_found_after_any_bytes_and_only_whole() {
        let ack = EndAck {
            seq: 1002,
            status: 8,
        };
        let bytes = ack.encode();
        // Alone.
        let mut w = EndAckWatch::new(ack);
        let mut hits = [false; SAMPLE_FRAME_BYTES];
        for (hit, &b) in hits.iter_mut().zip(&bytes) {
            *hit = w.push(b);
        }
        assert_eq!(
            hits,
            [false, false, false, false, false, false, false, true]
        );
        // After the rest of a corrupted sample frame, a whole sample frame and stray sync bytes.
        let mut w = EndAckWatch::new(ack);
        let sample = SampleFrame {
            seq: 1002,
            sample: Sample::Count(1286),
            coil_current_a: None,
        }
        .encode();
        let sample = sample.as_slice();
        let stray = [SYNC, SYNC, KIND_END_ACK];
        for &b in sample[1..].iter().chain(sample).chain(&stray) {
            assert!(!w.push(b));
        }
        assert_eq!(bytes.iter().filter(|&&b| w.push(b)).count(), 1);
        // Another sequence number, another status or a truncated frame is not it.
        for other in [
            EndAck {
                seq: 1001,
                status: 8,
            },
            EndAck {
                seq: 1002,
                status: 0,
            },
        ] {
            let mut w = EndAckWatch::new(ack);
            assert!(other.encode().iter().all(|&b| !w.push(b)));
        }
        let mut w = EndAckWatch::new(ack);
        assert!(bytes[..7].iter().chain(&bytes[..7]).all(|&b| !w.push(b)));
    }
}
