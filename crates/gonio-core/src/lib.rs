//! Gonio's common ground: the geometry of a goniometer measurement, the radiometric
//! quantities that turn detector readings into BRDF values, spectral channels, and the
//! numerical quadrature every integral in Gonio goes through.
//!
//! - [`Vec3`], [`Dir`] (a unit vector), [`Spherical`] (radians) and [`SphericalDeg`]
//!   (degrees, for files and commands) follow `CONVENTIONS.md`: z is the surface normal,
//!   both directions point away from the surface, θ from the normal, φ from +x to +y.
//! - [`Frame`] is an orthonormal local frame; [`HalfDiff`] the half/difference angles.
//! - [`radiometry`] holds the quantities of DeYoung's Appendix A that an instrument
//!   needs: solid angle of an aperture, projected solid angle, BRDF from a flux ratio.
//! - [`Channels`] names the spectral channels of every BRDF value; [`Spectrum`] is a
//!   value per channel that knows its channels.
//! - [`quad`] is adaptive Gauss–Kronrod quadrature in one and two dimensions.
//! - [`special`] has the error function the microfacet models need.
//! - [`dirfile`] reads and writes the directions CSV of `CONVENTIONS.md`.
//!
//! ```
//! use gonio_core::{Dir, SphericalDeg};
//! let wi = Dir::from(SphericalDeg::new(30.0, 0.0));
//! let m = wi.mirror();
//! let back = SphericalDeg::from(m);
//! assert!((back.theta_deg - 30.0).abs() < 1e-12 && (back.phi_deg - 180.0).abs() < 1e-12);
//! ```
//!
//! This crate has no I/O beyond parsing text it is handed, and no randomness.

mod channels;
pub mod dirfile;
mod frame;
mod geometry;
pub mod quad;
pub mod radiometry;
pub mod special;
mod vec3;

pub use channels::{ChannelError, Channels, Spectrum};
pub use frame::Frame;
pub use geometry::{Dir, DirPair, HalfDiff, Spherical, SphericalDeg, half_vector, sin_cos_deg};
pub use vec3::Vec3;
