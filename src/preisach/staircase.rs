//! The memory of the Preisach operator: the staircase of dominant reversal points.
//!
//! # Algebra
//!
//! The state is the alternating sequence `s_0 = 0 < ... ` of reversal points (normalized input)
//! followed by the current input `u`: `s_0` is the lower edge of the range (the anchor, a
//! minimum), `s_1` a maximum, `s_2` a minimum, and so on; the wiping-out property keeps the maxima
//! decreasing and the minima increasing. The boundary of `P₊` is the staircase through these
//! points, and
//!
//! `μ(P₊) = Σ_{k odd} T(s_k, s_{k-1}) - Σ_{k even, k>0} T(s_{k-1}, s_k) ± T(·, u)`
//!
//! (each rise from a minimum switches on the triangle under the new maximum, each fall switches
//! off the triangle right of the new minimum). Every vertex stores the running sum up to itself,
//! so the output is one stored value plus one Everett evaluation for the moving segment, and a
//! wipe-out is a pop: an update costs O(1 + corners wiped out), never O(325).
//!
//! The direction of the moving segment follows from the parity of the last vertex: rising after a
//! minimum (even index), falling after a maximum (odd index). Negative saturation is `[0]` with
//! `u = 0`; positive saturation is `[0]` with `u = 25`.
//!
//! # Capacity and merging
//!
//! The staircase lives in a fixed `heapless::Vec` of `N` vertices ([`DEFAULT_CAPACITY`] = 64,
//! 512 bytes). Each stored pair is a nested minor loop still "remembered"; a 25-level grid with a
//! smooth drive rarely needs more than a dozen (the Van der Pol trajectory of the controller
//! needs fewer than 8, the AC-demagnetized state 27). 64 leaves room for noisy, slowly decaying
//! oscillations while keeping the worst-case merge error small (below).
//!
//! When a new reversal would overflow the buffer, the pair `(s_j, s_{j+1})` whose removal changes
//! the output least *by area* is merged away (the smallest loop in the Preisach plane). Removing
//! the pair between neighbours `s_{j-1}` and `s_{j+2}` removes exactly the rectangle
//! `{β between s_{j-1} and s_{j+1}} × {α between s_j and s_{j+2}}` from `P₊` (or adds it), so the
//! output changes by exactly `2 μ(rectangle)`, which is computed and accumulated in
//! [`PreisachState::merge_error_a_per_m`]. Worst case: with `N` vertices the `N - 2` candidate
//! rectangles have side sums adding up to at most `4 L` (the minima and the maxima each span at
//! most the range `L` = [`LEVELS`]), so the smallest has area at most `(2 L / (N - 2))²` and
//!
//! `|ΔM_merge| <= 2 ρ_max (2 L / (N - 2))²`
//!
//! with `ρ_max` the largest cell density ([`super::PreisachMeasure::max_density_a_per_m`]);
//! [`super::PreisachMeasure::merge_error_bound_a_per_m`] evaluates it. For N = 64 the area factor
//! is 0.65 cell. Merge errors do not compound: each is a frozen rectangle until later input wipes
//! it out, so the deviation from an unbounded memory is at most the sum of the merge errors.
//!
//! Cost of a merge: one scan over the `N - 2` candidates (a multiply and a compare each) plus four
//! Everett evaluations; it only runs on overflow.
//!
//! # Resolution (opt-in)
//!
//! A periodic drive whose extremes differ from cycle to cycle by a hair (a sampled trajectory, a
//! learning controller adjusting its correction) leaves one nested pair per cycle, each a loop of
//! almost no area, until a slightly larger excursion wipes them all out in one update — a burst
//! of work in a control interrupt for no output worth the name. With
//! [`PreisachState::set_resolution`] a new reversal whose pair with the previous one encloses a
//! corner rectangle (same measure as above: `|s_m − s_{m−2}| · |x − s_{m−1}|`) smaller than the
//! resolution, in cells², merges that pair at once, with its exact output change accounted in
//! [`PreisachState::merge_error_a_per_m`] as every merge: `|ΔM| <= 2 ρ_max · resolution` per merge.
//! The default resolution is 0 (exact memory); the control loop sets one for its own memory.

use super::everett::{PreisachMeasure, Quadratic};
use super::grid::LEVELS;
use heapless::Vec;

/// Number of reversal inputs in [`DEMAGNETIZATION_HISTORY`].
pub const DEMAGNETIZATION_STEPS: usize = 2 * (LEVELS / 2) + 3;

