//! The diagnosis's decision rules: every tuned constant in one place, each with what it trades
//! off. The steps that use them are in the sibling modules; the rules in words are
//! [`CRITERION`] (in `diagnosis.json`).

use maglab_model::candidates;

/// The significance criterion in words (also in `diagnosis.json`).
pub const CRITERION: &str = "every candidate refits R_eddy, xi, f0 and the channel skew on the \
training experiments; one is named when, on held-out experiments (outside the training span in \
frequency and amplitude), it removes at least 91 % of the refitted nominal model's systematic gap \
energy (noise-corrected RMS gap after <= 0.3 x before, or <= 0.5 x before and below max(noise, \
0.2 % of the motion)) and makes at most a quarter of them worse; \
`none` when the refitted nominal model's held-out systematic gap is below max(0.35 x noise, 0.05 % \
of the motion, 1.5 x the model's own integration error), or below max(noise, 0.2 % of the motion, \
that floor) and no candidate explains it";

/// A candidate explains the gap when its held-out systematic gap is at most this fraction of the
/// refitted nominal one (it removes ≥ 91 % of the gap's energy). Trades naming a library effect
/// whose form differs from the rig's (which leaves up to about a quarter of its gap) against
/// naming an out-of-library effect that a static candidate mimics (a third or more left).
pub const EXPLAINED_RATIO: f64 = 0.3;

/// A candidate also explains the gap when what it leaves is below [`none_threshold`] (within
/// the noise) and at most this fraction of the refitted nominal gap (it removes ≥ 75 % of its
/// energy): a gap not far above the noise cannot be cut to [`EXPLAINED_RATIO`] of itself, so
/// the stricter ratio would call every small real effect `none`.
pub const WITHIN_NOISE_RATIO: f64 = 0.5;

/// A candidate that makes more than this share of the held-out experiments worse (RMS up by
/// more than [`WORSE_RMS_FACTOR`] and [`WORSE_NOISE_SHARE`] σ) is no explanation: it trades one
/// band's fit for another's.
pub const MAX_WORSE_SHARE: f64 = 0.25;

/// See [`MAX_WORSE_SHARE`]: the relative rise of an experiment's RMS error that counts as worse.
pub const WORSE_RMS_FACTOR: f64 = 1.05;

/// See [`MAX_WORSE_SHARE`]: the rise in units of the noise σ that counts as worse on top of
/// [`WORSE_RMS_FACTOR`] (below it the change is within the scatter of a held-out RMS).
pub const WORSE_NOISE_SHARE: f64 = 0.1;

/// An `unexplained` verdict is graded *partly explained* by a candidate that removes more than
/// this share of the gap's energy in every held-out band ([`super::grade`]): its part is larger
/// than the rest. Definitional (more than half), not fitted to cases.
pub const PARTIAL_SHARE: f64 = 0.5;

/// The second stage pairs the best this many single candidates (six pairs; up to two band-best
/// candidates join them): more pairs cost a fit each and give a wrong pair more chances.
pub const PAIR_CANDIDATES: usize = 4;

/// Band-best candidates that join the pairs: a slow and a fast effect each show in their own
/// band.
pub const BAND_BEST_CANDIDATES: usize = 2;

/// A candidate that leaves less than this fraction of a band's error is that band's best for
/// the pairs (it helps there, not just ranks first among candidates that all fail).
pub const BAND_HELPS: f64 = 0.8;

/// A winner that leaves more than this many σ of held-out systematic gap (and more than
/// [`SMALL_REMAINDER_SHARE`] of the refitted nominal gap), though less than the full second
/// stage's [`FULL_STAGE_NOISE`] σ and [`FULL_STAGE_SHARE`], is refitted with each other effect
/// of the library only: a weak second effect the winner's fit mostly absorbs leaves a few % of
/// the gap; below this it is the noise's scatter.
pub const SMALL_REMAINDER_NOISE: f64 = 0.5;

/// See [`SMALL_REMAINDER_NOISE`].
pub const SMALL_REMAINDER_SHARE: f64 = 0.02;

/// A winner that leaves more than this many σ of held-out systematic gap (and more than
/// [`FULL_STAGE_SHARE`] of the refitted nominal gap) gets the full second stage: every pair of
/// the best candidates. Lower, the pairs start naming a second effect for a single effect's
/// imperfect form.
pub const FULL_STAGE_NOISE: f64 = 2.0;

