//! The virtual gonioreflectometer: BRDFs predicted by Monte Carlo ray tracing of a
//! surface's microgeometry (Westin, Arvo & Torrance 1992; DeYoung 1996 Sec. 2.2.3).
//!
//! - [`HeightField`]: a periodic lattice of heights, two planar triangles a cell, a
//!   material id a triangle; generators for Gaussian random surfaces of given RMS
//!   height and correlation length, V-grooves / sawtooth with two materials
//!   (DeYoung Fig. 2.3), parallel cylinders (brushed metal), and explicit maps.
//! - [`Material`]: what a facet does — mirror, conductor or dielectric Fresnel,
//!   Lambert, or any gonio-brdf [`Model`](gonio_brdf::Model) at the microscale.
//! - [`Sample`]: surface + materials + channels, from a surface file
//!   ([`Sample::load`], format in [`surface`]).
//! - [`Tracer`]: ray–height-field intersection over a max-mip hierarchy (and a flat
//!   grid DDA and brute force, for benchmarks and as the test oracle).
//! - [`Simulation`]: traces rays through every bounce and estimates a tabulated BRDF
//!   ([`Simulation::to_table`], per bounce order, with Monte Carlo errors and albedos)
//!   or the symmetric spherical-harmonic matrix of Westin et al.
//!   ([`Simulation::estimate_sh`]).
//!
//! ```
//! use gonio_micro::{Sample, SimOptions, Simulation};
//! use gonio_process::{Axis, Grid};
//!
//! let sample = Sample::from_toml(r#"
//!     channels = ["value"]
//!     [surface]
//!     kind = "gaussian"
//!     size = [32, 32]
//!     rms_height = 0.5
//!     correlation_length = 4.0
//!     seed = 1
//!     material = "white"
//!     [materials.white]
//!     kind = "lambert"
//!     albedo = [1.0]
//! "#, None).unwrap();
//! let sim = Simulation::new(sample, SimOptions::default()).unwrap();
//! let grid = Grid::isotropic(
//!     Axis::from_deg(0.0, 30.0, 2),
//!     Axis::full_turn(4),
//!     Axis::polar_midpoints(3),
//! );
//! let r = sim.to_table(&grid, 4096, 7).unwrap();
//! // A white Lambertian microsurface keeps all the light (the white furnace).
//! assert!((r.albedo[0].albedo[0] - 1.0).abs() < 1e-12);
//! ```
//!
//! # Design
//! - **Determinism.** Every ray has its own counter-based stream (SplitMix64) named
//!   by the seed, the purpose, the incident node and its index; a segment's start
//!   points are drawn in spatial order by a tree whose splits have streams of their
//!   own. Blocks of [`sim::BLOCK`] rays run in parallel (rayon) and their sums are
//!   merged in ray order, so the same seed gives the same bytes on any number of
//!   threads.
//! - **Periodicity.** The patch tiles the plane: rays that leave it sideways meet
//!   its copies, so there are no edges to fall off, and every bounce is traced.
//! - **Exactness where it is cheap.** Facets are planar triangles, so normals are
//!   exact; the Gaussian surface is scaled to exactly the RMS height asked for.

mod error;
mod escape;
pub mod heightfield;
pub mod material;
pub mod sim;
pub mod surface;
pub mod trace;

pub use error::MicroError;
pub use heightfield::{GaussianParams, HeightField, HeightStats};
pub use material::{Material, fresnel_conductor, fresnel_dielectric};
pub use sim::{
    Exits, IncidentAlbedo, MAX_BOUNCES, MAX_RAYS, MicroResult, ORDERS, SEGMENT_RAYS, ShEstimate,
    SimOptions, Simulation, TablePart, TraceStats,
};
pub use surface::Sample;
pub use trace::{Hit, Method, Ray, Tracer};