/// The AC-demagnetization input history (normalized inputs, applied in order from negative
/// saturation) that defines the demagnetized state, the discrete counterpart of the ideal state
/// `P₊ = {α + β < L}` (the line `α = -β` about the middle of the range).
///
/// * Reversals stepping inward one grid interval at a time: maxima `L - ½ - k` and minima `k + 1`,
///   `k = 0 .. ⌊L/2⌋ - 1`. Every horizontal and vertical step of the resulting staircase has its
///   midpoint on the line `α + β = L`, so around each corner the staircase deviates from the line
///   by two triangles of equal area and opposite sign lying in the same cell: with a density
///   uniform per cell they cancel exactly.
/// * The middle diagonal cell `c = ⌊L/2⌋` (the line cuts it into halves) is finished with three
///   more inputs: up to `c + 1`, down to `c + ¼`, up to `c + ½ = L/2`. In the cell's own
///   coordinates that switches on `{β' < ¼} ∪ {¼ <= β' <= α' <= ½}`, area `¼ - 1/32 + 1/32 = ¼`:
///   exactly half of the half-square, as the ideal state has. Only cell masses matter for a
///   uniform density, so the output equals the ideal demagnetized output exactly (0 for a
///   measure symmetric about the middle of the range).
///
/// The reference simulator and the identification tests replay this same history.
pub const DEMAGNETIZATION_HISTORY: [f32; DEMAGNETIZATION_STEPS] = demagnetization_history();

const fn demagnetization_history() -> [f32; DEMAGNETIZATION_STEPS] {
    const {
        assert!(
            LEVELS % 2 == 1,
            "the demagnetization history is written for an odd level count"
        )
    };
    let mut out = [0.0f32; DEMAGNETIZATION_STEPS];
    let mut k = 0;
    while k < LEVELS / 2 {
        out[2 * k] = LEVELS as f32 - 0.5 - k as f32;
        out[2 * k + 1] = (k + 1) as f32;
        k += 1;
    }
    let c = (LEVELS / 2) as f32;
    out[2 * (LEVELS / 2)] = c + 1.0;
    out[2 * (LEVELS / 2) + 1] = c + 0.25;
    out[2 * (LEVELS / 2) + 2] = c + 0.5;
    out
}

/// Default staircase capacity (vertices, including the anchor). See the module docs.
pub const DEFAULT_CAPACITY: usize = 64;

/// A vertex of the staircase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Vertex {
    /// Normalized input of the reversal point.
    pub x: f32,
    /// `μ(P₊)` of the staircase from the anchor up to this vertex, A/m.
    pub cum: f32,
}

/// The piece of the input path the last solve ended on, remembered so that the next solve, which
/// usually starts on the same piece, need not rebuild it (`solve.rs`). It is a memo, not memory:
/// the piece's quadratic and end are a function of the direction, the grid cell, the last vertex
/// (input and running sum) and the bound (the vertex before it), and the memo is used only when
/// all of those equal, bit for bit, the ones it was built from — so whatever it holds, a solve gives
/// bit for bit what it gives without it. (The measure is not part of the key: a state belongs to
/// the measure that built it, whose running sums its vertices already store.) States compare
/// equal whatever their memos hold.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PieceMemo {
    /// Grid cell of the piece plus [`PieceMemo::FALLING`] for a falling piece; [`PieceMemo::NONE`]
    /// when empty.
    pub tag: u32,
    /// The last vertex the piece was built from: input, running sum.
    pub base_x: f32,
    pub base_cum: f32,
    /// The vertex before it (the cap of a rising piece, the floor of a falling one).
    pub bound: f32,
    /// `T` along the piece (see `everett.rs`).
    pub quad: Quadratic,
    /// The end of the piece and `μ(P₊)` there.
    pub end_x: f32,
    pub end_plus_mass: f32,
}

impl PieceMemo {
    pub const NONE: u32 = u32::MAX;
    pub const FALLING: u32 = 1 << 8;
    const EMPTY: PieceMemo = PieceMemo {
        tag: Self::NONE,
        base_x: 0.0,
        base_cum: 0.0,
        bound: 0.0,
        quad: Quadratic {
            q0: 0.0,
            q1: 0.0,
            q2: 0.0,
        },
        end_x: 0.0,
        end_plus_mass: 0.0,
    };

