//! `maglab identify`: a dataset of quasi-static measurements → the full parameter file.
//!
//! Steps: read the dataset (`maglab_dataset::data`); `H = c0 I`; `M` from the displacement through the
//! static model (6) ([`crate::magnetization`], sign convention as chosen); fit the 325 masses on
//! the grid of the base file ([`crate::fit`]) with the base masses as prior; write the base file
//! with the masses replaced and a provenance that records the dataset, the date, the options, the
//! residuals and the unexcited cells.
//!
//! This stage identifies the Preisach masses only: `R_eddy`, `ξ` and `f0` are copied from the base
//! file and listed in the provenance's `not_identified`. `maglab identify` then runs the dynamic
//! stage ([`crate::dynamics::fit_eddy_and_damping`]: the phase-lag scheme of Section 4 and the
//! direct waveform fit) on the dataset's dynamic experiments and records its result with
//! [`crate::dynamics::record::record`], which replaces the three values and removes them from
//! `not_identified`. `M_s`, `λ_s`, `l_m`, `c0`, `N_m`, `A_m` are the manufacturer's constants in
//! the paper and are copied.

use crate::cell_of_index;
use crate::design::{Experiment, Grid};
use crate::fit::{fit, FitError, FitOptions, FitResult, Unexcited};
use crate::magnetization::{magnetization, Branch, StaticModel};
use crate::model::{nrmse, PreisachModel, FORMAT};
use crate::reach::{banded_grid, identification_grid, prefers_banded, IdentificationGrid, Reach};
use actuator_params::{ActuatorParams, Provenance};
use maglab_dataset::data::Dataset;
use maglab_dataset::StartState;
use serde_json::{json, Map, Value};

/// Options of `identify`.
#[derive(Debug, Clone, PartialEq)]
pub struct MassOptions {
    /// Sign convention for M (`None`: per file, [`auto_branch`]).
    pub branch: Option<Branch>,
    /// Initial memory of every file (`None`: per file, as `dataset.json` documents it, else
    /// [`auto_initial`]).
    pub initial: Option<StartState>,
    /// The dataset's `dataset.json`, when it has one.
    pub documented: Option<maglab_dataset::dataset_info::DatasetInfo>,
    /// Zero band of the monotone sign rule, as a fraction of the full stroke `l_m λ_s`.
    pub zero_band_fraction: f64,
    /// The fit.
    pub fit: FitOptions,
    /// `[R_eddy Ω, ξ, f0 Hz]` for the first-order lag corrections of a finite-rate record
    /// ([`LagCorrection`]); `None`: no correction (the static model (6) as it stands).
    pub lag_correction: Option<[f64; 3]>,
    /// Where the current is read for each displacement sample, in samples after the current's
    /// own sample time: the channel skew (the displacement read that much later), less half a
    /// sample when the current is held between samples (a held current is the linear one half
    /// a sample late). 0: both channels sampled at once, the current linear between samples.
    /// The dynamic fit estimates both nuisances on the sines (`maglab_diagnose::identification`);
    /// the sweep's masses must see the same timing as the model they go into, else the few
    /// tens of µs go into the loops' width, and the minor loops the sines run on come out wrong.
    pub current_shift_samples: f64,
    /// The field range of the whole dataset (quasi-static and dynamic records), which sets the
    /// grid ([`crate::reach`]); `None`: the range of the records given.
    pub reach: Option<Reach>,
}

/// `x` read `shift` samples later: linear between samples, held at the ends.
pub fn shifted(x: &[f64], shift: f64) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    (0..n)
        .map(|k| {
            let t = (k as f64 + shift).clamp(0.0, (n - 1) as f64);
            let i = (t.floor() as usize).min(n - 1);
            let j = (i + 1).min(n - 1);
            x[i] + (t - i as f64) * (x[j] - x[i])
        })
        .collect()
}

/// Per-file diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct FileReport {
    /// File name.
    pub file: String,
    /// Samples.
    pub samples: usize,
    /// Samples with negative displacement (clipped to M = 0).
    pub clipped_negative: usize,
    /// Samples above the full stroke.
    pub above_stroke: usize,
    /// Sign changes of M assigned by the monotone rule.
    pub sign_changes: usize,
    /// White-noise level of the displacement, m ([`displacement_noise_m`]).
    pub noise_m: f64,
    /// Rows whose `u` lies below this are left out of the regression, m ([`fit_floor_m`]).
    pub fit_floor_m: f64,
    /// Selected rows left out by that floor.
    pub rows_below_floor: usize,
    /// NRMSE of the predicted magnetization.
    pub nrmse_magnetization: Option<f64>,
    /// NRMSE of the predicted displacement (static model (6)).
    pub nrmse_displacement: Option<f64>,
    /// Field (A/m), measured-converted M and predicted M, for plots.
    pub h_a_per_m: Vec<f64>,
    /// M from the measured displacement, A/m.
    pub m_measured_a_per_m: Vec<f64>,
    /// M predicted by the identified model, A/m.
    pub m_predicted_a_per_m: Vec<f64>,
    /// Where the record's start state came from.
    pub start_from: StartFrom,
}

