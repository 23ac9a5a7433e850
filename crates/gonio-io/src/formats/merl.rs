//! The MERL binary BRDF of Matusik et al. 2003 ("A data-driven reflectance model"),
//! as its reference reader `BRDFRead.cpp` defines it.
//!
//! # File
//! Three little-endian `int32`s, 90, 90, 180 (the bins of θh, θd, φd), then three
//! planes R, G, B of 1 458 000 little-endian `f64`s each: exactly
//! 12 + 3 · 1 458 000 · 8 = 34 992 012 bytes ([`FILE_BYTES`]). Within a plane the
//! bin (θh index `i`, θd index `j`, φd index `k`) is at `k + 180·(j + 90·i)`
//! ([`Bin::index`]). A stored value is the BRDF divided by the channel's scale
//! ([`SCALE`]: 1/1500, 1.15/1500, 1.66/1500), so BRDF = file value × scale. A negative
//! (or NaN) value marks an invalid bin, one that holds no data; Gonio writes
//! [`INVALID`] (−1) there. `+inf` is refused.
//!
//! # Bins
//! The half/difference angles are the standard ones of the reference code and
//! [`gonio_core::HalfDiff`]: the half vector `h = normalize(wi + wo)` has spherical
//! angles (θh, φh); the difference vector is `wi` turned by −φh about z, then by −θh
//! about y; (θd, φd) are its spherical angles. An isotropic BRDF does not depend on
//! φh, and reciprocity (swapping `wi` and `wo`) moves φd by π, so φd is folded into
//! [0, π). The indices ([`theta_h_index`], [`theta_d_index`], [`phi_d_index`]),
//! clamped to their ranges:
//!
//! - θh: `floor(sqrt(θh / (π/2)) · 90)` — the square-root map, dense near the
//!   specular peak (θh = 0);
//! - θd: `floor(θd / (π/2) · 90)`;
//! - φd: `floor(φd / π · 180)`, with φd + π for φd < 0 (here: φd − π for φd ≥ π).
//!
//! The **centre** of bin (i, j, k) ([`Bin::centre`]) is
//! θh = ((i + ½)/90)² · π/2 (the inverse square-root map at i + ½),
//! θd = (j + ½)/90 · π/2, φd = (k + ½)/180 · π, and its direction pair
//! ([`Bin::centre_pair`]) is the one with φh = 0. Near grazing one of the two
//! directions of a centre pair can lie below the horizon.
//!
//! # Evaluation
//! [`MerlBrdf`]'s [`Brdf::eval`] returns the value of the bin the pair falls in —
//! piecewise constant, no interpolation between bins, exactly what the MERL
//! reference lookup does — and 0 for an invalid bin (per channel), for a direction
//! at or below the horizon, and for `wi = −wo`. [`MerlBrdf::valid`] says whether the
//! bin holds data.
//!
//! # Writing
//! Any isotropic input is resampled onto the bin centres (always in parallel):
//! [`MerlBrdf::from_brdf`] (every bin valid), [`MerlBrdf::from_table`] (bins outside
//! the table's coverage invalid) and [`MerlBrdf::from_samples`] (kernel interpolation;
//! bins far from every sample invalid). Inputs are evaluated as given at the centre
//! pairs (φh = 0): the format stores isotropic BRDFs, and an anisotropic input is
//! recorded along φh = 0. Channels: R, G, B as they are, a single channel as grey
//! (the same BRDF in R, G and B); wavelength channels are refused here: turn them into
//! linear sRGB first with [`crate::rgb::to_rgb`], as `gonio export --format merl`
//! does. A negative value — measurement noise around 0 — cannot be stored as such
//! (negative means invalid) and is written as 0.

use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt;
use std::io::{self, Write};
use std::path::Path;

use gonio_brdf::{Brdf, Weighted};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, Dir, DirPair, HalfDiff, SphericalDeg};
use gonio_process::grid::Axis;
use gonio_process::samples::Kernel;
use gonio_process::{Sample, Samples, Table};
use rayon::prelude::*;

