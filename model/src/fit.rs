//! Fitting a candidate's parameters on training experiments: Levenberg-Marquardt (the
//! `levenberg-marquardt` crate, MINPACK's algorithm) on the displacement residual, with the
//! sensor offset solved in closed form (the residual's mean is removed: variable projection) and
//! the electromagnetic stage cached, so that the Jacobian columns of mechanical and sensor
//! parameters cost one mechanical run each (integrated side by side,
//! [`crate::model::track_mech_lanes`]: the same tracks, a quarter less time for a pair with ΔE),
//! and the mechanical stage's track cached too, so
//! that the columns of the channel skew and the sensor's parameters (which act on the track
//! afterwards, [`crate::model::observe`]) cost only the sensor's reading of it (the same
//! numbers, bit for bit).
//!
//! **Jacobian.** Forward differences of step `JACOBIAN_STEP` (10⁻³) in the unbounded coordinates. The
//! columns of the electromagnetic parameters (`R_eddy`, the eddy paths, the amplifier, the
//! reversible term) each need a new electromagnetic run; they take it from **one** run with the
//! setup's substeps ([`ModelSetup::single_run`]) instead of the Richardson pair of `S` and `2S`
//! (a third of the cost), both ends of the difference from single runs, so that the pair's
//! offset does not enter the slope. The residuals, and so the minimum the fit converges to, stay
//! the Richardson model's; only the direction Levenberg-Marquardt steers by is first order in
//! the step, so Levenberg-Marquardt stops a little short where the residual is at the level of
//! the model's own integration error: on a noise-free dataset without an effect
//! (`lab/tests/diagnose_noise_free.rs`) the amplifier candidate's training RMS ends at 1.95 nm
//! instead of 1.48 nm (of a 35 µm motion); with noise that difference is far below every
//! threshold, and the single-run columns cut a diagnosis by a fifth to a quarter.
//!
//! Starts: every start is evaluated once and the best (and the second when within 10 % of it)
//! refined. A candidate with effects is refined twice from each: all parameters at once, and in
//! two phases — the effect's own parameters first with the shared constants (`R_eddy`, `ξ`, `f0`,
//! skew) held at the start's, then everything — and the lower cost kept (single candidates from
//! their grid of starts; pairs and refits start from fitted values and are refined once). Freed at once, the
//! constants move first (their gradients are the strongest) to mimic the effect, and the fit can
//! stay in that valley with the constants at their range limits: on the bench plant's suites a
//! ΔE effect whose one-phase fit left a third of the gap leaves 4 % in two phases.
//!
//! Fitting uses at most [`FitSettings::max_fit_samples`] samples of each training experiment after
//! its settling time (the whole record is still simulated up to there); scoring uses the whole
//! record.

use crate::candidates::{self, Candidate, ParamSpec, Stage, COMMON_PARAMETER_COUNT};
use crate::effects::EffectName;
use crate::model::{
    chained_temperature, observe, run_electro, run_electro_single, run_mech, track_mech_lanes,
    Electro, ElectroDrive, ElectroRun, Mech, MechTrack, ModelStart, Nominal,
};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use magctl::preisach::PreisachMeasure;
use maglab_dataset::CurrentBetweenSamples;
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// One experiment as the model sees it.
#[derive(Debug, Clone)]
pub struct ExperimentData<'a> {
    /// Commanded current, A.
    pub current_a: &'a [f64],
    /// Measured displacement, m.
    pub measured_m: &'a [f64],
    /// First scored sample.
    pub settle: usize,
    /// How it starts.
    pub start: ModelStart,
    /// The currents of the experiments run before it without a reset (oldest first; empty unless
    /// it starts where the previous one ended): the coil's temperature carries over.
    pub heat_history: Vec<&'a [f64]>,
}

