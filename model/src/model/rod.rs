//! The mechanical stage's rod and load (module docs of [`super`], stage 2): RK4 on eq. (5) with
//! the load's masses, ΔE and the thermal drive, for one parameter set or several side by side.

use super::{ElectroRun, LinearStep, Mech, MechTrack, Nominal};
use std::f64::consts::PI;

/// The rod and load integrated over the first `n_samples` samples of `run` (the part of
/// [`super::run_mech`] before the sensor; it does not depend on the sensor or the skew).
pub fn track_mech(
    nominal: &Nominal,
    mech: &Mech,
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: (f64, f64),
) -> MechTrack {
    let mut tracks = track_mech_lanes(nominal, &[*mech], run, n_samples, step_s, &[theta0]);
    tracks.pop().expect("one track per parameter set")
}

/// [`track_mech`] of several parameter sets on the same run, each with its starting temperature
/// (`theta0[i]` for `mechs[i]`), integrated side by side (see `mech_states`): the same tracks
/// as one at a time, in less time when the rod is nonlinear (ΔE). Panics unless there is one
/// start per set.
pub fn track_mech_lanes(
    nominal: &Nominal,
    mechs: &[Mech],
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: &[(f64, f64)],
) -> Vec<MechTrack> {
    assert_eq!(mechs.len(), theta0.len(), "one start temperature per set");
    // The load's states exist only when it is switched on (a compile-time size: the rod alone
    // keeps two states, one load mode four; the states of an absent load would stay at rest
    // and only cost arithmetic). Sets of different sizes run in groups of their size.
    let size = |m: &Mech| {
        if m.second_load.is_some() {
            6
        } else if m.load.is_some() {
            4
        } else {
            2
        }
    };
    let mut tracks: Vec<Option<MechTrack>> = vec![None; mechs.len()];
    for n in [2, 4, 6] {
        let group: Vec<usize> = (0..mechs.len()).filter(|&i| size(&mechs[i]) == n).collect();
        if group.is_empty() {
            continue;
        }
        let sets: Vec<&Mech> = group.iter().map(|&i| &mechs[i]).collect();
        let starts: Vec<(f64, f64)> = group.iter().map(|&i| theta0[i]).collect();
        let states = match n {
            6 => mech_states::<6>(nominal, &sets, run, n_samples, step_s, &starts),
            4 => mech_states::<4>(nominal, &sets, run, n_samples, step_s, &starts),
            _ => mech_states::<2>(nominal, &sets, run, n_samples, step_s, &starts),
        };
        for (&i, (pos_m, rate_m_per_s)) in group.iter().zip(states) {
            tracks[i] = Some(MechTrack {
                substeps: run.substeps,
                pos_m,
                rate_m_per_s,
            });
        }
    }
    tracks
        .into_iter()
        .map(|t| t.expect("every set is in one group"))
        .collect()
}

