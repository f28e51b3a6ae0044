//! What a recorded coil current means between its samples: the one vocabulary of the workspace
//! (`maglab rig --current-between-samples`, the bench plant, the identification's and the
//! diagnosis's models).
//!
//! A DAC holds its command over each sample interval; a current probe samples a continuous
//! current. Taking one for the other shifts the input by half a sample, `π f h` rad: 3.6° at
//! 200 Hz and 10 kHz, more than the eddy-current lag the identification measures.

use std::fmt;

/// What the recorded current does between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CurrentBetweenSamples {
    /// Held over each sample interval (zero-order hold, a DAC).
    Hold,
    /// Linear to the next sample (a sampled continuous current).
    Linear,
}

impl CurrentBetweenSamples {
    /// Every value with its interface name.
    pub const NAMES: [(&'static str, CurrentBetweenSamples); 2] = [
        ("hold", CurrentBetweenSamples::Hold),
        ("linear", CurrentBetweenSamples::Linear),
    ];

    /// Parses an interface name.
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == text)
            .map(|(_, s)| *s)
            .ok_or_else(|| {
                format!("unknown current between samples `{text}`: expected hold or linear")
            })
    }

    /// The interface name.
    pub fn name(self) -> &'static str {
        match self {
            CurrentBetweenSamples::Hold => "hold",
            CurrentBetweenSamples::Linear => "linear",
        }
    }

    /// Where a sample's current acts on average, in samples after its time stamp: half a sample
    /// for a held command, at its time for a linear one.
    pub fn mean_delay_samples(self) -> f64 {
        match self {
            CurrentBetweenSamples::Hold => 0.5,
            CurrentBetweenSamples::Linear => 0.0,
        }
    }
}

impl fmt::Display for CurrentBetweenSamples {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
