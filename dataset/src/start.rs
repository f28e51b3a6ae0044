//! How an experiment starts: the one start-state vocabulary of the workspace.
//!
//! A bench documents it in `dataset.json` ([`crate::dataset_info`]), `maglab rig` and the bench
//! plant start experiments in it, the identification and the diagnosis simulate it. Each tool
//! accepts the states it can reproduce ([`StartState::require`] names the others in its error):
//!
//! | state | Preisach memory | mechanics | documented in `dataset.json` |
//! |---|---|---|---|
//! | `switch-on-demagnetized` | AC-demagnetized at 0 A | at rest at 0 A; the command switched on at `t = 0` | yes |
//! | `demagnetized` | AC-demagnetized at 0 A, then slowly to the first command | at rest there | yes |
//! | `demagnetized-at-first-input` | AC-demagnetized around the first command | at rest there | no |
//! | `negative-saturation` / `positive-saturation` | saturated, then slowly to the first command | at rest there | yes |
//! | `conditioned` | the coil swept the rod's reach (up to its top, down to its bottom: the firmware's conditioning on a rod the coil cannot saturate), then slowly to the first command; on a rod it saturates the same as `negative-saturation` | at rest there | yes |
//! | `periodic` | one period of a periodic steady state: the whole record played once before it | — | no |
//! | `previous` | whatever the previous experiment (file-name order) left | carried over | yes |

use std::fmt;

/// How an experiment was started (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum StartState {
    /// AC-demagnetized at 0 A, at rest; the command switched on at `t = 0`.
    SwitchOnDemagnetized,
    /// AC-demagnetized at 0 A, brought slowly to the first command, at rest there.
    Demagnetized,
    /// AC-demagnetized around the first command (a demagnetization with that bias).
    DemagnetizedAtFirstInput,
    /// Negative saturation, then slowly to the first command.
    NegativeSaturation,
    /// Positive saturation, then slowly to the first command.
    PositiveSaturation,
    /// The reach swept (top, then bottom), then slowly to the first command.
    Conditioned,
    /// One period of a periodic steady state (the record is played once before it starts).
    Periodic,
    /// The state the previous experiment (file-name order) left.
    Previous,
}

impl StartState {
    /// Every state with its interface name.
    pub const NAMES: [(&'static str, StartState); 8] = [
        ("switch-on-demagnetized", StartState::SwitchOnDemagnetized),
        ("demagnetized", StartState::Demagnetized),
        (
            "demagnetized-at-first-input",
            StartState::DemagnetizedAtFirstInput,
        ),
        ("negative-saturation", StartState::NegativeSaturation),
        ("positive-saturation", StartState::PositiveSaturation),
        ("conditioned", StartState::Conditioned),
        ("periodic", StartState::Periodic),
        ("previous", StartState::Previous),
    ];

    /// The states a bench documents in `dataset.json` and the dynamic model simulates.
    pub const BENCH: [StartState; 6] = [
        StartState::SwitchOnDemagnetized,
        StartState::Demagnetized,
        StartState::NegativeSaturation,
        StartState::PositiveSaturation,
        StartState::Conditioned,
        StartState::Previous,
    ];

    /// Parses an interface name (any state).
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::parse_among(text, &Self::NAMES.map(|(_, s)| s))
    }

    /// Parses an interface name among `allowed`; the error lists them.
    pub fn parse_among(text: &str, allowed: &[StartState]) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .find(|(n, s)| *n == text && allowed.contains(s))
            .map(|(_, s)| *s)
            .ok_or_else(|| {
                format!(
                    "unknown start state `{text}`: expected one of {}",
                    names(allowed)
                )
            })
    }

    /// `self` if it is among `allowed`, else an error naming `what` and the allowed states.
    pub fn require(self, allowed: &[StartState], what: &str) -> Result<Self, String> {
        if allowed.contains(&self) {
            Ok(self)
        } else {
            Err(format!(
                "{what}: start state `{}` is not supported here; expected one of {}",
                self.name(),
                names(allowed)
            ))
        }
    }

    /// The interface name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, s)| *s == self)
            .map_or("?", |(n, _)| n)
    }
}

impl fmt::Display for StartState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for StartState {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for StartState {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = String::deserialize(deserializer)?;
        StartState::parse(&text).map_err(serde::de::Error::custom)
    }
}

/// `a, b, c` of the states' names.
fn names(states: &[StartState]) -> String {
    states
        .iter()
        .map(|s| s.name())
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_errors_list_the_allowed_states() {
        for (name, state) in StartState::NAMES {
            assert_eq!(StartState::parse(name), Ok(state));
            assert_eq!(state.name(), name);
        }
        let e = StartState::parse_among("periodic", &StartState::BENCH).unwrap_err();
        assert!(e.contains("`periodic`") && e.contains("previous"), "{e}");
        assert!(!e.contains("demagnetized-at-first-input"), "{e}");
        let e = StartState::Periodic
            .require(&StartState::BENCH, "--start")
            .unwrap_err();
        assert!(
            e.starts_with("--start: ") && e.contains("switch-on-demagnetized"),
            "{e}"
        );
    }
}
