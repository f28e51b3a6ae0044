//! The phases of the QEMU benchmark run (`firmware-qemu`): the phase byte of each capture
//! record (`mps2_an386::capture`) and its name in `out/qemu/capture.csv`, the file `cargo xtask
//! qemu` writes and `maglab track --capture` reads. One table, so that writer and reader agree.

/// A phase of the benchmark run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CapturePhase {
    /// The instruction-counter check at start-up (not written to the CSV).
    Calibration,
    /// Dynamic inverse, the fast exact Preisach inverse.
    Dynamic,
    /// Static inverse.
    Static,
    /// Dynamic inverse with the naive inverse (the baseline it is measured against).
    Naive,
    /// Dynamic inverse with the staircase full: every reversal merges.
    Merge,
    /// Dynamic inverse with the Everett-bisection inverse (a baseline).
    EverettBisection,
    /// Dynamic inverse on a relay grid (a baseline).
    RelayGrid,
}

impl CapturePhase {
    /// Every phase, in the order of their codes.
    pub const ALL: [CapturePhase; 7] = [
        CapturePhase::Calibration,
        CapturePhase::Dynamic,
        CapturePhase::Static,
        CapturePhase::Naive,
        CapturePhase::Merge,
        CapturePhase::EverettBisection,
        CapturePhase::RelayGrid,
    ];

    /// The phase byte of a capture record.
    pub const fn code(self) -> u8 {
        match self {
            CapturePhase::Calibration => 0,
            CapturePhase::Dynamic => 1,
            CapturePhase::Static => 2,
            CapturePhase::Naive => 3,
            CapturePhase::Merge => 4,
            CapturePhase::EverettBisection => 5,
            CapturePhase::RelayGrid => 6,
        }
    }

    /// The phase of a capture record's phase byte.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.code() == code)
    }

    /// The name in `capture.csv`'s `phase` column.
    pub const fn name(self) -> &'static str {
        match self {
            CapturePhase::Calibration => "calibration",
            CapturePhase::Dynamic => "dynamic",
            CapturePhase::Static => "static",
            CapturePhase::Naive => "naive",
            CapturePhase::Merge => "merge",
            CapturePhase::EverettBisection => "everett_bisection",
            CapturePhase::RelayGrid => "relay_grid",
        }
    }

    /// The phase of a `phase` column's name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_and_names_round_trip() {
        for (k, p) in CapturePhase::ALL.into_iter().enumerate() {
            assert_eq!(p.code() as usize, k);
            assert_eq!(CapturePhase::from_code(p.code()), Some(p));
            assert_eq!(CapturePhase::from_name(p.name()), Some(p));
        }
        assert_eq!(CapturePhase::from_code(7), None);
        assert_eq!(CapturePhase::from_name("warp"), None);
    }
}