/// Where a quasi-static record's start state came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartFrom {
    /// `--initial`.
    Given,
    /// `dataset.json`.
    Documented,
    /// Not documented: estimated ([`auto_initial`]).
    Estimated,
    /// Documented `previous`, which a quasi-static record is not continued from (the records
    /// before it, dynamic ones included, are not simulated here): estimated as [`Estimated`]
    /// is, and said so, since the estimate does not see the memory those records left.
    ///
    /// [`Estimated`]: StartFrom::Estimated
    EstimatedForPrevious,
}

impl StartFrom {
    /// The provenance's `initial_state_from`.
    pub fn name(self) -> &'static str {
        match self {
            StartFrom::Given => "given",
            StartFrom::Documented => "documented",
            StartFrom::Estimated => "estimated",
            StartFrom::EstimatedForPrevious => "estimated (documented previous)",
        }
    }
}

/// The result of `identify`.
#[derive(Debug, Clone, PartialEq)]
pub struct MassIdentification {
    /// The full parameter file (validated).
    pub params: ActuatorParams,
    /// The fit.
    pub fit: FitResult,
    /// Per-file diagnostics.
    pub files: Vec<FileReport>,
}

/// First-order lag corrections of a finite-rate quasi-static record (the static model (6)
/// relates `H` and `u = l_m λ_s M²/M_s²`, not `c0 I` and `y`):
///
/// * mechanics, eq. (5): `u = y + (2ξ/ω0) y' + y''/ω0²` ([`LagCorrection::displacement`]; the rod
///   lags `u` by `2ξ/ω0` ≈ 0.6 ms);
/// * eddy currents, eq. (4): `H = c0 I − τ_e (H' + M')` with `τ_e = c0/c1`, to first order
///   `H ≈ c0 I − τ_e (c0 I' + M')` ([`LagCorrection::field`]): on a steep branch `M' = χ H'` with
///   χ in the hundreds, so even a 1 Hz sweep lags by ~0.1 cell there, a few % of `M_s` in `M`.
///
/// Derivatives are central differences across `±w` samples of a centred moving average over
/// `2w + 1` samples, `w` ≈ 0.5 ms: the noise of `y''` falls as `w⁻²·⁵` while a sweep slower than
/// ~10 Hz is not distorted.
#[derive(Debug, Clone, Copy)]
pub struct LagCorrection {
    tau_e: f64,
    damping_ratio: f64,
    omega0: f64,
    c0: f64,
}

impl LagCorrection {
    /// For the constants of `base` with `[R_eddy Ω, ξ, f0 Hz]`.
    pub fn new(base: &ActuatorParams, [r_eddy, xi, f0]: [f64; 3]) -> Self {
        let a = &base.actuator;
        let mu0 = 4e-7 * std::f64::consts::PI;
        let c1 = r_eddy / (mu0 * a.coil_turns * a.rod_area_m2);
        LagCorrection {
            tau_e: a.coil_factor_per_m / c1,
            damping_ratio: xi,
            omega0: 2.0 * std::f64::consts::PI * f0,
            c0: a.coil_factor_per_m,
        }
    }

    fn half_width(step_s: f64) -> usize {
        ((0.5e-3 / step_s).round() as usize).max(1)
    }

    fn smooth(x: &[f64], w: usize) -> Vec<f64> {
        let n = x.len();
        let mut prefix = vec![0.0; n + 1];
        for k in 0..n {
            prefix[k + 1] = prefix[k] + x[k];
        }
        (0..n)
            .map(|k| {
                let (lo, hi) = (k.saturating_sub(w), (k + w).min(n - 1));
                (prefix[hi + 1] - prefix[lo]) / (hi - lo + 1) as f64
            })
            .collect()
    }

    fn d1(x: &[f64], k: usize, w: usize, step_s: f64) -> f64 {
        let (lo, hi) = (k.saturating_sub(w), (k + w).min(x.len() - 1));
        if hi == lo {
            0.0
        } else {
            (x[hi] - x[lo]) / ((hi - lo) as f64 * step_s)
        }
    }

    /// `u` from the displacement `y` (offset already removed).
    pub fn displacement(&self, y: &[f64], step_s: f64) -> Vec<f64> {
        let n = y.len();
        let w = Self::half_width(step_s);
        let ys = Self::smooth(y, w);
        (0..n)
            .map(|k| {
                let d2 = if k < w || k + w >= n {
                    0.0
                } else {
                    (ys[k + w] - 2.0 * ys[k] + ys[k - w]) / (w as f64 * step_s).powi(2)
                };
                y[k] + 2.0 * self.damping_ratio / self.omega0 * Self::d1(&ys, k, w, step_s)
                    + d2 / (self.omega0 * self.omega0)
            })
            .collect()
    }

    /// How much [`LagCorrection::displacement`] amplifies white noise in `y`: the RMS of its
    /// output for white noise of unit RMS (the root sum of squares of its impulse response, away
    /// from the record's ends).
    pub fn noise_gain(&self, step_s: f64) -> f64 {
        let w = Self::half_width(step_s);
        let n = 8 * w + 1;
        let mut impulse = vec![0.0; n];
        impulse[n / 2] = 1.0;
        self.displacement(&impulse, step_s)
            .iter()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt()
    }

