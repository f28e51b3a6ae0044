//! `maglab-signal`: signal measures of recorded traces, shared by the identification, the
//! diagnosis and the bench plant's suite.
//!
//! * [`spectrum`]: spectra (rustfft), the dominant tone of a record, harmonic least squares
//!   (the paper's phase-lag scheme compares their phasors), Fourier coefficients over whole
//!   periods;
//! * [`noise`]: the white-noise level of a residual;
//! * [`denoise`]: a record with a known white noise taken out (thresholded cosine transform);
//! * [`branches`]: ascending / descending and near-reversal labels of an input's samples;
//! * [`golden`]: golden-section search, the workspace's one-dimensional minimizer.
//!
//! Everything is f64, allocation is fine (host only), and no function reads a file.

pub mod branches;
pub mod denoise;
pub mod golden;
pub mod noise;
pub mod spectrum;