/// The model settings shared by every run.
#[derive(Debug, Clone, Copy)]
pub struct ModelSetup<'a> {
    /// Nominal constants.
    pub nominal: &'a Nominal,
    /// The Preisach measure.
    pub measure: &'a PreisachMeasure,
    /// Sampling step, s.
    pub step_s: f64,
    /// The current between samples.
    pub interpolation: CurrentBetweenSamples,
    /// Electromagnetic substeps per sample.
    pub substeps: usize,
    /// One electromagnetic run with `substeps` instead of the Richardson pair
    /// ([`crate::model::run_electro_single`]): set only inside the fit, for the Jacobian's
    /// electromagnetic columns (module docs); `false` for every residual and prediction.
    pub single_run: bool,
}

impl ModelSetup<'_> {
    /// Stage A of one experiment over its first `len` samples, after `previous` (the memory the
    /// previous experiment of a chain left, for a chained start).
    pub fn electro(
        &self,
        e: &Electro,
        x: &ExperimentData<'_>,
        len: usize,
        previous: Option<&crate::model::Memory>,
    ) -> ElectroRun {
        let run = if self.single_run {
            run_electro_single
        } else {
            run_electro
        };
        let drive = ElectroDrive {
            currents_a: &x.current_a[..len],
            start: &x.start,
            previous,
        };
        run(self, e, drive)
    }

    /// Stage A of the experiments `which` of `data` (their first `lens[i]` samples). When an
    /// experiment starts where the previous one ended, its chain (back to the first record that
    /// does not continue another: a reset, or a start a lead-in record left,
    /// [`ModelStart::After`]) is simulated in order with the same parameters, each experiment
    /// whole (its end is the next one's start); otherwise the experiments run in parallel.
    pub fn electro_runs(
        &self,
        e: &Electro,
        data: &[ExperimentData<'_>],
        which: &[usize],
        lens: &[usize],
    ) -> Vec<ElectroRun> {
        let chained = data.iter().any(|x| x.start.is_previous());
        if !chained {
            return which
                .par_iter()
                .zip(lens)
                .map(|(&k, &len)| self.electro(e, &data[k], len, None))
                .collect();
        }
        // Every record a wanted one continues, back to its chain's first.
        let mut needed = vec![false; data.len()];
        for &k in which {
            let mut j = k;
            needed[j] = true;
            while j > 0 && data[j].start.is_previous() {
                j -= 1;
                needed[j] = true;
            }
        }
        let mut runs: Vec<Option<ElectroRun>> = (0..data.len()).map(|_| None).collect();
        let mut previous: Option<crate::model::Memory> = None;
        for (k, x) in data.iter().enumerate().filter(|(k, _)| needed[*k]) {
            let run = self.electro(e, x, x.current_a.len(), previous.as_ref());
            previous = Some((*run.end_memory).clone());
            runs[k] = Some(run);
        }
        which
            .iter()
            .map(|&k| {
                runs[k]
                    .take()
                    .unwrap_or_else(|| self.electro(e, &data[k], data[k].current_a.len(), None))
            })
            .collect()
    }

    /// The model's displacement for experiments `which` of `data` over their first `lens[i]`
    /// samples (no offset).
    pub fn predict(
        &self,
        e: &Electro,
        m: &Mech,
        data: &[ExperimentData<'_>],
        which: &[usize],
        lens: &[usize],
    ) -> Vec<Vec<f64>> {
        let runs = self.electro_runs(e, data, which, lens);
        which
            .par_iter()
            .zip(runs.par_iter())
            .zip(lens.par_iter())
            .map(|((&k, run), &len)| {
                let x = &data[k];
                let theta0 = chained_temperature(m, &x.heat_history, self.step_s);
                run_mech(self.nominal, m, run, len, self.step_s, theta0)
            })
            .collect()
    }

    /// The same over whole records.
    pub fn predict_all(
        &self,
        e: &Electro,
        m: &Mech,
        data: &[ExperimentData<'_>],
        which: &[usize],
    ) -> Vec<Vec<f64>> {
        let lens: Vec<usize> = which.iter().map(|&k| data[k].current_a.len()).collect();
        self.predict(e, m, data, which, &lens)
    }
}

/// Fit settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitSettings {
    /// Samples per experiment used in fitting, after its settling time.
    pub max_fit_samples: usize,
    /// Levenberg-Marquardt patience (evaluations ≈ patience × (parameters + 1)).
    pub patience: usize,
    /// How far `R_eddy`, `ξ`, `f0` may move from the nominal values (factors; see
    /// [`candidates::REFIT_RANGE`]).
    pub refit_range: [f64; 3],
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            max_fit_samples: 3000,
            patience: 12,
            refit_range: candidates::REFIT_RANGE,
        }
    }
}