    /// The remembered piece if it was built from exactly these inputs.
    #[inline(always)]
    pub fn lookup(&self, tag: u32, base: Vertex, bound: f32) -> Option<(Quadratic, f32, f32)> {
        // Bit patterns, OR-ed: one test instead of four floating-point compares (a -0 against
        // a +0 just misses).
        let differs = (self.tag ^ tag)
            | (self.base_x.to_bits() ^ base.x.to_bits())
            | (self.base_cum.to_bits() ^ base.cum.to_bits())
            | (self.bound.to_bits() ^ bound.to_bits());
        if differs == 0 {
            #[cfg(test)]
            PIECE_MEMO_HITS.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
            Some((self.quad, self.end_x, self.end_plus_mass))
        } else {
            None
        }
    }
}

/// How often a memo was used (tests only: shows that the memo test exercises it).
#[cfg(test)]
pub(crate) static PIECE_MEMO_HITS: core::sync::atomic::AtomicU32 =
    core::sync::atomic::AtomicU32::new(0);

impl PartialEq for PieceMemo {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// A rejected input: the state is left unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputError {
    /// The input was NaN or infinite.
    NonFinite,
}

/// The memory (state) of one Preisach operator: the staircase, the current input and the
/// merge bookkeeping. Pair it with the [`PreisachMeasure`] that holds the coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct PreisachState<const N: usize = DEFAULT_CAPACITY> {
    pub(crate) vertices: Vec<Vertex, N>,
    /// Current normalized input.
    pub(crate) x: f32,
    /// `μ(P₊)` at the current input, A/m.
    pub(crate) plus_mass: f32,
    merges: u32,
    merge_error_a_per_m: f32,
    /// Corner-rectangle area below which a new reversal pair is merged at once, cells² (0: exact).
    resolution_cells2: f32,
    /// The last solve's piece (a memo; see [`PieceMemo`]).
    pub(crate) piece: PieceMemo,
}

impl<const N: usize> PreisachState<N> {
    /// Sets the resolution (module docs, "Resolution"): a new reversal pair enclosing a corner
    /// rectangle smaller than `cells2` (in grid cells², ≥ 0; NaN or negative means 0) is merged
    /// at once.
    pub fn set_resolution(&mut self, cells2: f32) {
        self.resolution_cells2 = if cells2 > 0.0 { cells2 } else { 0.0 };
    }

    /// The resolution, cells².
    pub fn resolution_cells2(&self) -> f32 {
        self.resolution_cells2
    }

    const CAPACITY_OK: () = assert!(N >= 4, "the staircase needs room for at least 4 vertices");

    fn anchored(x: f32) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CAPACITY_OK;
        let mut vertices = Vec::new();
        let _ = vertices.push(Vertex { x: 0.0, cum: 0.0 });
        PreisachState {
            vertices,
            x,
            plus_mass: 0.0,
            merges: 0,
            merge_error_a_per_m: 0.0,
            resolution_cells2: 0.0,
            piece: PieceMemo::EMPTY,
        }
    }

    /// Number of stored vertices (anchor included).
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// Always false: the anchor is always there.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// The capacity `N`.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Reversal points as normalized inputs in `[0, 25]` (anchor first), for tests and plots.
    pub fn reversal_points_normalized(&self) -> impl Iterator<Item = f32> + '_ {
        self.vertices.iter().map(|v| v.x)
    }

    /// Current normalized input `x ∈ [0, 25]`.
    pub fn input_normalized(&self) -> f32 {
        self.x
    }

    /// How many times a pair was merged away: the buffer was full, or the pair enclosed less than
    /// the resolution ([`PreisachState::set_resolution`]).
    pub fn merges(&self) -> u32 {
        self.merges
    }

    /// Sum of the exact output changes caused by merges so far, A/m: a bound on how far the output
    /// is from that of an operator with unbounded memory.
    pub fn merge_error_a_per_m(&self) -> f32 {
        self.merge_error_a_per_m
    }

    #[inline]
    fn last(&self) -> Vertex {
        match self.vertices.last() {
            Some(v) => *v,
            None => Vertex { x: 0.0, cum: 0.0 },
        }
    }

    #[inline]
    pub(crate) fn last_index(&self) -> usize {
        self.vertices.len().saturating_sub(1)
    }

    /// Vertex `k`'s input (0 when out of range: never happens for the indices used).
    #[inline]
    pub(crate) fn vertex_x(&self, k: usize) -> f32 {
        self.vertices.get(k).map_or(0.0, |v| v.x)
    }

    /// Is the moving segment rising (last vertex a minimum)?
    #[inline]
    pub(crate) fn rising(&self) -> bool {
        // Last index even ⇔ length odd (the anchor is never removed, so the length is ≥ 1).
        self.vertices.len() % 2 == 1
    }
}