    /// `H` from the current and the (signed) magnetization.
    pub fn field(&self, current_a: &[f64], m_a_per_m: &[f64], step_s: f64) -> Vec<f64> {
        let w = Self::half_width(step_s);
        let is = Self::smooth(current_a, w);
        let ms = Self::smooth(m_a_per_m, w);
        (0..current_a.len())
            .map(|k| {
                self.c0 * current_a[k]
                    - self.tau_e
                        * (self.c0 * Self::d1(&is, k, w, step_s) + Self::d1(&ms, k, w, step_s))
            })
            .collect()
    }
}

/// The white-noise level of a record's displacement, m: from its second differences
/// `y[k+1] − 2 y[k] + y[k−1]`, whose noise is `√6 σ` and whose signal is nil on a slow record but
/// at its reversals — hence the median absolute deviation (`σ = 1.4826 · MAD / √6`), which the
/// few reversal samples do not move. 0 for fewer than 3 samples.
pub fn displacement_noise_m(y: &[f64]) -> f64 {
    let mut d2: Vec<f64> = y
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    if d2.is_empty() {
        return 0.0;
    }
    let mid = d2.len() / 2;
    let (_, median, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *median / 6f64.sqrt()
}

/// Largest relative bias of `|M| = M_s √(u / (l_m λ_s))` that a fitted row may carry from the
/// noise of `u`. The square root is concave, so noise of RMS `σ_u` biases it low by
/// `σ_u² / (8 u²)` of itself (second order): near `M = 0`, on the steep branch around the coercive
/// field, that is percents, the masses there come out low and R_eddy, ξ, f0 bend to make up for
/// it (measured on `maglab rig` folders: R_eddy +8.2 % at σ = 0.5 µm with the fixed zero band,
/// +2.5 % with this bound, +1.4 % without noise).
pub const SQRT_NOISE_BIAS_MAX: f64 = 0.001;

/// The fit floor never passes this fraction of the stroke `l_m λ_s` (`|M| = 0.32 M_s`): a record
/// so noisy, or sampled so coarsely that its own curvature reads as noise, keeps its rows above.
pub const FIT_FLOOR_MAX_FRACTION: f64 = 0.1;

/// The smallest `u` (m) whose row enters the regression: the zero band (`zero_band_m`: below it
/// the sign of `M` is uncertain) or, when the noise is larger, where the square root's noise bias
/// reaches [`SQRT_NOISE_BIAS_MAX`]: `u = σ_u / √(8 · SQRT_NOISE_BIAS_MAX)` ≈ 11 σ_u, that never
/// above [`FIT_FLOOR_MAX_FRACTION`] of the stroke `stroke_m`.
pub fn fit_floor_m(zero_band_m: f64, noise_u_m: f64, stroke_m: f64) -> f64 {
    let noise_floor_m = noise_u_m / (8.0 * SQRT_NOISE_BIAS_MAX).sqrt();
    zero_band_m.max(noise_floor_m.min(FIT_FLOOR_MAX_FRACTION * stroke_m))
}

/// The sensor offset, m: in a bipolar quasi-static record the magnetization crosses zero, where
/// `y = l_m λ_s M²/M_s²` vanishes, so the floor of the measured displacement is the offset. The
/// floor is the minimum of a moving average over `max(5, n/2000)` samples (the noise averaged
/// down); the median over the bipolar records (`None` when there is none). Records whose field
/// never leaves the grid's middle (|H| below a tenth of the range) are not bipolar enough.
pub fn displacement_offset_m(dataset: &Dataset, c0: f64, grid: &Grid) -> Option<f64> {
    let span = grid.h_max - grid.h_min;
    let mut floors: Vec<f64> = dataset
        .measurements
        .iter()
        .filter(|m| {
            let (lo, hi) = m
                .current_a
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
                    (a.min(c0 * i), b.max(c0 * i))
                });
            lo < -0.1 * span && hi > 0.1 * span
        })
        .filter_map(|m| {
            let y = &m.displacement_m;
            let w = (y.len() / 2000).max(5);
            if y.len() < w {
                return None;
            }
            let mut sum: f64 = y[..w].iter().sum();
            let mut floor = sum / w as f64;
            for k in w..y.len() {
                sum += y[k] - y[k - w];
                floor = floor.min(sum / w as f64);
            }
            Some(floor)
        })
        .collect();
    if floors.is_empty() {
        return None;
    }
    floors.sort_by(f64::total_cmp);
    Some(floors[floors.len() / 2])
}

/// The sign convention a file needs: `monotone` when its current changes sign (bipolar data:
/// the magnetization changes sign too), else `positive` (DC-biased data from a state at zero).
pub fn auto_branch(current_a: &[f64]) -> Branch {
    let (lo, hi) = current_a
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo < 0.0 && hi > 0.0 {
        Branch::Monotone
    } else {
        Branch::Positive
    }
}