use super::{Format, FormatError};

/// Bins of θh.
pub const THETA_H_BINS: usize = 90;
/// Bins of θd.
pub const THETA_D_BINS: usize = 90;
/// Bins of φd (over [0, π)).
pub const PHI_D_BINS: usize = 180;
/// Bins in one channel's plane: 90 · 90 · 180 = 1 458 000.
pub const BINS: usize = THETA_H_BINS * THETA_D_BINS * PHI_D_BINS;
/// The header's three `int32`s.
pub const HEADER: [i32; 3] = [90, 90, 180];
/// Bytes of the header.
pub const HEADER_BYTES: usize = 12;
/// Bytes of a MERL file: 12 + 3 · 1 458 000 · 8 = 34 992 012.
pub const FILE_BYTES: usize = HEADER_BYTES + 3 * BINS * 8;
/// The scale of each channel (R, G, B): BRDF = file value × scale.
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// The file value Gonio writes in an invalid bin.
pub const INVALID: f64 = -1.0;

/// The channels of every MERL table.
static RGB: Channels = Channels::Rgb;

/// Angles (radians) within which a bin centre counts as inside a table's axis range:
/// the tolerance `gonio_process::grid` puts nodes at.
const ON_AXIS: f64 = 1e-9;

/// The θh index of the square-root map: `floor(sqrt(θh / (π/2)) · 90)`, evaluated as
/// the reference code does (`sqrt(θh / (π/2) · 90 · 90)`) and clamped to 0..=89;
/// 0 for θh ≤ 0 or NaN.
pub fn theta_h_index(theta_h: f64) -> usize {
    if theta_h.is_nan() || theta_h <= 0.0 {
        return 0;
    }
    let t = (theta_h / FRAC_PI_2 * THETA_H_BINS as f64 * THETA_H_BINS as f64).sqrt();
    (t as usize).min(THETA_H_BINS - 1)
}

/// The θd index: `floor(θd / (π/2) · 90)`, clamped to 0..=89; 0 for θd ≤ 0 or NaN.
pub fn theta_d_index(theta_d: f64) -> usize {
    if theta_d.is_nan() || theta_d <= 0.0 {
        return 0;
    }
    ((theta_d / FRAC_PI_2 * THETA_D_BINS as f64) as usize).min(THETA_D_BINS - 1)
}

/// The φd index after folding by reciprocity into [0, π): `floor(φd / π · 180)`,
/// clamped to 0..=179; 0 for a non-finite φd.
pub fn phi_d_index(phi_d: f64) -> usize {
    if !phi_d.is_finite() {
        return 0;
    }
    let p = phi_d.rem_euclid(PI);
    ((p / PI * PHI_D_BINS as f64) as usize).min(PHI_D_BINS - 1)
}

/// One bin of the table: its θh, θd and φd indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Bin {
    /// θh index, 0..90 (square-root map).
    pub theta_h: usize,
    /// θd index, 0..90.
    pub theta_d: usize,
    /// φd index, 0..180.
    pub phi_d: usize,
}

impl Bin {
    /// The bin of these indices, `None` when one is out of range.
    pub fn new(theta_h: usize, theta_d: usize, phi_d: usize) -> Option<Bin> {
        (theta_h < THETA_H_BINS && theta_d < THETA_D_BINS && phi_d < PHI_D_BINS).then_some(Bin {
            theta_h,
            theta_d,
            phi_d,
        })
    }

    /// Position in a channel's plane: `φd + 180·(θd + 90·θh)`.
    pub fn index(self) -> usize {
        self.phi_d + PHI_D_BINS * (self.theta_d + THETA_D_BINS * self.theta_h)
    }

    /// The bin at a position of a plane; `None` beyond [`BINS`].
    pub fn from_index(i: usize) -> Option<Bin> {
        (i < BINS).then_some(Bin {
            theta_h: i / (PHI_D_BINS * THETA_D_BINS),
            theta_d: (i / PHI_D_BINS) % THETA_D_BINS,
            phi_d: i % PHI_D_BINS,
        })
    }