impl PreisachMeasure {
    /// A state at negative saturation (every hysteron at -1, input at `h_min`).
    pub fn negative_saturation<const N: usize>(&self) -> PreisachState<N> {
        PreisachState::anchored(0.0)
    }

    /// A state at positive saturation (every hysteron at +1, input at `h_max`).
    pub fn positive_saturation<const N: usize>(&self) -> PreisachState<N> {
        let mut state = PreisachState::anchored(LEVELS as f32);
        state.plus_mass = self.everett(LEVELS as f32, 0.0);
        state
    }

    /// The demagnetized state: the staircase along `α = -β` left by an AC demagnetization, with
    /// the input at the middle of the range. It is the state [`DEMAGNETIZATION_HISTORY`] leads to
    /// from negative saturation; see there why it equals the ideal state `P₊ = {α + β < L}`
    /// exactly for a density uniform per cell.
    pub fn demagnetized<const N: usize>(&self) -> PreisachState<N> {
        let mut state = self.negative_saturation::<N>();
        for &x in DEMAGNETIZATION_HISTORY.iter() {
            self.move_to(&mut state, x);
        }
        state
    }

    /// The state an AC demagnetization about the field `h_a_per_m` leaves: the staircase along
    /// `α + β = 2c` (`c = x(h)`, the normalized field) where that line crosses the grid, the input
    /// at `c`.
    ///
    /// * `c` on a grid line (an integer): the line runs through grid points, so it cuts every cell
    ///   it crosses corner to corner into two equal halves. The history "up to `2c − ½ − k`, down
    ///   to `k + 1`", `k = 0 … c − 1` (maxima above the range clamped to its top) puts one step
    ///   at the middle height of each such cell: exactly half of it switched on, as in the ideal
    ///   state, and every cell wholly below the line on. Exact.
    /// * `c` in the middle of an interval: [`DEMAGNETIZATION_HISTORY`] moved by `c − L/2`, an
    ///   integer, so its exactness argument holds cell for cell (inputs clamped to the grid).
    ///   About the middle of the range it is [`PreisachMeasure::demagnetized`].
    /// * elsewhere the same moved history: each step's two corner triangles (area 1/8 each,
    ///   opposite signs) may fall into different cells, so each of the `⌊L/2⌋ + 2` steps moves
    ///   `μ(P₊)` by at most `ρ_max / 8`: the output is within `(⌊L/2⌋ + 2) ρ_max / 4` of the ideal
    ///   state (`ρ_max`: [`PreisachMeasure::max_density_a_per_m`]; tested in `host-tests`).
    ///
    /// On a grid built around the reach of a coil that cannot saturate the rod, the outer
    /// intervals collapse everything beyond the reach; this state is then the convention for the
    /// one-way bands there that the identified offset `M_off` is measured against. A non-finite
    /// field gives the state about the middle.
    pub fn demagnetized_at<const N: usize>(&self, h_a_per_m: f32) -> PreisachState<N> {
        let middle = 0.5 * LEVELS as f32;
        let c = if h_a_per_m.is_finite() {
            self.normalize(h_a_per_m)
        } else {
            middle
        };
        // Within this of a line or a mid-interval the construction is taken as that case (an f32
        // normalization of a field meant to lie on a line is off by a few ulps).
        const SNAP: f32 = 1e-4;
        let line = libm::roundf(c);
        let mut state = self.negative_saturation::<N>();
        if libm::fabsf(c - line) <= SNAP {
            let lines = line as usize;
            for k in 0..lines {
                let max = 2.0 * line - 0.5 - k as f32;
                self.move_to(&mut state, max.min(LEVELS as f32));
                self.move_to(&mut state, (k + 1) as f32);
            }
            return state;
        }
        let mid = libm::floorf(c) + 0.5;
        let shift = if libm::fabsf(c - mid) <= SNAP {
            mid - middle
        } else {
            c - middle
        };
        if shift == 0.0 {
            return self.demagnetized();
        }
        for &x in DEMAGNETIZATION_HISTORY.iter() {
            self.move_to(&mut state, (x + shift).clamp(0.0, LEVELS as f32));
        }
        state
    }