/// A fitted candidate.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The candidate.
    pub candidate: Candidate,
    /// Parameter specs.
    pub specs: Vec<ParamSpec>,
    /// Values, physical units.
    pub values: Vec<f64>,
    /// Training RMS residual (offset removed), m.
    pub training_rms_m: f64,
    /// Model evaluations spent.
    pub evaluations: u64,
}

impl Fitted {
    /// Its model parameters.
    pub fn model(&self) -> (Electro, Mech) {
        candidates::model_parameters(&self.candidate, &self.values)
    }

    /// The name of each parameter in the report: the shared constants as they are, an effect's
    /// own parameters as they are for a single effect and as `effect.name` when the candidate
    /// has several effects (two effects may share a parameter name, e.g. `natural_hz`) or when
    /// the name is a shared constant's (the load's `damping_ratio`): the report's map would
    /// otherwise keep one of the two.
    pub fn report_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.specs[..COMMON_PARAMETER_COUNT.min(self.specs.len())]
            .iter()
            .map(|s| s.name.to_string())
            .collect();
        let several = self.candidate.effects.len() > 1;
        let shared = &self.specs[..COMMON_PARAMETER_COUNT.min(self.specs.len())];
        let mut k = COMMON_PARAMETER_COUNT;
        for (i, &e) in self.candidate.effects.iter().enumerate() {
            let n = candidates::parameter_count_at(&self.candidate.effects, i);
            let owner = if candidates::is_repeat(&self.candidate.effects, i) {
                format!("{}.{}", e.name(), candidates::second_term_label(e))
            } else {
                e.name().to_string()
            };
            for s in self.specs.iter().skip(k).take(n) {
                names.push(if several || shared.iter().any(|c| c.name == s.name) {
                    format!("{owner}.{}", s.name)
                } else {
                    s.name.to_string()
                });
            }
            k += n;
        }
        names
    }

    /// The effect parameters pinned at a physical limit of their range
    /// ([`ParamSpec::pinned`]), named as in [`Fitted::report_names`].
    pub fn pinned(&self) -> Vec<String> {
        self.names_where(COMMON_PARAMETER_COUNT..self.specs.len(), ParamSpec::pinned)
    }

    /// The shared parameters (the refitted `R_eddy`, `ξ`, `f0` and the channel skew) that ended
    /// within 1 % of an end of their band ([`ParamSpec::at_range_end`]), named as in
    /// [`Fitted::report_names`].
    pub fn shared_at_range_end(&self) -> Vec<String> {
        self.names_where(0..COMMON_PARAMETER_COUNT, ParamSpec::at_range_end)
    }

    /// The report names of the parameters at `indices` whose coordinate satisfies `test`.
    fn names_where(
        &self,
        indices: std::ops::Range<usize>,
        test: impl Fn(&ParamSpec, f64) -> bool,
    ) -> Vec<String> {
        self.report_names()
            .into_iter()
            .zip(self.specs.iter().zip(&self.values))
            .enumerate()
            .filter(|(i, (_, (s, &v)))| indices.contains(i) && test(s, s.coordinate(v)))
            .map(|(_, (name, _))| name)
            .collect()
    }

    /// The same fit with effect `drop` switched off (every other value unchanged).
    pub fn without_effect(&self, drop: usize) -> Fitted {
        let mut effects = Vec::new();
        let mut specs = self.specs[..COMMON_PARAMETER_COUNT].to_vec();
        let mut values = self.values[..COMMON_PARAMETER_COUNT].to_vec();
        let mut k = COMMON_PARAMETER_COUNT;
        for (i, &e) in self.candidate.effects.iter().enumerate() {
            let n = candidates::parameter_count_at(&self.candidate.effects, i);
            if i != drop {
                effects.push(e);
                specs.extend_from_slice(&self.specs[k..k + n]);
                values.extend_from_slice(&self.values[k..k + n]);
            }
            k += n;
        }
        Fitted {
            candidate: Candidate { effects },
            specs,
            values,
            training_rms_m: self.training_rms_m,
            evaluations: 0,
        }
    }

    /// The same fit with every listing of `effect` switched off (every other value unchanged).
    pub fn without(&self, effect: EffectName) -> Fitted {
        let mut out = self.clone();
        while let Some(i) = out.candidate.effects.iter().rposition(|&e| e == effect) {
            out = out.without_effect(i);
        }
        out.evaluations = 0;
        out
    }

    /// The same fit with only the first `keep` effects (the others switched off, every other
    /// value unchanged): what the fit owes to the effects dropped.
    pub fn knocked_out(&self, keep: usize) -> Fitted {
        let candidate = Candidate {
            effects: self.candidate.effects[..keep.min(self.candidate.effects.len())].to_vec(),
        };
        let n = COMMON_PARAMETER_COUNT
            + (0..candidate.effects.len())
                .map(|i| candidates::parameter_count_at(&candidate.effects, i))
                .sum::<usize>();
        Fitted {
            specs: self.specs[..n].to_vec(),
            values: self.values[..n].to_vec(),
            candidate,
            training_rms_m: self.training_rms_m,
            evaluations: 0,
        }
    }
}