    /// The bin of half/difference angles (φh is ignored).
    pub fn of_angles(hd: &HalfDiff) -> Bin {
        Bin {
            theta_h: theta_h_index(hd.theta_h),
            theta_d: theta_d_index(hd.theta_d),
            phi_d: phi_d_index(hd.phi_d),
        }
    }

    /// The bin a pair of directions falls in; `None` when `wi = −wo`.
    pub fn of(wi: Dir, wo: Dir) -> Option<Bin> {
        HalfDiff::from_pair(wi, wo).map(|hd| Bin::of_angles(&hd))
    }

    /// The bin's centre (radians, φh = 0): θh = ((i + ½)/90)² · π/2,
    /// θd = (j + ½)/90 · π/2, φd = (k + ½)/180 · π.
    pub fn centre(self) -> HalfDiff {
        let u = (self.theta_h as f64 + 0.5) / THETA_H_BINS as f64;
        HalfDiff {
            theta_h: u * u * FRAC_PI_2,
            phi_h: 0.0,
            theta_d: (self.theta_d as f64 + 0.5) / THETA_D_BINS as f64 * FRAC_PI_2,
            phi_d: (self.phi_d as f64 + 0.5) / PHI_D_BINS as f64 * PI,
        }
    }

    /// The direction pair of the centre (φh = 0). Either direction may lie below the
    /// horizon near grazing.
    pub fn centre_pair(self) -> DirPair {
        self.centre().to_pair()
    }

    /// Every bin, in file order.
    pub fn all() -> impl Iterator<Item = Bin> {
        (0..BINS).filter_map(Bin::from_index)
    }
}

impl fmt::Display for Bin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = self.centre();
        write!(
            f,
            "bin (θh {}, θd {}, φd {}) centred at θh {:.4}°, θd {:.1}°, φd {:.1}°",
            self.theta_h,
            self.theta_d,
            self.phi_d,
            c.theta_h.to_degrees(),
            c.theta_d.to_degrees(),
            c.phi_d.to_degrees()
        )
    }
}

/// A MERL table: an isotropic, reciprocal RGB BRDF on 90 × 90 × 180 half/difference
/// bins, some of which may be invalid (module docs).
///
/// It keeps the file's values as they are (so reading and writing again gives the
/// same bytes) and implements [`Brdf`] with channels R, G, B. Two tables are equal
/// when their file values are the same bit for bit (NaN markers included).
#[derive(Clone)]
pub struct MerlBrdf {
    /// File values, planes R, G, B of [`BINS`] each; never `+inf`.
    values: Vec<f64>,
}

impl PartialEq for MerlBrdf {
    fn eq(&self, o: &MerlBrdf) -> bool {
        self.values.len() == o.values.len()
            && self
                .values
                .iter()
                .zip(&o.values)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

impl fmt::Debug for MerlBrdf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MerlBrdf")
            .field("valid_bins", &self.valid_bins())
            .field("bins", &BINS)
            .finish()
    }
}

/// Options of [`MerlBrdf::from_samples`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FromSamples {
    /// The nearest-j Gaussian kernel (`gonio_process::samples`).
    pub kernel: Kernel,
    /// The largest distance from a bin centre to its nearest sample for which the bin
    /// is filled; farther bins are invalid. The distance is the samples' R⁶ distance,
    /// `sqrt(|wi − wi'|² + |wo − wo'|²)` (isotropic samples turned to φi = 0 first),
    /// which for small angles is the two directions' angular distances combined, in
    /// radians. For isotropic samples this overstates the distance between nearby
    /// pairs at near-normal incidence (where turning to φi = 0 is ill-conditioned),
    /// so a few bins there may stay invalid: the error is always on the safe side.
    pub max_distance: f64,
}

impl FromSamples {
    /// The default [`FromSamples::max_distance`]: 10° (0.1745 rad). A uniform grid of
    /// 10° steps leaves no point farther than 10° · √3 / 2 ≈ 8.7° from a node, so it is
    /// covered; a sparser scan leaves holes, which stay invalid.
    pub const DEFAULT_MAX_DISTANCE: f64 = 10.0 * PI / 180.0;
}