    /// The state a sweep of the reach `[low, high]` (A/m) leaves: from negative saturation up to
    /// `high`, then down to `low` (the start-up conditioning of a rod the coil cannot saturate,
    /// `inverse::conditioning`). Every cell with `α <= high` has been switched up and every cell
    /// with `β >= low` down, so the state depends on the history before only through the cells
    /// with `α > high` and `β < low`, taken as down. Non-finite fields leave negative saturation.
    pub fn conditioned<const N: usize>(
        &self,
        low_a_per_m: f32,
        high_a_per_m: f32,
    ) -> PreisachState<N> {
        let mut state = self.negative_saturation::<N>();
        if low_a_per_m.is_finite() && high_a_per_m.is_finite() {
            self.move_to(&mut state, self.normalize(high_a_per_m));
            self.move_to(&mut state, self.normalize(low_a_per_m));
        }
        state
    }

    /// Sets the input to `h_a_per_m` (A/m) and returns the output `M` (A/m). Inputs beyond the
    /// grid saturate the memory. A NaN or infinite input is rejected and the state is unchanged.
    ///
    /// Cost: O(1 + reversal points wiped out); a merge scan of O(N) only when a new reversal finds
    /// the buffer full.
    pub fn apply<const N: usize>(
        &self,
        state: &mut PreisachState<N>,
        h_a_per_m: f32,
    ) -> Result<f32, InputError> {
        if !h_a_per_m.is_finite() {
            return Err(InputError::NonFinite);
        }
        self.move_to(state, self.normalize(h_a_per_m));
        Ok(self.output_a_per_m(state))
    }

    /// Current output `M = 2 μ(P₊) - Σ w + R(x)`, A/m (`R` the reversible part, 0 without one).
    #[inline]
    pub fn output_a_per_m<const N: usize>(&self, state: &PreisachState<N>) -> f32 {
        let hysteretic = 2.0 * state.plus_mass - self.output_bias_a_per_m;
        if self.has_reversible {
            hysteretic + self.reversible_at(state.x)
        } else {
            hysteretic
        }
    }

    /// Current input of the memory, A/m (clamped to the grid range).
    pub fn input_a_per_m<const N: usize>(&self, state: &PreisachState<N>) -> f32 {
        self.denormalize(state.x)
    }

    /// The worst-case output change of one merge for capacity `N`: `2 ρ_max (2 L / (N - 2))²`,
    /// A/m (see the staircase docs).
    pub fn merge_error_bound_a_per_m(&self, capacity: usize) -> f32 {
        let side = 2.0 * LEVELS as f32 / (capacity.max(3) - 2) as f32;
        2.0 * self.max_density_a_per_m * side * side
    }

    /// `μ(P₊)` contribution of the segment from vertex value `from` to `to` as the parity says:
    /// `+T(to, from)` when rising, `-T(from, to)` when falling.
    #[inline]
    pub(crate) fn segment_term(&self, from: f32, to: f32, rising: bool) -> f32 {
        if rising {
            self.everett(to, from)
        } else {
            -self.everett(from, to)
        }
    }

    /// Moves the memory to normalized input `x ∈ [0, LEVELS]` (assumed finite and clamped).
    pub(crate) fn move_to<const N: usize>(&self, state: &mut PreisachState<N>, x: f32) {
        if x == state.x {
            return;
        }
        let rising = state.rising();
        if rising != (x > state.x) {
            self.reverse(state);
        }
        self.wipe_out(state, x);
        state.x = x;
        self.update_plus_mass(state);
    }

    /// Recomputes `μ(P₊)` at the current input from the last vertex.
    #[inline]
    pub(crate) fn update_plus_mass<const N: usize>(&self, state: &mut PreisachState<N>) {
        let last = state.last();
        state.plus_mass = last.cum + self.segment_term(last.x, state.x, state.rising());
    }