/// The rod and load integrated over every substep of `run`: the observed position and rate at
/// each substep point. State `[y1, v1]` (the rod) with `N = 2`, `[y1, v1, y2, v2]` (rod, first
/// load mass) with `N = 4`, and with `N = 6` the second load mass `[y3, v3]` hanging on the
/// first.
///
/// Several parameter sets on the same run (`mechs`, each with its starting temperature in
/// `theta0`) advance side by side, one substep point at a time; those with ΔE in groups of up
/// to four with the same `sub`, their RK4 stages interleaved ([`rk4_substep_lanes`]). Each is
/// the integration it would be alone, bit for bit, but one alone waits on each stage's result
/// (a chain of dependent multiplications), which four independent chains fill; eight no longer
/// fit the registers and are slower than four (BENCHMARKS.md, "Diagnosis model evaluation").
fn mech_states<const N: usize>(
    nominal: &Nominal,
    mechs: &[&Mech],
    run: &ElectroRun,
    n_samples: usize,
    step_s: f64,
    theta0: &[(f64, f64)],
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let delta = step_s / run.substeps as f64;
    let m0 = run.m_a_per_m[0];
    // A run may be longer than the samples asked for (a chained experiment is simulated whole).
    let total = run.m_a_per_m.len().min(1 + n_samples * run.substeps);
    let mut lanes: Vec<Lane<N>> = mechs
        .iter()
        .zip(theta0)
        .map(|(mech, &theta0)| Lane::at_rest(Rod::new(nominal, mech, delta), theta0, m0, total))
        .collect();
    // The nonlinear lanes (ΔE) in groups of up to four with the same `sub`; the linear ones
    // one by one (a matrix-vector product each).
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, lane) in lanes.iter().enumerate() {
        if lane.rod.linear.is_some() {
            continue;
        }
        match groups
            .iter_mut()
            .find(|g| g.len() < 4 && lanes[g[0]].rod.sub == lane.rod.sub)
        {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    for j in 1..total {
        for lane in lanes.iter_mut().filter(|l| l.rod.linear.is_some()) {
            lane.advance_linear(run, j);
        }
        for g in &groups {
            match g.len() {
                1 => advance_group::<N, 1>(&mut lanes, g, run, j),
                2 => advance_group::<N, 2>(&mut lanes, g, run, j),
                3 => advance_group::<N, 3>(&mut lanes, g, run, j),
                _ => advance_group::<N, 4>(&mut lanes, g, run, j),
            }
        }
    }
    lanes.into_iter().map(|l| (l.pos, l.rate)).collect()
}

/// One parameter set's rod (and load) on substeps of `δ`: the constants of its RK4 substep,
/// read once from a [`Mech`].
struct Rod<const N: usize> {
    /// Mechanical sub-substeps per substep, their length `δ/sub`, and `1/sub`.
    sub: usize,
    dm: f64,
    inv_sub: f64,
    /// `2 ζ ω0` and `ω0²`.
    damp: f64,
    om0_sq: f64,
    inv_stroke: f64,
    inv_ms2: f64,
    /// `l_m λ_s / M_s²`.
    k_u: f64,
    /// Each load mode as `(mass ratio, ω², 2 ζ ω)`.
    load: Option<(f64, f64, f64)>,
    second: Option<(f64, f64, f64)>,
    delta_e: Option<(f64, f64, f64, f64)>,
    /// `(coil decay, rod decay, gain loss, expansion · stroke)` per substep.
    thermal: Option<(f64, f64, f64, f64)>,
    /// Without ΔE, the substep as its matrix (see [`Rod::new`]).
    linear: Option<LinearStep<N>>,
}

impl<const N: usize> Rod<N> {
    fn new(nominal: &Nominal, mech: &Mech, delta: f64) -> Self {
        let om0 = 2.0 * PI * mech.resonance_hz;
        let damp = 2.0 * mech.damping_ratio * om0;
        let mode = |(r, f, z): (f64, f64, f64)| {
            let w = 2.0 * PI * f;
            (r, w * w, 2.0 * z * w)
        };
        let load = if N >= 4 { mech.load.map(mode) } else { None };
        let second = if N == 6 {
            mech.second_load.map(mode)
        } else {
            None
        };
        // Mechanical sub-substeps so that RK4 resolves the fastest mode, oscillatory or damped
        // (rate · δ_m ≤ 0.5).
        let mut rate_max = om0
            * (1.0
                + mech.delta_e.map_or(0.0, |(a, b, c, e)| {
                    a.max(0.0) + b.max(0.0) + c.max(0.0) + e.abs()
                }))
            .sqrt();
        rate_max = rate_max.max(damp);
        if let Some((r, w2, c2)) = load {
            rate_max = rate_max.max((w2 * (1.0 + r)).sqrt()).max(c2 * (1.0 + r));
            // With the second mass on the first: Gershgorin's bound on the chain's stiffness
            // and damping rows (per unit mass).
            if let Some((r3, w3, c3)) = second {
                rate_max = rate_max
                    .max((2.0 * (w2 + r3 * w3)).sqrt())
                    .max((2.0 * w3).sqrt())
                    .max(2.0 * (c2 + r3 * c3))
                    .max(2.0 * c3);
            }
        }
        let sub = ((rate_max * delta / 0.5).ceil() as usize).clamp(1, 10_000);
        let thermal = mech.thermal.map(|(tau, lag, g, e)| {
            (
                (-delta / tau).exp(),
                (-delta / lag).exp(),
                g,
                e * nominal.stroke_m,
            )
        });
        let mut rod = Rod {
            sub,
            dm: delta / sub as f64,
            inv_sub: 1.0 / sub as f64,
            damp,
            om0_sq: om0 * om0,
            inv_stroke: 1.0 / nominal.stroke_m.max(1e-12),
            inv_ms2: 1.0 / (nominal.saturation_a_per_m * nominal.saturation_a_per_m),
            k_u: nominal.displacement_per_m2_m,
            load,
            second,
            delta_e: mech.delta_e,
            thermal,
            linear: None,
        };
        // Without ΔE the rod and load are linear and time-invariant, so the RK4 substep is an
        // affine map of the state and the two end values of `u`: its matrix is read once by
        // stepping the unit vectors, and every substep is then one matrix-vector product — the
        // same integrator, about 2.5x cheaper (the mechanical stage was half of a diagnosis'
        // time).
        if rod.delta_e.is_none() {
            let mut phi = [[0.0; N]; N];
            for i in 0..N {
                let mut e = [0.0; N];
                e[i] = 1.0;
                let column = rod.rk4_substep(e, 0.0, 0.0, 0.0, 0.0);
                for (r, c) in column.iter().enumerate() {
                    phi[r][i] = *c;
                }
            }
            let from_prev = rod.rk4_substep([0.0; N], 1.0, 0.0, 0.0, 0.0);
            let from_next = rod.rk4_substep([0.0; N], 0.0, 1.0, 0.0, 0.0);
            rod.linear = Some(LinearStep {
                phi,
                g0: std::array::from_fn(|r| from_prev[r] + from_next[r]),
                g1: from_next,
            });
        }
        rod
    }

    /// The rod's drive `u` at magnetization `m` and rod temperature `φ`.
    fn u_of(&self, m: f64, phi: f64) -> f64 {
        match self.thermal {
            // The gain is the fraction of λ_s the warm rod keeps: it cannot fall below zero.
            Some((_, _, g, e)) => (1.0 - g * phi).max(0.0) * self.k_u * m * m + e * phi,
            None => self.k_u * m * m,
        }
    }

    /// ΔE: the stiffness depends on the magnetization and on the stress (the elastic strain
    /// (y − u)/stroke), so it is evaluated inside the mechanical step. Its magnetization part
    /// `1 + d₁ r + d₂ r² + d₃ r³` (r = m²/M_s²) depends on the input only: it is evaluated once
    /// per point of the substep (here), the stress part per RK4 stage ([`Rod::om2_of`]).
    /// (Reciprocals instead of divisions: the two divisions per stage were a fifth of a
    /// diagnosis' time on an out-of-library case.)
    fn stiffening(&self, m: f64) -> f64 {
        match self.delta_e {
            Some((d1, d2, d3, _)) => {
                let r = m * m * self.inv_ms2;
                1.0 + r * (d1 + r * (d2 + r * d3))
            }
            None => 1.0,
        }
    }

    fn om2_of(&self, stiffening: f64, strain: f64) -> f64 {
        match self.delta_e {
            Some((_, _, _, d_stress)) => self.om0_sq * (stiffening + d_stress * strain).max(0.05),
            None => self.om0_sq,
        }
    }

    /// The state's time derivative at `x`, with the rod's drive `u` and the magnetization's
    /// stiffening `st`.
    fn derivative(&self, x: &[f64; N], u: f64, st: f64) -> [f64; N] {
        let mut d = [0.0; N];
        let om2 = self.om2_of(st, (x[0] - u) * self.inv_stroke);
        d[0] = x[1];
        d[1] = -self.damp * x[1] - om2 * (x[0] - u);
        if let Some((r, w2, c2)) = self.load {
            let coupling = w2 * (x[0] - x[2]) + c2 * (x[1] - x[3]);
            d[1] -= r * coupling;
            d[2] = x[3];
            d[3] = coupling;
            if let Some((r3, w3, c3)) = self.second {
                let coupling3 = w3 * (x[2] - x[4]) + c3 * (x[3] - x[5]);
                d[3] -= r3 * coupling3;
                d[4] = x[5];
                d[5] = coupling3;
            }
        }
        d
    }

    /// One substep of RK4 (`sub` steps of `δ/sub`) from `x`, `u` and `M` linear over it.
    fn rk4_substep(&self, x: [f64; N], u_prev: f64, u_next: f64, m_a: f64, m_b: f64) -> [f64; N] {
        let [x] = rk4_substep_lanes(&[self], [x], [u_prev], [u_next], m_a, m_b);
        x
    }
}

/// [`Rod::rk4_substep`] of `L` rods with the same `sub` (and so the same `δ/sub`), stage by
/// stage across the rods: the arithmetic of each is that of one alone, but the `L` chains of
/// dependent stages run interleaved, where one alone waits on each stage's result.
fn rk4_substep_lanes<const N: usize, const L: usize>(
    rods: &[&Rod<N>; L],
    x: [[f64; N]; L],
    u_prev: [f64; L],
    u_next: [f64; L],
    m_a: f64,
    m_b: f64,
) -> [[f64; N]; L] {
    let mut x = x;
    let shifted = |x: &[f64; N], k: &[f64; N], h: f64| -> [f64; N] {
        std::array::from_fn(|i| x[i] + h * k[i])
    };
    let (sub, dm, inv_sub) = (rods[0].sub, rods[0].dm, rods[0].inv_sub);
    debug_assert!(rods.iter().all(|r| r.sub == sub));
    let hd = 0.5 * dm;
    let d6 = dm / 6.0;
    let point = |f: f64| -> [(f64, f64); L] {
        std::array::from_fn(|l| {
            (
                u_prev[l] + (u_next[l] - u_prev[l]) * f,
                rods[l].stiffening(m_a + (m_b - m_a) * f),
            )
        })
    };
    let mut start = point(0.0);
    for q in 0..sub {
        let half = point((q as f64 + 0.5) * inv_sub);
        let end = point((q as f64 + 1.0) * inv_sub);
        let k1: [[f64; N]; L] =
            std::array::from_fn(|l| rods[l].derivative(&x[l], start[l].0, start[l].1));
        let k2: [[f64; N]; L] = std::array::from_fn(|l| {
            rods[l].derivative(&shifted(&x[l], &k1[l], hd), half[l].0, half[l].1)
        });
        let k3: [[f64; N]; L] = std::array::from_fn(|l| {
            rods[l].derivative(&shifted(&x[l], &k2[l], hd), half[l].0, half[l].1)
        });
        let k4: [[f64; N]; L] = std::array::from_fn(|l| {
            rods[l].derivative(&shifted(&x[l], &k3[l], dm), end[l].0, end[l].1)
        });
        for l in 0..L {
            for i in 0..N {
                x[l][i] += d6 * (k1[l][i] + 2.0 * k2[l][i] + 2.0 * k3[l][i] + k4[l][i]);
            }
        }
        start = end;
    }
    x
}

/// One parameter set's integration in progress: its rod, state, temperatures, the drive at the
/// last point, and the observed motion so far.
struct Lane<const N: usize> {
    rod: Rod<N>,
    x: [f64; N],
    theta: f64,
    phi: f64,
    u_prev: f64,
    /// The observed mass's position index in `x` (the first load mass when there is a load:
    /// the sensor sits on it).
    observed: usize,
    pos: Vec<f64>,
    rate: Vec<f64>,
}

impl<const N: usize> Lane<N> {
    /// At rest at the drive's initial displacement: every mass at `u0`, no velocity.
    fn at_rest(rod: Rod<N>, theta0: (f64, f64), m0: f64, total: usize) -> Self {
        let (theta, phi) = if rod.thermal.is_some() {
            theta0
        } else {
            (0.0, 0.0)
        };
        let u0 = rod.u_of(m0, phi);
        let x: [f64; N] = std::array::from_fn(|i| if i % 2 == 0 { u0 } else { 0.0 });
        let observed = if rod.load.is_some() { 2 } else { 0 };
        let mut pos = Vec::with_capacity(total);
        let mut rate = Vec::with_capacity(total);
        pos.push(x[observed]);
        rate.push(x[observed + 1]);
        Lane {
            rod,
            x,
            theta,
            phi,
            u_prev: u0,
            observed,
            pos,
            rate,
        }
    }

    /// The coil and rod temperatures over substep `j − 1` of `run` (when the rod heats), and the
    /// drive at point `j`.
    fn heat(&mut self, run: &ElectroRun, j: usize) -> f64 {
        if let Some((decay, lag_decay, _, _)) = self.rod.thermal {
            let i2 = run.current_sq_a2[j - 1];
            let before = self.theta;
            self.theta = i2 + (self.theta - i2) * decay;
            self.phi =
                0.5 * (before + self.theta) + (self.phi - 0.5 * (before + self.theta)) * lag_decay;
        }
        self.rod.u_of(run.m_a_per_m[j], self.phi)
    }

    /// The state `x` at the next point, reached with the drive `u_next`.
    fn record(&mut self, x: [f64; N], u_next: f64) {
        self.x = x;
        self.u_prev = u_next;
        self.pos.push(x[self.observed]);
        self.rate.push(x[self.observed + 1]);
    }

    /// From substep point `j − 1` of `run` to point `j` with the linear map (no ΔE; a lane with
    /// ΔE is advanced by [`advance_group`]).
    fn advance_linear(&mut self, run: &ElectroRun, j: usize) {
        let u_next = self.heat(run, j);
        if let Some(map) = &self.rod.linear {
            let x = map.step(self.x, self.u_prev, u_next);
            self.record(x, u_next);
        }
    }
}

/// The lanes `group` (`L` of them, ΔE, the same `sub`) from substep point `j − 1` of `run` to
/// point `j`, their RK4 stages interleaved ([`rk4_substep_lanes`]).
fn advance_group<const N: usize, const L: usize>(
    lanes: &mut [Lane<N>],
    group: &[usize],
    run: &ElectroRun,
    j: usize,
) {
    let at: [usize; L] = std::array::from_fn(|l| group[l]);
    let u_next: [f64; L] = std::array::from_fn(|l| lanes[at[l]].heat(run, j));
    let u_prev: [f64; L] = std::array::from_fn(|l| lanes[at[l]].u_prev);
    let x: [[f64; N]; L] = std::array::from_fn(|l| lanes[at[l]].x);
    let rods: [&Rod<N>; L] = std::array::from_fn(|l| &lanes[at[l]].rod);
    let next = rk4_substep_lanes(
        &rods,
        x,
        u_prev,
        u_next,
        run.m_a_per_m[j - 1],
        run.m_a_per_m[j],
    );
    for l in 0..L {
        lanes[at[l]].record(next[l], u_next[l]);
    }
}