impl Default for FromSamples {
    fn default() -> Self {
        FromSamples {
            kernel: Kernel::default(),
            max_distance: FromSamples::DEFAULT_MAX_DISTANCE,
        }
    }
}

/// How the input's channels become R, G, B.
#[derive(Clone, Copy)]
enum ChannelMap {
    Rgb,
    Grey,
}

fn channel_map(channels: &Channels) -> Result<ChannelMap, FormatError> {
    match channels {
        Channels::Rgb => Ok(ChannelMap::Rgb),
        Channels::Single => Ok(ChannelMap::Grey),
        Channels::Wavelengths(_) => Err(FormatError::whole(
            Some(Format::Merl),
            None,
            format!(
                "a MERL file holds R, G, B (or one grey channel); the data has the \
                 wavelength channels {channels}"
            ),
        )),
    }
}

impl MerlBrdf {
    /// A table from file values (planes R, G, B of [`BINS`] each, BRDF / [`SCALE`];
    /// negative or NaN marks an invalid bin). Refused when the length is wrong or a
    /// value is `+inf`.
    pub fn from_file_values(values: Vec<f64>) -> Result<MerlBrdf, FormatError> {
        if values.len() != 3 * BINS {
            return Err(FormatError::whole(
                Some(Format::Merl),
                None,
                format!("{} values, a MERL table has {}", values.len(), 3 * BINS),
            ));
        }
        if let Some(i) = values.iter().position(|v| *v == f64::INFINITY) {
            return Err(FormatError::at_byte(
                Format::Merl,
                None,
                (HEADER_BYTES + 8 * i) as u64,
                format!("value {i} is +inf"),
            ));
        }
        Ok(MerlBrdf { values })
    }

    /// The file values (planes R, G, B).
    pub fn file_values(&self) -> &[f64] {
        &self.values
    }

    /// The BRDF value (1/sr) of channel `ch` (0 = R, 1 = G, 2 = B) in a bin; `None`
    /// when the bin is invalid in that channel or `ch > 2`.
    pub fn value(&self, bin: Bin, ch: usize) -> Option<f64> {
        let s = *SCALE.get(ch)?;
        let v = self.values[ch * BINS + bin.index()];
        (v >= 0.0).then_some(v * s)
    }

    /// The three BRDF values of a bin, when it is valid in all three channels.
    pub fn bin_values(&self, bin: Bin) -> Option<[f64; 3]> {
        Some([
            self.value(bin, 0)?,
            self.value(bin, 1)?,
            self.value(bin, 2)?,
        ])
    }

    /// Whether a bin holds data in all three channels.
    pub fn is_valid_bin(&self, bin: Bin) -> bool {
        self.bin_values(bin).is_some()
    }

    /// Whether the pair falls in a bin that holds data in all three channels; false
    /// for a direction at or below the horizon and for `wi = −wo`.
    pub fn valid(&self, wi: Dir, wo: Dir) -> bool {
        wi.is_above() && wo.is_above() && Bin::of(wi, wo).is_some_and(|b| self.is_valid_bin(b))
    }

    /// How many bins hold data in all three channels.
    pub fn valid_bins(&self) -> usize {
        (0..BINS)
            .filter(|&i| (0..3).all(|ch| self.values[ch * BINS + i] >= 0.0))
            .count()
    }

    /// The valid bins whose centre pair lies strictly above the horizon, as isotropic
    /// samples at the centre pairs (channels R, G, B, no uncertainties): up to about
    /// 1.1 million of them. [`MerlBrdf::to_samples_strided`] takes fewer.
    pub fn to_samples(&self) -> Samples {
        self.to_samples_strided(1)
    }