/// The initial memory of an undocumented file, from its field `h` and displacement `y` (white
/// noise `noise_m`): a record that starts beyond an end of the grid saturates the memory itself;
/// a closed record (first and last samples within 2 % of the field range, at least one
/// reversal) is a period of a periodic loop — unless it holds two periods and its first differs
/// from its second ([`first_period_is_a_transient`]): then it was switched on from a
/// demagnetized rod and its first period is the way onto the loop. Any other record starts from
/// a demagnetization at zero current.
pub fn auto_initial(h: &[f64], y: &[f64], noise_m: f64, grid: &Grid) -> StartState {
    let (Some(&first), Some(&last)) = (h.first(), h.last()) else {
        return StartState::Demagnetized;
    };
    if first <= grid.h_min {
        return StartState::NegativeSaturation;
    }
    if first >= grid.h_max {
        return StartState::PositiveSaturation;
    }
    let (lo, hi) = h
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let reversal = h.windows(3).any(|w| (w[1] - w[0]) * (w[2] - w[1]) < 0.0);
    let closed = reversal && (first - last).abs() <= 0.02 * (hi - lo);
    if closed && !first_period_is_a_transient(h, y, noise_m) {
        StartState::Periodic
    } else {
        StartState::Demagnetized
    }
}

/// Whether the displacement over the first period of the input differs from the second by more
/// than two noisy copies of one loop would: RMS difference above `max(3 √2 σ, 10⁻³ of the
/// displacement's range)` (the difference of two records with white noise σ has RMS `√2 σ`; the
/// floor covers noise-free records). The period ends where the input first returns to its first
/// value moving the way it started, after a reversal. `false` when the record holds less than
/// two periods (nothing to compare).
pub fn first_period_is_a_transient(h: &[f64], y: &[f64], noise_m: f64) -> bool {
    let n = h.len().min(y.len());
    let Some(&h0) = h.first() else {
        return false;
    };
    let Some(direction) = h
        .iter()
        .map(|&v| v - h0)
        .find(|d| *d != 0.0)
        .map(f64::signum)
    else {
        return false;
    };
    let mut reversed = false;
    let mut period = None;
    for t in 1..n {
        let step = h[t] - h[t - 1];
        if step * direction < 0.0 {
            reversed = true;
        }
        let crossed = (h[t - 1] - h0) * direction < 0.0 && (h[t] - h0) * direction >= 0.0;
        if reversed && crossed && step * direction > 0.0 {
            period = Some(t);
            break;
        }
    }
    let Some(p) = period.filter(|&p| 2 * p <= n) else {
        return false;
    };
    let (lo, hi) = y[..2 * p]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let rms = (y[..p]
        .iter()
        .zip(&y[p..2 * p])
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / p as f64)
        .sqrt();
    rms > (3.0 * std::f64::consts::SQRT_2 * noise_m).max(1e-3 * (hi - lo))
}

/// The Preisach memory a documented bench start leaves (`switch-on-demagnetized` is
/// `demagnetized` for the memory); `previous` has none of its own: `None`, the file's start is
/// then estimated.
pub fn documented_initial(start: StartState) -> Option<StartState> {
    match start {
        StartState::SwitchOnDemagnetized => Some(StartState::Demagnetized),
        StartState::Previous => None,
        other => Some(other),
    }
}

/// Identifies the Preisach masses from `dataset` on the grid of `base` (see the module docs).
pub fn identify_masses(
    dataset: &Dataset,
    base: &ActuatorParams,
    base_name: &str,
    options: &MassOptions,
) -> Result<MassIdentification, FitError> {
    let a = &base.actuator;
    let base_grid =
        Grid::of_params(&base.preisach).map_err(|e| FitError(format!("{base_name}: {e}")))?;
    let reach = options
        .reach
        .or_else(|| {
            Reach::of_currents(
                dataset.measurements.iter().map(|m| &m.current_a[..]),
                a.coil_factor_per_m,
            )
        })
        .ok_or_else(|| FitError(format!("{}: no finite current", dataset.dir.display())))?;
    let chosen = identification_grid(base_grid, reach);
    let on_base = identify_on_grid(dataset, base, base_name, options, chosen)?;
    if chosen.has_bands() {
        return Ok(on_base);
    }
    // The records cover the base grid: whether the coil saturates the rod there is for the data
    // to say. The banded grid is the larger model (its bands empty, it is the base grid's plane
    // on slightly coarser cells); it is kept when it explains the quasi-static rows better by
    // more than its extra parameters are worth (`prefers_banded`).
    let Some(banded) = banded_grid(base_grid, reach) else {
        return Ok(on_base);
    };
    let on_bands = identify_on_grid(dataset, base, base_name, options, banded)?;
    Ok(if prefers_banded(&on_base.fit, &on_bands.fit) {
        on_bands
    } else {
        on_base
    })
}

