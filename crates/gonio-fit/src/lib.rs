//! Fitting measured BRDFs with sums of generalized cosine lobes (Lafortune et al.
//! 1997, Sec. 6) by Levenberg–Marquardt with variable projection, with standard
//! errors, and fits of other analytic models on the same data for comparison.
//!
//! - [`data`]: the pairs, values and residual weights of a fit (metrics, cutoff, σ).
//! - [`varpro`]: the separable least-squares engine (non-negative linear part solved
//!   exactly, Levenberg–Marquardt over the rest, Kaufman's Jacobian).
//! - [`lobes`]: the lobe basis with its analytic derivatives.
//! - [`fit`]: start search, refinement, standard errors, the model file and report.

pub mod compare;
pub mod data;
mod fastmath;
pub mod fit;
pub mod lobes;
pub mod varpro;

pub use data::{Columns, DataOptions, FitData, Metric, Objective};
pub use fit::{FitOptions, LobeFit, MAX_LOBES, fit_lobes};
pub use lobes::{Diffuse, Shape};

/// Why a fit was refused or failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// The data cannot be fitted (empty, not finite, a single incident direction…).
    #[error("{0}")]
    Data(String),
    /// The numerics failed.
    #[error("{0}")]
    Numerics(String),
    /// The options cannot be used (more lobes than [`MAX_LOBES`]): bad input.
    #[error("{0}")]
    Options(String),
}