    /// As [`MerlBrdf::to_samples`], from every `stride`-th bin along each of θh, θd
    /// and φd (indices divisible by `stride`; 0 counts as 1): about `1/stride³` of
    /// them.
    pub fn to_samples_strided(&self, stride: usize) -> Samples {
        let s = stride.max(1);
        let mut samples = Vec::new();
        for th in (0..THETA_H_BINS).step_by(s) {
            for td in (0..THETA_D_BINS).step_by(s) {
                for pd in (0..PHI_D_BINS).step_by(s) {
                    let bin = Bin {
                        theta_h: th,
                        theta_d: td,
                        phi_d: pd,
                    };
                    let Some(v) = self.bin_values(bin) else {
                        continue;
                    };
                    let p = bin.centre_pair();
                    if !(p.wi.is_above() && p.wo.is_above()) {
                        continue;
                    }
                    samples.push(Sample {
                        pair: PairDeg {
                            incident: SphericalDeg::from(p.wi),
                            outgoing: SphericalDeg::from(p.wo),
                        },
                        value: v.to_vec(),
                        sigma: None,
                        flags: 0,
                    });
                }
            }
        }
        Samples {
            channels: Channels::Rgb,
            samples,
            isotropic: true,
        }
    }

    /// The smallest stride for which [`MerlBrdf::to_samples_strided`] gives at most
    /// `max_samples` samples whatever the table holds (counting every bin of the
    /// strided lattice); at least 1.
    pub fn stride_for(max_samples: usize) -> usize {
        (1..=PHI_D_BINS)
            .find(|&s| {
                THETA_H_BINS.div_ceil(s) * THETA_D_BINS.div_ceil(s) * PHI_D_BINS.div_ceil(s)
                    <= max_samples
            })
            .unwrap_or(PHI_D_BINS)
    }

    /// Tabulates any BRDF at the bin centres: every bin valid. A centre pair with a
    /// direction below the horizon gets what the model gives there (0, by the
    /// [`Brdf`] contract). Refused for wavelength channels and for a model that gives
    /// a non-finite value.
    pub fn from_brdf(brdf: &dyn Brdf) -> Result<MerlBrdf, FormatError> {
        let map = channel_map(brdf.channels())?;
        let nc = brdf.channels().len();
        build(map, nc, |bin, out| {
            let p = bin.centre_pair();
            brdf.eval(p.wi, p.wo, out);
            Ok(true)
        })
    }

    /// Resamples a table onto the bin centres with its quadrilinear interpolation.
    /// A bin is valid only when its centre pair lies within the table's coverage:
    /// every angle within its axis's range (to 1e-9 rad; azimuths modulo a full turn,
    /// full-turn azimuth axes covering everything; an isotropic table's φ axis is
    /// φo − φi). Nothing is extrapolated, and reciprocity is not used to fill a bin
    /// whose centre pair lies outside from the swapped pair.
    pub fn from_table(table: &Table) -> Result<MerlBrdf, FormatError> {
        let map = channel_map(&table.channels)?;
        let nc = table.channels.len();
        table
            .grid
            .validate()
            .map_err(|e| FormatError::whole(Some(Format::Merl), None, format!("table: {e}")))?;
        build(map, nc, |bin, out| {
            let p = bin.centre_pair();
            let Some(ang) = coverage(table, p.wi, p.wo) else {
                return Ok(false);
            };
            for (ch, o) in out.iter_mut().enumerate() {
                *o = table.eval_angles(ch, ang);
            }
            Ok(true)
        })
    }