/// The mass identification on one grid.
fn identify_on_grid(
    dataset: &Dataset,
    base: &ActuatorParams,
    base_name: &str,
    options: &MassOptions,
    mut chosen: IdentificationGrid,
) -> Result<MassIdentification, FitError> {
    let a = &base.actuator;
    let model = StaticModel {
        rod_length_m: a.rod_length_m,
        saturation_magnetostriction: a.saturation_magnetostriction,
        saturation_magnetization_a_per_m: a.saturation_magnetization_a_per_m,
    };
    let base_grid =
        Grid::of_params(&base.preisach).map_err(|e| FitError(format!("{base_name}: {e}")))?;
    // A documented `conditioned` start is the sweep the base file's firmware ran.
    let sweep = maglab_model::model::Nominal::from_params(base)
        .conditioning_sweep_a_per_m
        .map(|(lo, hi)| (f64::from(lo), f64::from(hi)));
    chosen.grid = chosen.grid.with_conditioning(sweep);
    let grid = chosen.grid;
    let zero_band_m = options.zero_band_fraction * model.stroke_m();
    let sensor_offset_m = displacement_offset_m(dataset, a.coil_factor_per_m, &base_grid);
    let records: Vec<Record> = dataset
        .measurements
        .iter()
        .map(|m| {
            let setting = RecordSetting {
                base,
                model: &model,
                grid: &grid,
                reach: chosen.reach,
                zero_band_m,
                sensor_offset_m: sensor_offset_m.unwrap_or(0.0),
                options,
            };
            setting.convert(m)
        })
        .collect();
    let (selected, rows_below_floor) = select_rows(&records, &model, zero_band_m);
    let experiments: Vec<Experiment<'_>> = records
        .iter()
        .zip(&selected)
        .map(|(r, selected)| Experiment {
            label: &r.label,
            input: &r.field,
            output: &r.conversion.m_a_per_m,
            selected,
            initial: r.initial,
            weights: None,
        })
        .collect();
    let fit_options = fit_options(&chosen, options, &model);
    let prior = (!chosen.has_bands()).then_some(&base.preisach.weights_a_per_m[..]);
    let result = fit(&grid, &experiments, prior, &fit_options)?;
    let files = file_reports(
        dataset,
        &records,
        &rows_below_floor,
        &grid,
        &result,
        &fit_options,
        &model,
    );
    let choices: Vec<Value> = records.iter().map(|r| r.choice.clone()).collect();
    let params = identified_params(
        (dataset, base, base_name),
        (&chosen, options, &fit_options),
        &result,
        &files,
        &choices,
        sensor_offset_m,
    )?;
    Ok(MassIdentification {
        params,
        fit: result,
        files,
    })
}

/// One quasi-static record made ready for the mass fit.
struct Record {
    /// File name.
    label: String,
    /// The field `H` (lag-corrected), A/m.
    field: Vec<f64>,
    /// `M` from the (lag-corrected, offset-free) displacement.
    conversion: crate::magnetization::Conversion,
    /// The start state the record is simulated from.
    initial: StartState,
    /// The displacement the masses are fitted to (lag-corrected), m.
    displacement_m: Vec<f64>,
    /// White-noise level of the displacement, m.
    noise_m: f64,
    /// Rows below this displacement are left out, m.
    floor_m: f64,
    /// How the start state and the sign convention were chosen, for the provenance.
    choice: Value,
    /// Where the start state came from.
    start_from: StartFrom,
}

/// What every record's conversion shares.
struct RecordSetting<'a> {
    base: &'a ActuatorParams,
    model: &'a StaticModel,
    grid: &'a Grid,
    /// The reach of a grid with bands: the lag-corrected field is kept inside it.
    reach: Option<Reach>,
    zero_band_m: f64,
    sensor_offset_m: f64,
    options: &'a MassOptions,
}

impl RecordSetting<'_> {
    /// The record `m` with its current read at the fit's timing, the sensor offset removed,
    /// the lags corrected, its start state and sign convention chosen, converted to `M`.
    fn convert(&self, m: &maglab_dataset::data::Measurement) -> Record {
        let (a, options) = (&self.base.actuator, self.options);
        let correction = options
            .lag_correction
            .map(|c| LagCorrection::new(self.base, c));
        let current_a = shifted(&m.current_a, options.current_shift_samples);
        let h_static: Vec<f64> = current_a.iter().map(|i| a.coil_factor_per_m * i).collect();
        let y: Vec<f64> = m
            .displacement_m
            .iter()
            .map(|y| y - self.sensor_offset_m)
            .collect();
        let noise_m = displacement_noise_m(&y);
        let gain = correction.map_or(1.0, |c| c.noise_gain(m.step_s));
        let displacement = match &correction {
            Some(c) => c.displacement(&y, m.step_s),
            None => y,
        };
        let name = m.path.file_name().map_or_else(
            || m.path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        let documented = options.documented.as_ref().and_then(|d| d.start_of(&name));
        let (initial, start_from) = match options.initial {
            Some(i) => (i, StartFrom::Given),
            None => match documented.and_then(documented_initial) {
                Some(i) => (i, StartFrom::Documented),
                None => (
                    auto_initial(&h_static, &displacement, noise_m, self.grid),
                    if documented == Some(StartState::Previous) {
                        StartFrom::EstimatedForPrevious
                    } else {
                        StartFrom::Estimated
                    },
                ),
            },
        };
        let branch = options.branch.unwrap_or_else(|| auto_branch(&current_a));
        // The zero band guards the sign of M; with `positive` there is no sign to guess, only
        // the square root's noise bias sets the floor (on a rod the coil cannot saturate the
        // whole motion may lie within a few zero bands of rest).
        let band_m = match branch {
            Branch::Positive => 0.0,
            Branch::Monotone => self.zero_band_m,
        };
        let floor_m = fit_floor_m(band_m, gain * noise_m, self.model.stroke_m());
        let initial_sign: i8 = match initial {
            StartState::NegativeSaturation | StartState::Conditioned => -1,
            StartState::PositiveSaturation => 1,
            _ => 0,
        };
        let conversion = magnetization(
            self.model,
            &displacement,
            &h_static,
            branch,
            initial_sign,
            self.zero_band_m,
        );
        let mut field = match &correction {
            Some(c) => c.field(&current_a, &conversion.m_a_per_m, m.step_s),
            None => h_static,
        };
        // Eq. (4) moves H toward c0 I at every instant (H' = c1 (I − H/c0) / (1 + dM/dH) with
        // dM/dH >= 0), so H never leaves the range of c0 I. The first-order correction can
        // overshoot it by its noise; inside a band that would fake an excitation of cells the
        // coil never switches, which only the offset could balance.
        if let Some(r) = self.reach {
            for h in &mut field {
                *h = h.clamp(r.lo_a_per_m, r.hi_a_per_m);
            }
        }
        Record {
            choice: json!({"file": name, "initial_state": initial.name(), "initial_state_from": start_from.name(), "branch": branch.name()}),
            label: name,
            start_from,
            field,
            conversion,
            initial,
            displacement_m: displacement,
            noise_m,
            floor_m,
        }
    }
}

