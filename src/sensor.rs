//! The displacement sample of every control tick: ADC count → metres, and the checks that make
//! a bad sample a fault instead of a number (`sensor` section of the parameter file); and the
//! current monitor's count of the same tick → amperes (`current_monitor`).
//!
//! A sensor at one of its rails (saturated, cable off), a rod beyond its stroke, a count the ADC
//! cannot produce or a non-finite value from a link is a [`SensorFault`]. The control loop
//! latches the first one and ramps the coil to 0 A ([`crate::inverse::ControlLoop::tick_sensed`]).
//!
//! Cost: a compare, a multiply-add and two compares (~10 instructions).

use crate::params::{CurrentMonitorScale, Sensor};

/// Why a sample was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorFault {
    /// The count exceeds the ADC's range (`2^bits − 1`).
    CountOutOfRange,
    /// A reading that is NaN or infinite (from a link, not from an ADC).
    NotFinite,
    /// The reading lies outside `[valid_min_m, valid_max_m]`.
    OutOfValidRange,
    /// No sample arrived in time (a silent sensor or link).
    Missing,
    /// The sample came back bit-identical for `control.feedback.stuck_sensor_ticks` ticks while
    /// the trajectory moved (detected by the feedback).
    Stuck,
}

/// Scaling and validity of the sensor's samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorScale {
    gain_m_per_count: f32,
    offset_m: f32,
    valid_min_m: f32,
    valid_max_m: f32,
    max_count: u32,
}

impl SensorScale {
    /// From the (validated) parameter file's `sensor` section.
    pub const fn new(s: &Sensor) -> Self {
        let bits = if s.adc_bits > 31 { 31 } else { s.adc_bits };
        SensorScale {
            gain_m_per_count: s.gain_m_per_count,
            offset_m: s.offset_m,
            valid_min_m: s.valid_min_m,
            valid_max_m: s.valid_max_m,
            max_count: (1u32 << bits) - 1,
        }
    }

    /// The displacement of an ADC count, m, or the fault.
    #[inline]
    pub fn displacement_m(&self, count: u32) -> Result<f32, SensorFault> {
        if count > self.max_count {
            return Err(SensorFault::CountOutOfRange);
        }
        self.check_m(self.offset_m + self.gain_m_per_count * count as f32)
    }

    /// The reading of an ADC count, m, checked only against the converter's range (not the valid
    /// range): what a measurement records, since identification drives the rod over its whole
    /// stroke.
    #[inline]
    pub fn reading_m(&self, count: u32) -> Result<f32, SensorFault> {
        if count > self.max_count {
            return Err(SensorFault::CountOutOfRange);
        }
        Ok(self.offset_m + self.gain_m_per_count * count as f32)
    }

    /// The coil current of a current-monitor count on the same converter, A (`None`: a count
    /// the ADC cannot produce — the record then holds NaN for the tick, never a made-up value).
    #[inline]
    pub fn monitor_current_a(&self, monitor: &CurrentMonitorScale, count: u32) -> Option<f32> {
        (count <= self.max_count)
            .then_some(monitor.offset_a + monitor.gain_a_per_count * count as f32)
    }

    /// Checks a reading already in metres (a virtual sensor, a link), m, or the fault.
    #[inline]
    pub fn check_m(&self, displacement_m: f32) -> Result<f32, SensorFault> {
        if !displacement_m.is_finite() {
            Err(SensorFault::NotFinite)
        } else if displacement_m < self.valid_min_m || displacement_m > self.valid_max_m {
            Err(SensorFault::OutOfValidRange)
        } else {
            Ok(displacement_m)
        }
    }

    /// The count a sensor reading `displacement_m` produces (rounded, clamped to the ADC's
    /// range; NaN gives 0): what a virtual sensor hands the firmware.
    pub fn count_of(&self, displacement_m: f32) -> u32 {
        let c = (displacement_m - self.offset_m) / self.gain_m_per_count + 0.5;
        if c.is_nan() || c <= 0.0 {
            0
        } else if c >= self.max_count as f32 {
            self.max_count
        } else {
            c as u32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::BAKED_PARAMETERS;

    #[test]
    fn counts_scale_to_metres_and_bad_samples_are_faults() {
        let s = &BAKED_PARAMETERS.sensor;
        let scale = SensorScale::new(s);
        let mid = scale.displacement_m(2048).unwrap();
        assert!((mid - (s.offset_m + 2048.0 * s.gain_m_per_count)).abs() < 1e-12);
        // The rails of the default 12-bit sensor are outside its valid range.
        assert_eq!(scale.displacement_m(0), Err(SensorFault::OutOfValidRange));
        assert_eq!(
            scale.displacement_m(4095),
            Err(SensorFault::OutOfValidRange)
        );
        assert_eq!(
            scale.displacement_m(4096),
            Err(SensorFault::CountOutOfRange)
        );
        assert_eq!(scale.check_m(f32::NAN), Err(SensorFault::NotFinite));
        assert_eq!(scale.check_m(f32::INFINITY), Err(SensorFault::NotFinite));
        assert_eq!(scale.check_m(20e-6), Ok(20e-6));
        // Round trip through the count within half a count.
        for y in [1e-6f32, 10e-6, 25e-6, 40e-6] {
            let back = scale.displacement_m(scale.count_of(y)).unwrap();
            assert!(
                (back - y).abs() <= 0.5 * s.gain_m_per_count + 1e-12,
                "{y} -> {back}"
            );
        }
        assert_eq!(scale.count_of(f32::NAN), 0);
        assert_eq!(scale.count_of(1.0), 4095);
    }

    /// A ±5 A monitor on the 12-bit converter (2.44 mA per count, 0 A at mid-scale).
    #[test]
    fn monitor_counts_scale_to_amperes_and_impossible_counts_are_none() {
        let scale = SensorScale::new(&BAKED_PARAMETERS.sensor);
        let monitor = CurrentMonitorScale {
            gain_a_per_count: 10.0 / 4095.0,
            offset_a: -5.0,
        };
        assert_eq!(scale.monitor_current_a(&monitor, 0), Some(-5.0));
        let top = scale.monitor_current_a(&monitor, 4095).unwrap();
        assert!((top - 5.0).abs() < 1e-5, "{top}");
        let mid = scale.monitor_current_a(&monitor, 2048).unwrap();
        assert!(mid.abs() < 2e-3, "{mid}");
        assert_eq!(scale.monitor_current_a(&monitor, 4096), None);
    }
}