    /// Resamples scattered samples onto the bin centres with the nearest-j Gaussian
    /// kernel (`Samples::interpolator`). A bin is valid only when its centre pair lies
    /// strictly above the horizon and within `options.max_distance` of a sample
    /// (default 10°, [`FromSamples::DEFAULT_MAX_DISTANCE`]); every other bin is
    /// invalid, never invented. A centre that coincides with a sample gets its value
    /// exactly.
    pub fn from_samples(samples: &Samples, options: &FromSamples) -> Result<MerlBrdf, FormatError> {
        let map = channel_map(&samples.channels)?;
        let nc = samples.channels.len();
        if !(options.max_distance.is_finite() && options.max_distance > 0.0) {
            return Err(FormatError::whole(
                Some(Format::Merl),
                None,
                format!(
                    "the largest distance to a sample must be positive, got {}",
                    options.max_distance
                ),
            ));
        }
        let interp = samples
            .interpolator(options.kernel)
            .map_err(|e| FormatError::whole(Some(Format::Merl), None, format!("samples: {e}")))?;
        // The polar ranges of the samples. Turning about the normal keeps θ, so a
        // pair is at least the chords of its polar gaps away from every sample: bins
        // beyond `max_distance` by this bound are invalid without a search.
        let range = |th: &dyn Fn(&Sample) -> f64| {
            samples
                .samples
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
                    let t = th(s).to_radians();
                    (a.min(t), b.max(t))
                })
        };
        let (ti_lo, ti_hi) = range(&|s| s.pair.incident.theta_deg);
        let (to_lo, to_hi) = range(&|s| s.pair.outgoing.theta_deg);
        let chord = |x: f64, lo: f64, hi: f64| 2.0 * ((lo - x).max(x - hi).max(0.0) / 2.0).sin();
        let surely_far = |wi: Dir, wo: Dir| {
            let bound = chord(wi.theta(), ti_lo, ti_hi).hypot(chord(wo.theta(), to_lo, to_hi));
            bound > options.max_distance * (1.0 + 1e-9) + 1e-12
        };
        build(map, nc, |bin, out| {
            let p = bin.centre_pair();
            if !(p.wi.is_above() && p.wo.is_above()) || surely_far(p.wi, p.wo) {
                return Ok(false);
            }
            let pair = PairDeg {
                incident: SphericalDeg::from(p.wi),
                outgoing: SphericalDeg::from(p.wo),
            };
            // NaN (no sample at all) counts as far.
            let d = interp.nearest_distance(&pair);
            if d.is_nan() || d > options.max_distance {
                return Ok(false);
            }
            let (v, _) = interp.eval(&pair);
            out.copy_from_slice(&v);
            Ok(true)
        })
    }

    /// The file's bytes: exactly [`FILE_BYTES`].
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FILE_BYTES);
        for h in HEADER {
            out.extend_from_slice(&h.to_le_bytes());
        }
        for v in &self.values {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Writes the file to `w` (buffer it: this is 4.4 million small writes).
    pub fn write_to<W: Write>(&self, mut w: W) -> io::Result<()> {
        for h in HEADER {
            w.write_all(&h.to_le_bytes())?;
        }
        for v in &self.values {
            w.write_all(&v.to_le_bytes())?;
        }
        w.flush()
    }
}

/// The angles (φi, θi, φo, θo) at which to interpolate `t` for the pair, brought into
/// the axes' ranges, or `None` when the pair lies outside the table's coverage.
fn coverage(t: &Table, wi: Dir, wo: Dir) -> Option<[f64; 4]> {
    let g = &t.grid;
    let (mut pi, ti, mut po, to) = (wi.phi(), wi.theta(), wo.phi(), wo.theta());
    if g.isotropic {
        po -= pi;
        pi = 0.0;
    }
    Some([
        azimuth_within(&g.phi_i, pi)?,
        polar_within(&g.theta_i, ti)?,
        azimuth_within(&g.phi_o, po)?,
        polar_within(&g.theta_o, to)?,
    ])
}

fn polar_within(ax: &Axis, x: f64) -> Option<f64> {
    let (first, last) = (ax.start, ax.node(ax.n - 1));
    (x >= first - ON_AXIS && x <= last + ON_AXIS).then_some(x)
}

fn azimuth_within(ax: &Axis, x: f64) -> Option<f64> {
    if ax.is_periodic() {
        return Some(x);
    }
    let (first, last) = (ax.start, ax.node(ax.n - 1));
    // x moved by whole turns into [first − tol, first − tol + 2π).
    let y = (x - first + ON_AXIS).rem_euclid(std::f64::consts::TAU) + first - ON_AXIS;
    (y <= last + ON_AXIS).then_some(y)
}