/// The rows each record's regression keeps, and how many between the zero band and the fit
/// floor it leaves out. Rows whose |M| lies below the fit floor are left out: inside the zero
/// band the sign of M is uncertain, and near zero M = M_s √(u/S) turns the sensor noise into
/// tens of kA/m (dM/du grows as 1/√u) with a bias (`fit_floor_m`). The memory still sees them.
fn select_rows(
    records: &[Record],
    model: &StaticModel,
    zero_band_m: f64,
) -> (Vec<Vec<bool>>, Vec<usize>) {
    // |M| at u (static model (6)).
    let m_at = |u_m: f64| model.saturation_magnetization_a_per_m * (u_m / model.stroke_m()).sqrt();
    let m_zero_band = m_at(zero_band_m);
    records
        .iter()
        .map(|r| {
            let m_floor = m_at(r.floor_m);
            let kept: Vec<bool> = r
                .conversion
                .m_a_per_m
                .iter()
                .map(|m| m.abs() >= m_floor)
                .collect();
            let below = r
                .conversion
                .m_a_per_m
                .iter()
                .filter(|m| (m_zero_band..m_floor).contains(&m.abs()))
                .count();
            (kept, below)
        })
        .unzip()
}

/// The fit's options on the chosen grid. With a reversible part the masses saturate at M_s
/// (Σ masses <= M_s) and the part carries the magnetization beyond it (the paper's model alone
/// keeps its masses free: what they absorb past M_s is what `--reversible auto` looks at). On a
/// grid with one-way bands ([`crate::reach`]) the output gets its offset `M_off`, the masses have
/// no prior (the base grid's cells are not these) and sum to at most M_s (they are parts of the
/// rod's plane), and unexcited cells the base would have kept are left to the regularization
/// (band cells: fixed at 0, [`crate::fit::Bands`]).
fn fit_options(
    chosen: &IdentificationGrid,
    options: &MassOptions,
    model: &StaticModel,
) -> FitOptions {
    let ms = model.saturation_magnetization_a_per_m;
    let mut fit_options = FitOptions {
        total_mass_at_most: if options.fit.reversible.is_piecewise() {
            Some(options.fit.total_mass_at_most.map_or(ms, |cap| cap.min(ms)))
        } else {
            options.fit.total_mass_at_most
        },
        ..options.fit
    };
    if chosen.has_bands() {
        fit_options.reversible = fit_options.reversible.with_offset();
        fit_options.bands = chosen.bands;
        // The cells are parts of the rod's plane, whose whole mass is at most M_s (|M| <= M_s).
        fit_options.total_mass_at_most =
            Some(fit_options.total_mass_at_most.map_or(ms, |cap| cap.min(ms)));
        if fit_options.unexcited == Unexcited::KeepPrior {
            fit_options.unexcited = Unexcited::Regularized;
        }
    }
    fit_options
}