/// The last few results of a computation, by its parameters (shared by the problems of one fit).
struct Recent<K, V> {
    capacity: usize,
    entries: Mutex<Vec<(K, Arc<V>)>>,
}

impl<K: PartialEq, V> Recent<K, V> {
    fn new(capacity: usize) -> Self {
        Recent {
            capacity,
            entries: Mutex::new(Vec::new()),
        }
    }

    /// The value for `key`: kept, else computed by `make` and kept (the oldest dropped).
    fn get_or_make(&self, key: K, make: impl FnOnce() -> V) -> Arc<V> {
        let lock = || self.entries.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, v)) = lock().iter().find(|(k, _)| *k == key) {
            return v.clone();
        }
        let v = Arc::new(make());
        let mut entries = lock();
        if entries.len() >= self.capacity {
            entries.remove(0);
        }
        entries.push((key, v.clone()));
        v
    }
}

/// The electromagnetic runs of the training experiments, by their parameters.
type Cache = Recent<Electro, Vec<ElectroRun>>;
/// The mechanical tracks of the training experiments, by the electromagnetic parameters and
/// [`Mech::track_key`].
type TrackCache = Recent<(Electro, Mech), Vec<MechTrack>>;

/// The least-squares problem of one candidate on the training experiments.
struct Problem<'a> {
    setup: ModelSetup<'a>,
    data: &'a [ExperimentData<'a>],
    training: &'a [usize],
    lengths: Vec<usize>,
    candidate: &'a Candidate,
    specs: Vec<ParamSpec>,
    cache: Arc<Cache>,
    tracks: Arc<TrackCache>,
    evaluations: Arc<AtomicU64>,
    /// Coordinates held fixed (the first `head.len()` parameters); `z` holds the others.
    head: Vec<f64>,
    z: DVector<f64>,
    residuals: Option<DVector<f64>>,
}