    /// Pops the reversal points the new segment end `x` passes (wiping-out property).
    /// Each iteration pops at least one vertex, so the loop runs at most `N` times.
    pub(crate) fn wipe_out<const N: usize>(&self, state: &mut PreisachState<N>, x: f32) {
        loop {
            let m = state.last_index();
            if m % 2 == 0 {
                // Rising from minimum s_m; s_{m-1} is the dominating maximum.
                if m >= 2 && x >= state.vertex_x(m - 1) {
                    state.vertices.truncate(m - 1);
                    continue;
                }
            } else if m >= 3 && x <= state.vertex_x(m - 1) {
                // Falling from maximum s_m past the dominating minimum s_{m-1}.
                state.vertices.truncate(m - 1);
                continue;
            } else if m == 1 && x <= 0.0 {
                // Falling to the bottom of the range: negative saturation.
                state.vertices.truncate(1);
                continue;
            }
            break;
        }
    }

    /// The input reverses at the current point: it becomes a reversal point.
    pub(crate) fn reverse<const N: usize>(&self, state: &mut PreisachState<N>) {
        let m = state.last_index();
        if m >= 1 && state.vertex_x(m) == state.x {
            // Reversing straight back at the last reversal point: that reversal never happened.
            state.vertices.truncate(m);
            return;
        }
        if m >= 2 && state.resolution_cells2 > 0.0 {
            // The pair (s_{m-1}, s_m) against its neighbours s_{m-2} and the new point x.
            let area = ((state.vertex_x(m) - state.vertex_x(m - 2))
                * (state.x - state.vertex_x(m - 1)))
            .abs();
            if area < state.resolution_cells2 {
                self.merge_pair(state, m - 1);
            }
        }
        if state.vertices.is_full() {
            self.merge_smallest(state);
        }
        let _ = state.vertices.push(Vertex {
            x: state.x,
            cum: state.plus_mass,
        });
    }

    /// Removes the pair of reversal points whose corner rectangle is smallest (see module docs),
    /// accounting the exact output change.
    fn merge_smallest<const N: usize>(&self, state: &mut PreisachState<N>) {
        let m = state.last_index();
        if m < 2 {
            return;
        }
        // Candidates j = 1 ..= m-1 with area |x_{j+1} - x_{j-1}| · |x_{j+2} - x_j|; the right
        // neighbour of the last one (x_{m+1}) is the current input, which is about to become a
        // reversal point. With d_k = x_{k+2} - x_k the area is |d_{j-1} d_j|: one subtraction,
        // one multiply per candidate, over windows of three stored inputs (no index checks),
        // then the last candidate.
        let mut best_j = 1;
        let mut best_area = f32::INFINITY;
        let xs = state.vertices.as_slice();
        let mut previous_d = f32::NAN;
        for (k, w) in (0..).zip(xs.windows(3)) {
            let d = w[2].x - w[0].x;
            // Candidate j = k; k = 0 has none (a NaN area never compares less).
            let area = (previous_d * d).abs();
            if area < best_area {
                best_area = area;
                best_j = k;
            }
            previous_d = d;
        }
        if let [.., b, _] = xs {
            if (previous_d * (state.x - b.x)).abs() < best_area {
                best_j = m - 1;
            }
        }
        self.merge_pair(state, best_j);
    }

    /// Removes the reversal points `j` and `j + 1` (`1 <= j`, `j + 1 < len`), accounting the
    /// exact output change.
    fn merge_pair<const N: usize>(&self, state: &mut PreisachState<N>, j: usize) {
        if j == 0 || j + 1 >= state.vertices.len() {
            return;
        }
        let old_plus_mass = state.plus_mass;
        // Remove vertices j and j+1: shift j+2.. down by two (memmove).
        let len = state.vertices.len();
        // (Element by element through `get`: no panic path for the no-panic proof.)
        for k in j..len.saturating_sub(2) {
            if let Some(v) = state.vertices.get(k + 2).copied() {
                if let Some(slot) = state.vertices.get_mut(k) {
                    *slot = v;
                }
            }
        }
        state.vertices.truncate(len.saturating_sub(2));
        // Recompute the running sums from vertex j on: the pair terms after the removed corner are
        // unchanged, so all later sums shift by the same delta.
        let before = state
            .vertices
            .get(j - 1)
            .copied()
            .unwrap_or(Vertex { x: 0.0, cum: 0.0 });
        let delta = if let Some(v) = state.vertices.get(j).copied() {
            let new_cum = before.cum + self.segment_term(before.x, v.x, j % 2 == 1);
            new_cum - v.cum
        } else {
            let new_plus = before.cum + self.segment_term(before.x, state.x, (j - 1) % 2 == 0);
            new_plus - old_plus_mass
        };
        if let Some(tail) = state.vertices.get_mut(j..) {
            for v in tail {
                v.cum += delta;
            }
        }
        state.plus_mass = old_plus_mass + delta;
        state.merges = state.merges.saturating_add(1);
        state.merge_error_a_per_m += 2.0 * delta.abs();
    }
}