/// See [`FULL_STAGE_NOISE`].
pub const FULL_STAGE_SHARE: f64 = 0.1;

/// After a small remainder ([`SMALL_REMAINDER_NOISE`]) the best pair is considered only when
/// it leaves at most this fraction of the next pair's held-out systematic gap, and the next
/// pair at least [`SPECIFIC_NEXT_SHARE`] of the winner's remainder: a remainder that other
/// effects remove as well is the winner's form differing from the rig's, not a second effect.
pub const SPECIFIC_SECOND_RATIO: f64 = 0.5;

/// See [`SPECIFIC_SECOND_RATIO`].
pub const SPECIFIC_NEXT_SHARE: f64 = 0.6;

/// A single candidate that leaves at most this fraction of the refitted nominal gap (removes at
/// least 36 % of its energy) is worth a second effect on top when it is not significant alone:
/// two strong effects each leave much of the gap alone.
pub const PROMISING: f64 = 0.8;

/// A single candidate whose training systematic error is at most this fraction of the refitted
/// nominal model's (it removes three quarters of the training gap's energy) is worth a second
/// effect on top as well, however little it does on the held-out experiments alone: each of two
/// effects may fit the training experiments alone and extrapolate only with the other.
pub const PROMISING_TRAINING: f64 = 0.5;

/// A pair is named when it leaves at most this fraction of what its first effect alone and the
/// refitted nominal model leave: a second effect must halve the remainder to be worth naming.
pub const PAIR_RATIO: f64 = 0.5;

/// Each effect of a named pair is needed: with it switched off and the rest refitted, the
/// held-out gap is at least this many times the pair's.
pub const NEEDED_FACTOR: f64 = 2.0;

/// A significant candidate whose training RMS is at most this factor of the winner's fits the
/// training experiments as well ([`super::Diagnosis::equal_on_training`]): then only the
/// extrapolation to the held-out experiments tells them apart, and the report says so.
pub const EQUAL_ON_TRAINING: f64 = 1.01;

/// Two fits whose held-out RMS errors are within this factor of each other explain the held-out
/// experiments equally well: the data do not rank them. The tie goes to the fit that needs fewer
/// of its refitted constants and of the channel skew at an end of their band (a fit that
/// stretches `f0` or the skew to a limit makes up with the nominal constants for what its effect
/// does not explain).
pub const EQUAL_HELD_OUT: f64 = 1.01;

/// Candidates whose held-out error is within this factor of the winner's are listed as
/// ambiguous with it.
pub const AMBIGUOUS_HELD_OUT: f64 = 1.1;

/// A held-out gap up to this many times the model's own integration error
/// ([`super::Diagnosis::model_error_m`]) is no effect. The error is measured as the difference
/// from the same model with twice the substeps; the model converges at about second order, so
/// its error against the exact solution is about 4/3 of that difference, and the refit absorbs
/// part of it.
pub const MODEL_ERROR_FACTOR: f64 = 1.5;

/// The model's substeps may be raised to at most this many times the requested ones
/// ([`super::diagnose`]): each doubling doubles the time of a diagnosis.
pub const MAX_SUBSTEPS_FACTOR: usize = 4;

/// How far the refit may move the constants that `maglab identify` fitted from recorded data
/// (factors for `R_eddy`, `ξ`, `f0`), instead of [`candidates::REFIT_RANGE`]: as far as the
/// identification could have moved them, so that a candidate can take back out of them what
/// the identification absorbed (a lag read as a lower `f0`, ΔE as a higher one).
pub const IDENTIFIED_REFIT_RANGE: [f64; 3] = candidates::IDENTIFICATION_RANGE;

/// The gap below which the verdict is `none` unless a candidate explains it significantly
/// (step 7): the noise level, or 0.2 % of the motion when the noise is smaller (the resolution
/// a user reads a displacement to).
pub fn none_threshold(noise_m: f64, motion_m: f64) -> f64 {
    noise_m.max(0.002 * motion_m)
}

/// The gap below which the verdict is `none` outright: the resolution of the systematic-gap
/// estimate (a few % error in σ makes a spurious gap of ~0.3 σ) or 0.05 % of the motion.
pub fn resolution_floor(noise_m: f64, motion_m: f64) -> f64 {
    (0.35 * noise_m).max(0.0005 * motion_m)
}
