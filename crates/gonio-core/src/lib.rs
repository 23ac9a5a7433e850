//! Gonio's common ground: the geometry of a goniometer measurement, the radiometric
//! quantities that turn detector readings into BRDF values, spectral channels, and the
//! numerical quadrature every integral in Gonio goes through.
//!
//! - [`Vec3`], [`Dir`] (a unit vector), [`Spherical`] (radians) and [`SphericalDeg`]
//!   (degrees, for files and commands) follow `docs/CONVENTIONS.md`: z is the surface normal,
//!   both directions point away from the surface, θ from the normal, φ from +x to +y.
//! - [`Frame`] is an orthonormal local frame; [`HalfDiff`] the half/difference angles.
//! - [`radiometry`] holds the quantities of DeYoung's Appendix A that an instrument
//!   needs: solid angle of an aperture, projected solid angle, BRDF from a flux ratio.
//! - [`Channels`] names the spectral channels of every BRDF value; [`Spectrum`] is a
//!   value per channel that knows its channels.
//! - [`colour`] turns spectra into CIE XYZ, chromaticity and sRGB (CIE 015:2018).
//! - [`quad`] is adaptive Gauss–Kronrod quadrature in one and two dimensions.
//! - [`special`] has the error function the microfacet models need.
//! - [`dirfile`] reads and writes the directions CSV of `docs/CONVENTIONS.md`.
//! - [`kinematics`] maps a goniometer's stage positions to direction pairs and back.
//! - [`goniometer`] is the instrument as planning and reduction see it: layout, role
//!   axes, limits, speeds ([`motion`]) and optical geometry.
//! - [`kdtree`] is the k-d tree for exact k-nearest queries under a pluggable metric
//!   (Euclidean for scattered samples, motion time for plan ordering), with deletion.
//! - [`rng`] is SplitMix64, the deterministic hash and generator of counters and seeds.
//! - [`input`] reads input files without trusting them (regular files only, never
//!   blocking, at most a cap of bytes); [`limits`] holds the sane ranges numbers from
//!   files are checked against, with messages that name them.
//! - [`fuzz`] makes hostile variations of good input files for the loaders' tests.
//!
//! ```
//! use gonio_core::{Dir, SphericalDeg};
//! let wi = Dir::from(SphericalDeg::new(30.0, 0.0));
//! let m = wi.mirror();
//! let back = SphericalDeg::from(m);
//! assert!((back.theta_deg - 30.0).abs() < 1e-12 && (back.phi_deg - 180.0).abs() < 1e-12);
//! ```
//!
//! This crate has no I/O beyond reading the input files it is asked to parse, and no
//! randomness: [`rng`] is a deterministic function of its seed.

mod channels;
pub mod colour;
pub mod dirfile;
mod frame;
pub mod fuzz;
mod geometry;
pub mod goniometer;
pub mod input;
pub mod kdtree;
pub mod kinematics;
pub mod limits;
pub mod motion;
pub mod quad;
pub mod radiometry;
pub mod rng;
pub mod special;
pub mod spectral_timing;
pub mod tomlfile;
mod vec3;

pub use channels::{ChannelError, Channels, Spectrum};
pub use frame::Frame;
pub use geometry::{Dir, DirPair, HalfDiff, Spherical, SphericalDeg, half_vector, sin_cos_deg};
pub use vec3::Vec3;

/// Positions in text, for error messages that name a line and column.
pub mod text {
    use std::fmt;
    use std::path::Path;

    /// Writes the one-line form every Gonio input error takes:
    /// `FILE:LINE:COL: field `NAME`: MESSAGE`, leaving out the parts that are unknown
    /// (`unnamed` stands in for a missing file name).
    pub fn write_located(
        f: &mut fmt::Formatter<'_>,
        path: Option<&Path>,
        unnamed: &str,
        line: Option<usize>,
        column: Option<usize>,
        field: Option<&str>,
        message: &str,
    ) -> fmt::Result {
        match path {
            Some(p) => write!(f, "{}", p.display())?,
            None => f.write_str(unnamed)?,
        }
        if let Some(l) = line {
            write!(f, ":{l}")?;
            if let Some(c) = column {
                write!(f, ":{c}")?;
            }
        }
        f.write_str(": ")?;
        if let Some(field) = field {
            write!(f, "field `{field}`: ")?;
        }
        f.write_str(message)
    }

    /// `text` without the UTF-8 byte order mark that Windows editors and spreadsheets
    /// put at the start of a file ("CSV UTF-8"): every text reader takes it off
    /// first, so that a header or a first key compares equal to what it says.
    pub fn strip_bom(text: &str) -> &str {
        text.strip_prefix('\u{feff}').unwrap_or(text)
    }

    /// [`strip_bom`] for bytes not yet known to be UTF-8.
    pub fn strip_bom_bytes(bytes: &[u8]) -> &[u8] {
        bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes)
    }

    /// The 1-based line and column (in characters) of byte `offset` in `text`.
    pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
        let mut end = offset.min(text.len());
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        let before = &text[..end];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }

    #[cfg(test)]
    mod tests {
        #[test]
        fn lines_and_columns() {
            let t = "a = 1\nbé = 2\n";
            assert_eq!(super::line_col(t, 0), (1, 1));
            assert_eq!(super::line_col(t, 6), (2, 1));
            // 'é' is two bytes: the '=' at byte 10 is the 4th character of line 2.
            assert_eq!(super::line_col(t, 10), (2, 4));
            assert_eq!(super::line_col(t, 999), (3, 1));
        }

        #[test]
        fn a_byte_order_mark_is_taken_off_once() {
            assert_eq!(super::strip_bom("\u{feff}a,b"), "a,b");
            assert_eq!(super::strip_bom("\u{feff}\u{feff}a"), "\u{feff}a");
            assert_eq!(super::strip_bom("a\u{feff}"), "a\u{feff}");
            assert_eq!(super::strip_bom_bytes(b"\xef\xbb\xbfkind"), b"kind");
            assert_eq!(super::strip_bom_bytes(b"\xef\xbb"), b"\xef\xbb");
        }
    }
}