impl<'a> Problem<'a> {
    /// The same problem at the same point with single electromagnetic runs
    /// ([`ModelSetup::single_run`]) and caches of its own (a single run must never be served to
    /// a residual), counting into the same evaluations.
    fn single_run_twin(&self) -> Problem<'a> {
        Problem {
            setup: ModelSetup {
                single_run: true,
                ..self.setup
            },
            data: self.data,
            training: self.training,
            lengths: self.lengths.clone(),
            candidate: self.candidate,
            specs: self.specs.clone(),
            cache: Arc::new(Recent::new(3)),
            tracks: Arc::new(Recent::new(2)),
            evaluations: self.evaluations.clone(),
            head: self.head.clone(),
            z: self.z.clone(),
            residuals: None,
        }
    }

    fn values(&self, z: &DVector<f64>) -> Vec<f64> {
        self.specs
            .iter()
            .zip(self.head.iter().chain(z.iter()))
            .map(|(s, &z)| s.value(z))
            .collect()
    }

    fn electro_runs(&self, e: &Electro) -> Arc<Vec<ElectroRun>> {
        self.cache.get_or_make(*e, || {
            self.setup
                .electro_runs(e, self.data, self.training, &self.lengths)
        })
    }

    /// The tracks of the training experiments for `e` and `m`.
    fn tracks(&self, e: &Electro, m: &Mech) -> Arc<Vec<MechTrack>> {
        self.tracks.get_or_make((*e, m.track_key()), || {
            let mut by_set = self.tracks_of(e, &[*m]);
            by_set.pop().expect("one set, one list of tracks")
        })
    }

    /// The tracks of the training experiments for `e` and each of `mechs` (by set), integrated
    /// side by side ([`track_mech_lanes`]), experiment by experiment in parallel.
    fn tracks_of(&self, e: &Electro, mechs: &[Mech]) -> Vec<Vec<MechTrack>> {
        let runs = self.electro_runs(e);
        let by_experiment: Vec<Vec<MechTrack>> = self
            .training
            .par_iter()
            .zip(runs.par_iter())
            .zip(self.lengths.par_iter())
            .map(|((&k, run), &len)| {
                let x = &self.data[k];
                let theta0: Vec<(f64, f64)> = mechs
                    .iter()
                    .map(|m| chained_temperature(m, &x.heat_history, self.setup.step_s))
                    .collect();
                track_mech_lanes(
                    self.setup.nominal,
                    mechs,
                    run,
                    len,
                    self.setup.step_s,
                    &theta0,
                )
            })
            .collect();
        let mut by_set: Vec<Vec<MechTrack>> = (0..mechs.len())
            .map(|_| Vec::with_capacity(by_experiment.len()))
            .collect();
        for tracks in by_experiment {
            for (set, track) in by_set.iter_mut().zip(tracks) {
                set.push(track);
            }
        }
        by_set
    }

    fn eval(&self, z: &DVector<f64>) -> Option<DVector<f64>> {
        self.evaluations.fetch_add(1, Ordering::Relaxed);
        let (e, m) = candidates::model_parameters(self.candidate, &self.values(z));
        let tracks = self.tracks(&e, &m);
        self.residuals_on(&m, &tracks)
    }

    /// [`Problem::eval`] at several points whose electromagnetic parameters are the same: their
    /// tracks are integrated side by side on the one electromagnetic run
    /// ([`track_mech_lanes`]), each the track it would be alone, and not cached (a Jacobian's
    /// columns are visited once).
    fn eval_lanes(&self, zs: &[DVector<f64>]) -> Option<Vec<DVector<f64>>> {
        let models: Vec<(Electro, Mech)> = zs
            .iter()
            .map(|z| candidates::model_parameters(self.candidate, &self.values(z)))
            .collect();
        let Some(&(e, _)) = models.first() else {
            return Some(Vec::new());
        };
        if models.iter().any(|(other, _)| *other != e) {
            return zs.iter().map(|z| self.eval(z)).collect();
        }
        self.evaluations
            .fetch_add(zs.len() as u64, Ordering::Relaxed);
        let mechs: Vec<Mech> = models.iter().map(|&(_, m)| m).collect();
        let by_set = self.tracks_of(&e, &mechs);
        mechs
            .iter()
            .zip(&by_set)
            .map(|(m, tracks)| self.residuals_on(m, tracks))
            .collect()
    }

    /// The residuals of the training experiments (their mean taken out) when the sensor and the
    /// skew of `m` read `tracks`.
    fn residuals_on(&self, m: &Mech, tracks: &[MechTrack]) -> Option<DVector<f64>> {
        let parts: Vec<Vec<f64>> = self
            .training
            .par_iter()
            .zip(tracks.par_iter())
            .zip(self.lengths.par_iter())
            .map(|((&k, track), &len)| {
                let x = &self.data[k];
                let y = observe(m, track, len, self.setup.step_s);
                (x.settle..len).map(|k| y[k] - x.measured_m[k]).collect()
            })
            .collect();
        let mut all: Vec<f64> = parts.into_iter().flatten().collect();
        if all.is_empty() {
            return None;
        }
        if !all.iter().all(|v| v.is_finite()) {
            // A trial point where the model is not finite: a residual far worse than any real
            // one, so Levenberg-Marquardt rejects the step and shrinks its trust region.
            return Some(DVector::from_element(all.len(), UNSTABLE_RESIDUAL_M));
        }
        let mean = all.iter().sum::<f64>() / all.len() as f64;
        for v in all.iter_mut() {
            *v -= mean;
        }
        Some(DVector::from_vec(all))
    }
}