#[cfg(test)]
mod tests {
    use crate::params::BAKED_MEASURE;

    /// A periodic drive whose extremes shrink by a hair each cycle stacks one nested pair per
    /// cycle in an exact memory; with a resolution the pairs are merged as they come, the
    /// staircase stays short, and the output stays within the accounted merge error of the
    /// exact memory's.
    #[test]
    fn a_resolution_merges_hair_thin_nested_pairs_at_once() {
        let measure = &BAKED_MEASURE;
        let mut exact = measure.negative_saturation::<128>();
        let mut coarse = measure.negative_saturation::<64>();
        coarse.set_resolution(1e-4);
        let mut longest = [0usize; 2];
        let mut worst = 0.0f32;
        for cycle in 0..40 {
            // Extremes 17.97 − 2e-4·cycle and 12.21 + 2e-4·cycle: pairs of ~4e-8 cells².
            let top = 17.97 - 2e-4 * cycle as f32;
            let bottom = 12.21 + 2e-4 * cycle as f32;
            for k in 0..=40 {
                let phase = k as f32 / 40.0 * 2.0 * core::f32::consts::PI;
                let x = 0.5 * (top + bottom) + 0.5 * (top - bottom) * libm::cosf(phase);
                measure.move_to(&mut exact, x);
                measure.move_to(&mut coarse, x);
                longest[0] = longest[0].max(exact.len());
                longest[1] = longest[1].max(coarse.len());
                let d = (measure.output_a_per_m(&exact) - measure.output_a_per_m(&coarse)).abs();
                worst = worst.max(d - coarse.merge_error_a_per_m());
            }
        }
        assert!(
            longest[0] > 40,
            "the exact memory stacks the pairs: {}",
            longest[0]
        );
        assert!(
            longest[1] <= 5,
            "the resolution keeps it short: {}",
            longest[1]
        );
        assert!(coarse.merges() > 30);
        // Within the accounted merge error, up to f32 rounding of the two outputs.
        assert!(
            worst <= 1e-6 * measure.saturation_a_per_m(),
            "{worst} A/m beyond the merge error"
        );
    }

    /// The merge removes the pair with the smallest corner rectangle: checked against a direct
    /// evaluation of every candidate's area on a random, often-full staircase of capacity 10.
    #[test]
    fn merge_removes_the_pair_with_the_smallest_rectangle() {
        let measure = &BAKED_MEASURE;
        let mut state = measure.negative_saturation::<10>();
        let mut seed = 0x2545_F491_u32;
        let mut checked = 0;
        for step in 0..5_000 {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            // Decaying random oscillation around the middle: many nested reversals.
            let amplitude = 12.0 * (1.0 - (step % 500) as f32 / 520.0);
            let sign = if step % 2 == 0 { 1.0 } else { -1.0 };
            let x = 12.5 + sign * amplitude * (0.5 + 0.5 * (seed as f32 / u32::MAX as f32));
            let reverses = state.rising() != (x > state.x);
            let full = state.vertices.is_full();
            let expected = if reverses && full && x != state.x {
                let xs: heapless::Vec<f32, 11> = state
                    .vertices
                    .iter()
                    .map(|v| v.x)
                    .chain(core::iter::once(state.x))
                    .collect();
                let m = state.last_index();
                let area = |j: usize| (xs[j + 1] - xs[j - 1]).abs() * (xs[j + 2] - xs[j]).abs();
                let best = (1..m).fold(1, |b, j| if area(j) < area(b) { j } else { b });
                let mut kept: heapless::Vec<f32, 11> = xs.clone();
                kept.remove(best);
                kept.remove(best);
                Some(kept)
            } else {
                None
            };
            let merges = state.merges();
            measure.move_to(&mut state, x);
            if let Some(kept) = expected {
                if state.merges() == merges + 1 {
                    // After the merge the old current input became the last reversal point;
                    // the new move may also have wiped out some of the tail.
                    let now: heapless::Vec<f32, 11> = state.vertices.iter().map(|v| v.x).collect();
                    assert_eq!(&kept[..now.len()], &now[..], "step {step}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 100, "only {checked} merges checked");
    }
}
