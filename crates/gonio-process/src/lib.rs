//! Processing: BRDF samples become tabulated BRDFs, and tabulated BRDFs are
//! measured and transformed for the four properties of DeYoung's thesis
//! (reciprocity, energy conservation, isotropy, separability).
//!
//! Pure: this crate knows nothing of run files, SQLite, serial ports or clocks. A
//! run's readings become [`Samples`] in `gonio-reduce`.
//!
//! - [`samples`]: scattered samples, the nearest-j Gaussian kernel of Sec. 3.2.1,
//!   resampling onto grids with the interpolation error estimated from the data.
//! - [`grid`]: uniform and isotropic grids and quadrilinear interpolation.
//! - [`hemisphere`]: measured samples over the hemisphere: bilateral unfolding of
//!   isotropic half turns, the data's own grid, the triangulated albedo.
//! - [`measure`]: P_r, P_ec, P_i, P_s^(k) (Ch. 4), with the albedos' quadrature
//!   uncertainty.
//! - [`floor`]: what each measure reads for a BRDF with the property, under the same
//!   sampling and noise.
//! - [`transform`]: the δ-transforms of Ch. 5, weighted by the uncertainties.
//! - [`separable`]: the k-separable representation (Eq. 5.13–5.14).
//! - [`sh`]: real spherical harmonics with a symmetric coefficient matrix, exactly
//!   reciprocal (Westin et al. 1992, Eq. 8–10).
//! - [`reduction`]: the account a run's reduction gives (written by `gonio-reduce`).
//! - [`file`](mod@file): the table and sample file (CSV with a sidecar JSON).
//! - [`svd`]: the leading singular values and Frobenius tails P_s^(k) needs.

pub mod adapt;
pub mod columns;
pub mod covariance;
pub mod file;
pub mod grid;
pub mod hemisphere;
pub mod measure;
/// The measures' floors ([`measure::floor`]), at the crate root as before.
pub use measure::floor;
pub mod reduction;
pub mod samples;
pub mod separable;
pub mod sh;
pub mod svd;
pub mod transform;

pub use grid::{Axis, Grid, GridStep, MAX_GRID_NODES, Table};

/// The largest magnitude a coefficient of a harmonics file or a factor of a separable
/// file may have: 10¹⁰⁰. Finite is not enough: two factors of 10²⁰⁰ multiply to
/// infinity, and a harmonics sum of 10³⁰⁵s overflows; no BRDF needs more than a few
/// dozen orders of magnitude.
pub const MAX_MAGNITUDE: f64 = 1e100;
pub use samples::{Sample, Samples};

/// Why processing refused its input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcessError {
    /// A grid axis that cannot be used.
    #[error("grid axis `{axis}` {why}")]
    Grid {
        /// The axis (`phi_i`, `theta_i`, `phi_o`, `theta_o`).
        axis: &'static str,
        /// What is wrong with it.
        why: String,
    },
    /// Arrays of the wrong length.
    #[error("shape: {0}")]
    Shape(String),
    /// A value that is not usable (not finite, negative uncertainty…).
    #[error("value: {0}")]
    Value(String),
    /// A request that the data cannot answer (no samples, no hemisphere coverage…).
    #[error("{0}")]
    Unsupported(String),
    /// A linear-algebra routine did not converge.
    #[error("numerics: {0}")]
    Numerics(String),
}

impl ProcessError {
    pub(crate) fn grid(axis: &'static str, why: &str) -> ProcessError {
        ProcessError::Grid {
            axis,
            why: why.into(),
        }
    }
}
