//! Gonio's results in the tools people already use: BRDF file formats, plots and the
//! run report.
//!
//! - [`formats`]: MERL binary, ASTM E1392-style text, CSV samples; detection from
//!   content.
//! - [`plot`]: polar plots, hemisphere maps, albedo curves, separability, a rendered
//!   sphere (PNG or SVG, drawn with the font shipped in `assets/fonts`).
//! - [`rgb`]: spectral data turned into linear sRGB (for MERL and true-colour plots).
//! - [`report`]: the self-contained HTML run report.

pub mod formats;
pub mod plot;
pub mod report;
pub mod rgb;