/// Fills every bin in parallel: `f(bin, out)` writes the input's channels to `out`
/// and says whether the bin is valid, or gives a reason to refuse. The first error
/// in file order wins, so the outcome does not depend on the thread count.
fn build<F>(map: ChannelMap, nc: usize, f: F) -> Result<MerlBrdf, FormatError>
where
    F: Fn(Bin, &mut [f64]) -> Result<bool, String> + Sync,
{
    const CHUNK: usize = 4096;
    let mut rgb = vec![[INVALID; 3]; BINS];
    let errors: Vec<(usize, String)> = rgb
        .par_chunks_mut(CHUNK)
        .enumerate()
        .filter_map(|(c, chunk)| {
            let mut buf = vec![0.0; nc];
            for (k, o) in chunk.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                let Some(bin) = Bin::from_index(i) else {
                    continue;
                };
                match f(bin, &mut buf) {
                    Ok(false) => {}
                    Ok(true) => match file_values(map, &buf) {
                        Ok(v) => *o = v,
                        Err(e) => return Some((i, format!("{bin}: {e}"))),
                    },
                    Err(e) => return Some((i, format!("{bin}: {e}"))),
                }
            }
            None
        })
        .collect();
    if let Some((_, e)) = errors.into_iter().min_by_key(|e| e.0) {
        return Err(FormatError::whole(Some(Format::Merl), None, e));
    }
    let mut values = vec![0.0; 3 * BINS];
    for (i, v) in rgb.iter().enumerate() {
        for ch in 0..3 {
            values[ch * BINS + i] = v[ch];
        }
    }
    Ok(MerlBrdf { values })
}

/// The three file values of a bin's channel values (BRDF / scale; negative → 0).
fn file_values(map: ChannelMap, v: &[f64]) -> Result<[f64; 3], String> {
    let mut out = [0.0; 3];
    for (ch, o) in out.iter_mut().enumerate() {
        let x = match map {
            ChannelMap::Rgb => v[ch],
            ChannelMap::Grey => v[0],
        };
        if !x.is_finite() {
            return Err(format!("the value {x} is not finite"));
        }
        let f = x.max(0.0) / SCALE[ch];
        if !f.is_finite() {
            return Err(format!("the value {x} is too large for the file"));
        }
        *o = f;
    }
    Ok(out)
}

/// Whether `bytes` is a MERL file by [`super::detect`]'s rule: the exact length and
/// the header.
pub(crate) fn is_merl(bytes: &[u8]) -> bool {
    bytes.len() == FILE_BYTES && header_ok(bytes)
}

/// Whether `bytes` looks enough like a MERL file to be read as one for the error:
/// the right header, or the exact length of a binary (non-text) file.
pub(crate) fn looks_like_merl(bytes: &[u8]) -> bool {
    header_ok(bytes) || (bytes.len() == FILE_BYTES && std::str::from_utf8(bytes).is_err())
}

fn header_ok(bytes: &[u8]) -> bool {
    bytes.len() >= HEADER_BYTES && (0..3).all(|k| header_int(bytes, k) == HEADER[k])
}

fn header_int(bytes: &[u8], k: usize) -> i32 {
    let mut b = [0u8; 4];
    b.copy_from_slice(&bytes[4 * k..4 * k + 4]);
    i32::from_le_bytes(b)
}

