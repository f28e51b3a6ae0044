//! Output safety between the inverse and the DAC: every command passes through here.
//!
//! * **Non-finite or failed inverse** (NaN/inf anywhere in the desired motion, or a rejected
//!   Preisach solve): the output **holds the last valid current** and raises
//!   [`CommandFlags::FAULT`]. Holding (rather than dropping to zero) keeps the bias field, so the
//!   actuator stays near its operating point instead of slamming to zero displacement; the
//!   controller's memory is left unchanged, so the next valid sample continues from there.
//! * **Magnitude**: clamped to `±current_limit_a` ([`CommandFlags::CURRENT_LIMITED`]).
//! * **Slew**: the change per control period is clamped to `current_slew_limit_a_per_s · h`
//!   ([`CommandFlags::SLEW_LIMITED`]).
//!
//! The inverse is open loop: while a limit is active the actuator no longer follows the inverse's
//! internal `H, M`; the flags make that visible. Nothing here can panic (comparisons and `clamp`
//! with validated, ordered bounds only).

use super::RawCommand;
use crate::params::Control;
use crate::preisach::SolveError;

/// Bit flags of one command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CommandFlags(pub u8);

impl CommandFlags {
    /// The demanded `u = M²` or the magnetization was outside the attainable set and was clamped.
    pub const U_CLAMPED: u8 = 1;
    /// The current was clamped to ±I_max.
    pub const CURRENT_LIMITED: u8 = 2;
    /// The current change was clamped to the slew limit.
    pub const SLEW_LIMITED: u8 = 4;
    /// Non-finite input or rejected solve: the last valid current was held.
    pub const FAULT: u8 = 8;
    /// A sensor fault is latched: the command ramps to 0 A at the slew limit and stays there.
    pub const SENSOR_FAULT: u8 = 16;
    /// The command belongs to the start-up conditioning sequence, not to tracking.
    pub const CONDITIONING: u8 = 32;
    /// The command plays a measurement programme (`ControlLoop::measure_sensed`).
    pub const MEASURE: u8 = 64;
    /// The displacement feedback fell back to the feedforward alone (a sensor fault with the
    /// feedback on).
    pub const FEEDFORWARD: u8 = 128;

    /// Whether `flag` is set.
    pub fn has(self, flag: u8) -> bool {
        self.0 & flag != 0
    }
}

/// Limits of the output stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputLimiter {
    limit_a: f32,
    max_step_a: f32,
}

/// Rejected limiter settings (JSON field path and value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimiterError {
    /// Field path in the parameter file.
    pub field: &'static str,
    /// The value.
    pub value: f32,
}

impl OutputLimiter {
    /// Limits from the control settings; both must be finite and positive.
    pub fn new(control: &Control) -> Result<Self, LimiterError> {
        let limit = control.current_limit_a;
        let slew = control.current_slew_limit_a_per_s;
        let rate = control.sample_rate_hz;
        if !(limit.is_finite() && limit > 0.0) {
            return Err(LimiterError {
                field: "control.current_limit_a",
                value: limit,
            });
        }
        if !(slew.is_finite() && slew > 0.0) {
            return Err(LimiterError {
                field: "control.current_slew_limit_a_per_s",
                value: slew,
            });
        }
        if !(rate.is_finite() && rate > 0.0) {
            return Err(LimiterError {
                field: "control.sample_rate_hz",
                value: rate,
            });
        }
        Ok(OutputLimiter {
            limit_a: limit,
            max_step_a: slew / rate,
        })
    }

    /// ±I_max, A.
    pub fn limit_a(&self) -> f32 {
        self.limit_a
    }

    /// Largest change per period, A.
    pub fn max_step_a(&self) -> f32 {
        self.max_step_a
    }

    /// One step of the ramp to 0 A: `last_current_a` moves toward 0 by at most the slew limit
    /// (a non-finite held value goes to 0 at once). Flags `SENSOR_FAULT` (and `SLEW_LIMITED`
    /// while still ramping).
    #[inline]
    pub fn ramp_to_zero(&self, last_current_a: &mut f32) -> (f32, CommandFlags) {
        let held = if last_current_a.is_finite() {
            *last_current_a
        } else {
            0.0
        };
        // Not `f32::clamp`: it asserts its bounds are ordered, a panic path in the interrupt.
        let step = if held > self.max_step_a {
            self.max_step_a
        } else if held < -self.max_step_a {
            -self.max_step_a
        } else {
            held
        };
        let out = held - step;
        *last_current_a = out;
        let mut flags = CommandFlags::SENSOR_FAULT;
        if out != 0.0 {
            flags |= CommandFlags::SLEW_LIMITED;
        }
        (out, CommandFlags(flags))
    }

    /// The safe output for a raw inverse result; updates `last_current_a` (the held value).
    #[inline]
    pub fn apply(
        &self,
        last_current_a: &mut f32,
        raw: &Result<RawCommand, SolveError>,
    ) -> (f32, CommandFlags) {
        let mut flags = 0u8;
        let requested = match raw {
            Ok(cmd) if cmd.current_a.is_finite() => {
                if cmd.clamped {
                    flags |= CommandFlags::U_CLAMPED;
                }
                cmd.current_a
            }
            _ => return (*last_current_a, CommandFlags(CommandFlags::FAULT)),
        };
        let mut out = requested;
        if out > self.limit_a {
            out = self.limit_a;
            flags |= CommandFlags::CURRENT_LIMITED;
        } else if out < -self.limit_a {
            out = -self.limit_a;
            flags |= CommandFlags::CURRENT_LIMITED;
        }
        let lo = *last_current_a - self.max_step_a;
        let hi = *last_current_a + self.max_step_a;
        if out > hi {
            out = hi;
            flags |= CommandFlags::SLEW_LIMITED;
        } else if out < lo {
            out = lo;
            flags |= CommandFlags::SLEW_LIMITED;
        }
        *last_current_a = out;
        (out, CommandFlags(flags))
    }
}