/// Residual given to a trial point whose simulation is not finite, m.
const UNSTABLE_RESIDUAL_M: f64 = 1.0;

/// Forward-difference step in the unbounded coordinate.
const JACOBIAN_STEP: f64 = 1e-3;

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, z: &DVector<f64>) {
        self.z = z.clone();
        self.residuals = self.eval(z);
    }

    fn params(&self) -> DVector<f64> {
        self.z.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        self.residuals.clone()
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let base = self.residuals.as_ref()?;
        let n = self.z.len();
        let fixed = self.head.len();
        let mut jac = DMatrix::zeros(base.len(), n);
        let shifted = |j: usize| {
            let mut z = self.z.clone();
            z[j] += JACOBIAN_STEP;
            z
        };
        let electro = |j: usize| self.specs[fixed + j].stage == Stage::Electro;
        let (_, base_mech) = candidates::model_parameters(self.candidate, &self.values(&self.z));
        let moves_track = |j: usize| {
            let (_, m) = candidates::model_parameters(self.candidate, &self.values(&shifted(j)));
            m.track_key() != base_mech.track_key()
        };
        // The mechanical columns that move the track first, side by side on the base
        // electromagnetic run (`eval_lanes`: the same columns, in less time when the rod is
        // nonlinear); then those that leave the track as it is (the skew, the sensor), read off
        // the cached base track; the electromagnetic ones last.
        let lanes: Vec<usize> = (0..n).filter(|&j| !electro(j) && moves_track(j)).collect();
        let points: Vec<DVector<f64>> = lanes.iter().map(|&j| shifted(j)).collect();
        let mut from_lanes: Vec<Option<DVector<f64>>> = vec![None; n];
        for (&j, r) in lanes.iter().zip(self.eval_lanes(&points)?) {
            from_lanes[j] = Some(r);
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&j| electro(j));
        // The electromagnetic columns from single runs (module docs): a problem of its own, with
        // caches of its own, and its own base point, so that no Richardson offset enters a
        // difference.
        let mut single: Option<(Problem<'_>, DVector<f64>)> = None;
        for j in order {
            let z = shifted(j);
            let column = if electro(j) {
                if single.is_none() {
                    let problem = self.single_run_twin();
                    let base = problem.eval(&self.z)?;
                    single = Some((problem, base));
                }
                let (problem, single_base) = single.as_ref()?;
                let r = problem.eval(&z)?;
                if r.len() != single_base.len() {
                    return None;
                }
                (r - single_base) / JACOBIAN_STEP
            } else {
                let r = match from_lanes[j].take() {
                    Some(r) => r,
                    None => self.eval(&z)?,
                };
                if r.len() != base.len() {
                    return None;
                }
                (r - base) / JACOBIAN_STEP
            };
            jac.set_column(j, &column);
        }
        Some(jac)
    }
}