/// Reads a MERL file. `path` only labels errors, which give the byte offset: a
/// short header, a wrong header `int32`, a length other than [`FILE_BYTES`] (checked
/// before anything is decoded or allocated), or a `+inf` value.
pub fn read_merl(bytes: &[u8], path: Option<&Path>) -> Result<MerlBrdf, FormatError> {
    let at = |byte: usize, msg: String| FormatError::at_byte(Format::Merl, path, byte as u64, msg);
    if bytes.len() < HEADER_BYTES {
        return Err(at(
            bytes.len(),
            format!(
                "the file ends after {} bytes, inside the 12-byte header",
                bytes.len()
            ),
        ));
    }
    const NAMES: [&str; 3] = ["θh", "θd", "φd"];
    for k in 0..3 {
        let v = header_int(bytes, k);
        if v != HEADER[k] {
            return Err(at(
                4 * k,
                format!(
                    "header int32 {} (bins of {}) is {v}, expected {}",
                    k + 1,
                    NAMES[k],
                    HEADER[k]
                ),
            ));
        }
    }
    if bytes.len() < FILE_BYTES {
        return Err(at(
            bytes.len(),
            format!(
                "the file is truncated: {} bytes, a MERL file has exactly {FILE_BYTES} \
                 ({} missing)",
                bytes.len(),
                FILE_BYTES - bytes.len()
            ),
        ));
    }
    if bytes.len() > FILE_BYTES {
        return Err(at(
            FILE_BYTES,
            format!(
                "{} bytes after the last value: a MERL file has exactly {FILE_BYTES}",
                bytes.len() - FILE_BYTES
            ),
        ));
    }
    let values = decode_values(&bytes[HEADER_BYTES..], HEADER_BYTES, path)?;
    Ok(MerlBrdf { values })
}

/// Decodes little-endian `f64`s; `offset` is the byte offset of `bytes[0]` in the file
/// (for errors). Refuses a length that is not a multiple of 8 and `+inf`.
pub(crate) fn decode_values(
    bytes: &[u8],
    offset: usize,
    path: Option<&Path>,
) -> Result<Vec<f64>, FormatError> {
    let whole = bytes.len() / 8 * 8;
    if whole != bytes.len() {
        return Err(FormatError::at_byte(
            Format::Merl,
            path,
            (offset + whole) as u64,
            format!(
                "{} bytes left over after the last whole value",
                bytes.len() - whole
            ),
        ));
    }
    let mut values = Vec::with_capacity(bytes.len() / 8);
    for (i, c) in bytes.chunks_exact(8).enumerate() {
        let mut b = [0u8; 8];
        b.copy_from_slice(c);
        let v = f64::from_le_bytes(b);
        if v == f64::INFINITY {
            let byte = offset + 8 * i;
            let (ch, bin) = (i / BINS, Bin::from_index(i % BINS));
            let place = match (["R", "G", "B"].get(ch), bin) {
                (Some(c), Some(b)) => format!("channel {c}, {b}"),
                _ => format!("value {i}"),
            };
            return Err(FormatError::at_byte(
                Format::Merl,
                path,
                byte as u64,
                format!("{place}: +inf is not a BRDF value (negative or NaN marks an invalid bin)"),
            ));
        }
        values.push(v);
    }
    Ok(values)
}

/// The file's bytes ([`MerlBrdf::to_bytes`]): exactly [`FILE_BYTES`].
pub fn write_merl(merl: &MerlBrdf) -> Vec<u8> {
    merl.to_bytes()
}

impl Brdf for MerlBrdf {
    fn channels(&self) -> &Channels {
        &RGB
    }

    /// The value of the bin the pair falls in (no interpolation, as the MERL
    /// reference lookup); 0 in a channel where the bin is invalid, for a direction at
    /// or below the horizon, and for `wi = −wo`.
    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if !(wi.is_above() && wo.is_above()) {
            return;
        }
        let Some(bin) = Bin::of(wi, wo) else {
            return;
        };
        for (ch, o) in out.iter_mut().enumerate() {
            *o = self.value(bin, ch).unwrap_or(0.0);
        }
    }

    /// Cosine-weighted about the normal (a measured table's shape is unknown in
    /// advance; this density covers the hemisphere).
    fn proposals(&self, _wi: Dir, out: &mut Vec<Weighted>) {
        out.push(Weighted::COSINE);
    }

    /// Reciprocal by construction: `(wi, wo)` and `(wo, wi)` fall in the same bin
    /// (φd moves by π, which the fold undoes), up to rounding at bin boundaries.
    fn is_reciprocal(&self) -> bool {
        true
    }
}