/// Each record's report: its conversion and how the identified model predicts it.
fn file_reports(
    dataset: &Dataset,
    records: &[Record],
    rows_below_floor: &[usize],
    grid: &Grid,
    result: &FitResult,
    fit_options: &FitOptions,
    model: &StaticModel,
) -> Vec<FileReport> {
    let generic = PreisachModel {
        format: FORMAT.into(),
        input_column: "h_a_per_m".into(),
        output_column: "m_a_per_m".into(),
        levels: crate::LEVELS,
        h_min: grid.h_min,
        h_max: grid.h_max,
        grid_lines: grid.lines.map(|l| l.to_vec()),
        weights: result.weights.clone(),
        offset: result.offset,
        slope: 0.0,
        reversible_slopes: fit_options
            .reversible
            .is_piecewise()
            .then(|| result.reversible_slopes.clone()),
        initial_state: records
            .first()
            .map(|r| r.initial)
            .unwrap_or(StartState::NegativeSaturation),
        closed_loops_periodic: false,
        provenance: Value::Null,
    };
    records
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let m_pred = generic.predict(&r.field, r.initial);
            let y_pred: Vec<f64> = m_pred.iter().map(|&m| model.displacement_m(m)).collect();
            FileReport {
                file: r.label.clone(),
                samples: dataset.measurements[k].len(),
                clipped_negative: r.conversion.clipped_negative,
                above_stroke: r.conversion.above_stroke,
                sign_changes: r.conversion.sign_changes,
                noise_m: r.noise_m,
                fit_floor_m: r.floor_m,
                rows_below_floor: rows_below_floor[k],
                nrmse_magnetization: nrmse(&m_pred, &r.conversion.m_a_per_m, None),
                nrmse_displacement: nrmse(&y_pred, &r.displacement_m, None),
                h_a_per_m: r.field.clone(),
                m_measured_a_per_m: r.conversion.m_a_per_m.clone(),
                m_predicted_a_per_m: m_pred,
                start_from: r.start_from,
            }
        })
        .collect()
}

/// The base file with the identified masses (and reversible part; on a grid with bands the grid,
/// the reach and the offset) and the provenance, validated.
fn identified_params(
    (dataset, base, base_name): (&Dataset, &ActuatorParams, &str),
    (chosen, options, fit_options): (&IdentificationGrid, &MassOptions, &FitOptions),
    result: &FitResult,
    files: &[FileReport],
    choices: &[Value],
    sensor_offset_m: Option<f64>,
) -> Result<ActuatorParams, FitError> {
    let mut params = base.clone();
    let p = &mut params.preisach;
    p.weights_a_per_m = result.weights.clone();
    p.reversible_susceptibility = fit_options
        .reversible
        .is_piecewise()
        .then(|| result.reversible_slopes.clone());
    if let Some(reach) = chosen.reach {
        p.h_min_a_per_m = chosen.grid.h_min;
        p.h_max_a_per_m = chosen.grid.h_max;
        p.grid_lines_a_per_m = chosen.grid.lines.map(|l| l.to_vec());
        p.reach_a_per_m = Some(vec![reach.lo_a_per_m, reach.hi_a_per_m]);
        p.offset_a_per_m = result.offset;
    }
    let mut prov = provenance(
        (dataset, base, base_name),
        (options, fit_options),
        result,
        files,
        choices,
    );
    prov.details.insert(
        "sensor_offset_m".into(),
        json!({
            "value": sensor_offset_m.unwrap_or(0.0),
            "how": if sensor_offset_m.is_some() {
                "estimated: the floor of the displacement where M crosses zero in the bipolar \
                 quasi-static records (median over them), subtracted before M = +/- M_s sqrt(y / (l_m lambda_s))"
            } else {
                "assumed 0: no bipolar quasi-static record (M never crosses zero) to estimate it from"
            },
        }),
    );
    prov.details
        .insert("grid".into(), grid_provenance(chosen, base));
    params.provenance = prov;
    params
        .validate("identified parameters")
        .map_err(|e| FitError(format!("the identified parameters do not validate: {e}")))?;
    Ok(params)
}

/// The file's fields the mass fit identified.
fn identified_fields(fit_options: &FitOptions) -> Vec<&'static str> {
    let mut fields = vec!["preisach.weights_a_per_m"];
    if fit_options.reversible.is_piecewise() {
        fields.push("preisach.reversible_susceptibility");
    }
    if fit_options.bands != Default::default() {
        fields.extend([
            "preisach.h_min_a_per_m",
            "preisach.h_max_a_per_m",
            "preisach.reach_a_per_m",
            "preisach.offset_a_per_m",
        ]);
    }
    fields
}

/// How the grid was chosen, for the provenance.
fn grid_provenance(chosen: &IdentificationGrid, base: &ActuatorParams) -> Value {
    match chosen.reach {
        None => json!({
            "choice": "base",
            "why": "the records reach both ends of the base file's grid: the coil saturates the rod there",
        }),
        Some(reach)
            if reach.lo_a_per_m <= base.preisach.h_min_a_per_m
                && reach.hi_a_per_m >= base.preisach.h_max_a_per_m =>
        {
            json!({
                "choice": "reach",
                "reach_a_per_m": [reach.lo_a_per_m, reach.hi_a_per_m],
                "base_range_a_per_m": [base.preisach.h_min_a_per_m, base.preisach.h_max_a_per_m],
                "bands": {"low": true, "high": true},
                "why": "the records cover the base file's grid but the rod was not saturated there:                         the fit with a one-way band beyond each end of the reach and the offset                         preisach.offset_a_per_m explains the quasi-static rows better than the base                         grid by more than the Bayesian information criterion charges for the band                         cells (docs/model.md)",
            })
        }
        Some(reach) => json!({
            "choice": "reach",
            "reach_a_per_m": [reach.lo_a_per_m, reach.hi_a_per_m],
            "base_range_a_per_m": [base.preisach.h_min_a_per_m, base.preisach.h_max_a_per_m],
            "bands": {"low": chosen.bands.low, "high": chosen.bands.high},
            "why": "the base file's grid extends beyond the field the records reach (c0 times their \
                    current extremes): the grid divides the reach, a band interval beyond each \
                    unreached end holds the one-way hysterons there, and the output offset \
                    preisach.offset_a_per_m the part no reachable field switches (docs/model.md)",
        }),
    }
}