/// Fits `candidate` on the experiments `training` of `data` from the best of `starts`
/// (physical values, [`candidates::parameters`] order); `two_phase`: also refine with the shared
/// constants held first (module docs; the single candidates' fits, whose starts are a generic
/// grid — a pair or a refit starts from fitted values and skips it).
pub fn fit(
    setup: ModelSetup<'_>,
    data: &[ExperimentData<'_>],
    training: &[usize],
    candidate: &Candidate,
    starts: &[Vec<f64>],
    settings: &FitSettings,
    two_phase: bool,
) -> Fitted {
    let specs = candidates::parameters(candidate, setup.nominal, &settings.refit_range);
    let lengths: Vec<usize> = training
        .iter()
        .map(|&k| (data[k].settle + settings.max_fit_samples).min(data[k].current_a.len()))
        .collect();
    let origin = Problem {
        setup,
        data,
        training,
        lengths,
        candidate,
        specs,
        cache: Arc::new(Recent::new(3)),
        tracks: Arc::new(Recent::new(2)),
        evaluations: Arc::new(AtomicU64::new(0)),
        head: Vec::new(),
        z: DVector::zeros(0),
        residuals: None,
    };
    let scored = origin.score_starts(starts);
    // Refine the best start (and the second when within 10 % of it: a second basin as good).
    let refine = if scored.len() > 1 && scored[1].0 <= 1.1 * scored[0].0 {
        2
    } else {
        1
    };
    let two_phase = two_phase && !candidate.effects.is_empty();
    let results: Vec<(f64, DVector<f64>)> = scored
        .iter()
        .take(refine)
        .flat_map(|(_, z0)| origin.refine_from(z0, settings, two_phase))
        .collect();
    let best = origin
        .least_pinned_best(results)
        .unwrap_or_else(|| scored[0].clone());
    origin.fitted(&best)
}

impl<'a> Problem<'a> {
    /// The same problem at another point, sharing the caches and the count of evaluations:
    /// the coordinates `head` held fixed and `z` free.
    fn at(&self, head: Vec<f64>, z: DVector<f64>) -> Problem<'a> {
        Problem {
            setup: self.setup,
            data: self.data,
            training: self.training,
            lengths: self.lengths.clone(),
            candidate: self.candidate,
            specs: self.specs.clone(),
            cache: self.cache.clone(),
            tracks: self.tracks.clone(),
            evaluations: self.evaluations.clone(),
            head,
            z,
            residuals: None,
        }
    }

    /// Each start's cost and coordinates, the lowest cost first (a start the model cannot run
    /// costs infinity).
    fn score_starts(&self, starts: &[Vec<f64>]) -> Vec<(f64, DVector<f64>)> {
        let mut scored: Vec<(f64, DVector<f64>)> = starts
            .iter()
            .map(|v| {
                let z = DVector::from_iterator(
                    self.specs.len(),
                    self.specs
                        .iter()
                        .zip(v)
                        .map(|(s, &v)| s.start_coordinate(v)),
                );
                let cost = self
                    .at(Vec::new(), z.clone())
                    .eval(&z)
                    .map_or(f64::INFINITY, |r| r.norm_squared());
                (cost, z)
            })
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        scored
    }

    /// The optima reached from `z0`: everything free; with `two_phase` also the effect's own
    /// parameters first, with the shared constants held at the start's (the parameter file's or
    /// the refitted ones), then everything from there. Freed at once, the constants move first
    /// (their gradients are the strongest) to mimic the effect, and the fit stays in that valley.
    fn refine_from(
        &self,
        z0: &DVector<f64>,
        settings: &FitSettings,
        two_phase: bool,
    ) -> Vec<(f64, DVector<f64>)> {
        let mut results = vec![self.minimize(self.at(Vec::new(), z0.clone()), settings)];
        if two_phase {
            let head: Vec<f64> = z0.iter().take(COMMON_PARAMETER_COUNT).copied().collect();
            let tail = DVector::from_iterator(
                z0.len() - COMMON_PARAMETER_COUNT,
                z0.iter().skip(COMMON_PARAMETER_COUNT).copied(),
            );
            let (_, z1) = self.minimize(self.at(head, tail), settings);
            results.push(self.minimize(self.at(Vec::new(), z1), settings));
        }
        results
    }

    /// Levenberg-Marquardt from `p`'s point: the cost and the whole coordinates it ends at (the
    /// held ones first).
    fn minimize(&self, mut p: Problem<'a>, settings: &FitSettings) -> (f64, DVector<f64>) {
        let z = p.z.clone();
        p.set_params(&z);
        let (p, report) = LevenbergMarquardt::new()
            .with_patience(settings.patience)
            .with_ftol(1e-8)
            .with_xtol(1e-6)
            .with_stepbound(1.0)
            .minimize(p);
        if std::env::var_os("MAGLAB_DEBUG_FIT").is_some() {
            eprintln!(
                "fit {} ({} fixed): {:?} after {} evaluations, cost -> {:.3e}",
                self.candidate.name(),
                p.head.len(),
                report.termination,
                report.number_of_evaluations,
                p.residuals().map_or(f64::NAN, |r| r.norm_squared())
            );
        }
        let cost = p.residuals().map_or(f64::INFINITY, |r| r.norm_squared());
        let z: DVector<f64> = DVector::from_iterator(
            p.head.len() + p.z.len(),
            p.head.iter().copied().chain(p.z.iter().copied()),
        );
        (cost, z)
    }

    /// The lowest cost, unless it pins an effect parameter at a physical limit and a result that
    /// pins none comes within 10 % of it: the pinned optimum would disqualify the candidate
    /// (an implausible effect) for a gain in cost the data do not resolve.
    fn least_pinned_best(
        &self,
        mut results: Vec<(f64, DVector<f64>)>,
    ) -> Option<(f64, DVector<f64>)> {
        let pins = |z: &DVector<f64>| self.specs.iter().zip(z.iter()).any(|(s, &v)| s.pinned(v));
        results.sort_by(|a, b| a.0.total_cmp(&b.0));
        match (results.first(), results.iter().find(|r| !pins(&r.1))) {
            (Some(lowest), Some(free)) if pins(&lowest.1) && free.0 <= 1.1 * lowest.0 => {
                Some(free.clone())
            }
            (Some(lowest), _) => Some(lowest.clone()),
            (None, _) => None,
        }
    }

    /// The fitted candidate at `(cost, z)`: its values and training RMS per sample.
    fn fitted(self, best: &(f64, DVector<f64>)) -> Fitted {
        let n_res: usize = self
            .training
            .iter()
            .zip(&self.lengths)
            .map(|(&k, &len)| len.saturating_sub(self.data[k].settle))
            .sum();
        let values: Vec<f64> = self
            .specs
            .iter()
            .zip(best.1.iter())
            .map(|(s, &z)| s.value(z))
            .collect();
        Fitted {
            candidate: self.candidate.clone(),
            specs: self.specs,
            values,
            training_rms_m: (best.0 / n_res.max(1) as f64).sqrt(),
            evaluations: self.evaluations.load(Ordering::Relaxed),
        }
    }
}