fn provenance(
    (dataset, base, base_name): (&Dataset, &ActuatorParams, &str),
    (options, fit_options): (&MassOptions, &FitOptions),
    result: &FitResult,
    files: &[FileReport],
    choices: &[Value],
) -> Provenance {
    let mut d = Map::new();
    d.insert("dataset".into(), json!(dataset.dir.display().to_string()));
    d.insert(
        "dataset_files".into(),
        json!(files
            .iter()
            .map(|f| json!({
                "file": f.file,
                "samples": f.samples,
                "negative_displacement_clipped_to_zero": f.clipped_negative,
                "above_full_stroke": f.above_stroke,
                "sign_changes_of_m": f.sign_changes,
                "displacement_noise_m": f.noise_m,
                "fit_floor_m": f.fit_floor_m,
                "rows_below_fit_floor_outside_zero_band": f.rows_below_floor,
                "nrmse_magnetization": f.nrmse_magnetization,
                "nrmse_displacement": f.nrmse_displacement,
            }))
            .collect::<Vec<_>>()),
    );
    d.insert(
        "dataset_entries_not_read".into(),
        json!(dataset
            .ignored
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()),
    );
    d.insert(
        "date".into(),
        json!(humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()),
    );
    d.insert("base_parameters".into(), json!(base_name));
    d.insert(
        actuator_params::Provenance::IDENTIFIED.into(),
        json!(identified_fields(fit_options)),
    );
    d.insert(
        "not_identified".into(),
        json!({
            "fields": actuator_params::Provenance::DYNAMIC_FIELDS,
            "values": {
                "eddy_resistance_ohm": base.actuator.eddy_resistance_ohm,
                "damping_ratio": base.actuator.damping_ratio,
                "resonance_hz": base.actuator.resonance_hz,
            },
            "reason": "copied from the base parameter file: identifying R_eddy, xi and f0 needs the \
                       dynamic model (4)-(5) (phase-lag scheme or direct waveform fit), not implemented \
                       in `maglab identify` yet. The other actuator constants are manufacturer data \
                       (paper Section 4) and are copied as well.",
        }),
    );
    d.insert(
        "method".into(),
        json!({
            "input": "H = c0 * current_a (static limit of (4))",
            "output": "M = +/- M_s sqrt(y / (l_m lambda_s)) (static model (6))",
            "branch_and_initial_state_per_file": choices,
            "zero_band_fraction_of_stroke": options.zero_band_fraction,
            "fit_floor": format!(
                "rows with u below max(zero band, min(sigma_u / sqrt(8 * {SQRT_NOISE_BIAS_MAX}), \
                 {FIT_FLOOR_MAX_FRACTION} * l_m lambda_s)) are left out: sigma_u (the noise of u after the lag correction) biases \
                 M = M_s sqrt(u/S) low by sigma_u^2 / (8 u^2) of itself"
            ),
            "regression": "M = sum_k w_k (2 f_k - 1), f_k = exact fraction of cell k in P+, \
                           w >= 0, clarabel QP",
            "smoothness": fit_options.smoothness,
            "ridge_toward_base": fit_options.ridge,
            "row_stride": fit_options.row_stride,
        }),
    );
    d.insert(
        "fit".into(),
        json!({
            "rows": result.rows,
            "selected_rows_left_out_by_stride": result.strided_out,
            "rms_residual_a_per_m": result.rms_residual,
            "output_range_a_per_m": result.output_scale,
            "solver": result.solver,
            "samples_outside_grid": result.outside.iter().map(|(l, n)| json!({"file": l, "samples": n})).collect::<Vec<_>>(),
            "sum_of_weights_a_per_m": result.weights.iter().sum::<f64>(),
            "saturation_magnetization_a_per_m": base.actuator.saturation_magnetization_a_per_m,
        }),
    );
    d.insert(
        "unexcited_cells".into(),
        json!({
            "count": result.unexcited.len(),
            "treatment": fit_options.unexcited.name(),
            "meaning": "cells whose P+ fraction never changed over the data: the data do not \
                        determine their masses; `keep-prior` = base file's mass kept, `zero` = set \
                        to 0, `regularized` = set by the smoothness/ridge terms only",
            "cells_i_j": result.unexcited.iter().map(|&k| { let (i, j) = cell_of_index(k); json!([i, j]) }).collect::<Vec<_>>(),
        }),
    );
    Provenance {
        source: "maglab identify (Preisach masses identified; R_eddy, xi, f0 copied from base)"
            .into(),
        details: d,
    }
}
