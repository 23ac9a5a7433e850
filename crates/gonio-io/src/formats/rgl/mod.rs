//! The RGL material (`.bsdf`) of Dupuy & Jakob 2018 ("An Adaptive Parameterization
//! for Efficient Material Acquisition and Rendering", SIGGRAPH Asia), which Mitsuba
//! 3's `measured` plugin loads and importance-samples, read and written exactly as
//! that plugin (`src/bsdfs/measured.cpp`) evaluates it.
//!
//! # Parameterisation
//! Directions are held in a unit square `u = (u_θ, u_φ)`: θ = u_θ² · π/2 (dense near
//! the normal) and φ = (2u_φ − 1)π; a solid angle is dω = 2π² u_θ sin θ du.
//!
//! - `ndf` (2-D, `[φ][θ]`): the microfacet distribution D(m) on that square,
//!   normalised so that ∫ D(m) cos θm dm = 1. Gonio derives it from the BRDF's
//!   retro-reflection (the paper's recipe): a microfacet BRDF with Smith's uncorrelated
//!   masking–shadowing gives f(ω, ω) = F D(ω) / (4 σ(ω)²), with G1(ω) = cos θ / σ(ω)
//!   (Heitz 2014, the projected-area form of Smith's G1), so D ∝ f(ω, ω) σ(ω)², solved
//!   by fixed-point iteration; 5% of a cosine distribution (D = 1/π) is mixed in so
//!   that the warp reaches every half vector a diffuse part needs.
//! - `sigma` (2-D over the incident direction): the projected area
//!   σ(ω) = ∫ D(m) ⟨ω · m⟩ dm.
//! - `vndf` (`[φi][θi][φm][θm]`): per incidence, the visible normals
//!   D(m) ⟨ωi · m⟩ / σ(ωi) as a density on the square (times the Jacobian
//!   2π² u_θ sin θm); the plugin turns it into a warp ([`warp::Warp2D`]) from a
//!   uniform *sample square* to half vectors.
//! - `rgb` or `spectra` + `wavelengths` (`[φi][θi][channel][y][x]`): at each node of
//!   the sample square, warped to its half vector m and outgoing direction ωo,
//!   f_r(ωi, ωo) cos θo · 4σ(ωi) / D(m) (with `jacobian` = 1). The plugin evaluates
//!   it bilinearly in the sample square (the inverse warp of ωo's half vector),
//!   linearly in θi (and φi), and multiplies back by D(m) / (4σ(ωi)): at a node it
//!   gives f_r cos θo exactly.
//! - `luminance` (`[φi][θi][y][x]`): the same nodes' luminance (RGB: Rec. 709 Y;
//!   spectral: the mean over wavelengths), which the plugin samples before the VNDF
//!   warp, so that its sampling density follows f_r cos θo.
//! - `theta_i`, `phi_i` (radians): the incidences. An isotropic material has one φi
//!   (φ of m is then relative to φi); an anisotropic one spans [−π, π].
//! - `description` (UTF-8) and `jacobian` (`u8`); Gonio adds `valid` (`u8`,
//!   `[φi][θi][y][x]`): 0 where the value was extrapolated beyond the data.
//!
//! # Reading
//! [`RglBsdf`] checks the structure the plugin checks (types, ranks and matching
//! shapes), builds the same warps, and evaluates as the plugin's `eval`:
//! [`RglBsdf::eval_cos`] is f_r cos θo, [`Brdf::eval`] that divided by cos θo.

pub mod tensor;
pub mod warp;

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

use gonio_brdf::{Brdf, Weighted};
use gonio_core::{Channels, Dir, Vec3};
use rayon::prelude::*;

use super::{Format, FormatError};
use tensor::{Field, Values};
use warp::Warp2D;

/// The most values (VNDF and slices, over every incidence) a file is written with:
/// 64 Mi, 256 MB of `f32` (the database's files have about 0.2 Mi).
const MAX_VALUES: usize = 1 << 26;

/// Rec. 709 luminance weights of linear R, G, B.
const LUMA: [f64; 3] = [0.212_671, 0.715_160, 0.072_169];

/// What [`RglBsdf::from_brdf`] writes: the resolutions. The defaults are the RGL
/// database's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RglOptions {
    /// Incidence angles θi, from 0 to [`RglOptions::theta_max_deg`].
    pub incidences: usize,
    /// The largest θi (degrees); beyond it the plugin holds the last slice.
    pub theta_max_deg: f64,
    /// Nodes a side of the sample square of each incidence (`rgb`, `luminance`).
    pub slice: usize,
    /// Nodes a side of each incidence's VNDF.
    pub vndf: usize,
    /// Nodes of the NDF and σ along θ (and along φ for an anisotropic material).
    pub ndf: usize,
    /// Incidence azimuths of an anisotropic material, over [−π, π].
    pub azimuths: usize,
}

impl Default for RglOptions {
    fn default() -> Self {
        RglOptions {
            incidences: 8,
            theta_max_deg: 85.0,
            slice: 32,
            vndf: 128,
            ndf: 64,
            azimuths: 16,
        }
    }
}

/// An RGL material: its fields and the plugin's warps over them.
#[derive(Clone, Debug)]
pub struct RglBsdf {
    /// The `description` field.
    pub description: String,
    /// Incidence elevations (radians).
    pub theta_i: Vec<f32>,
    /// Incidence azimuths (radians); one (or two) for an isotropic material.
    pub phi_i: Vec<f32>,
    /// Gonio's `valid` mask (`[φi][θi][y][x]`), when the file has one.
    pub valid: Option<Vec<u8>>,
    fields: Vec<Field>,
    channels: Channels,
    /// The wavelengths (nm) of spectral data; `None` for RGB.
    wavelengths: Option<Vec<f64>>,
    ndf: Warp2D,
    sigma: Warp2D,
    vndf: Warp2D,
    spectra: Warp2D,
    isotropic: bool,
    jacobian: bool,
    reduction: i32,
    slice: [usize; 2],
}

impl PartialEq for RglBsdf {
    fn eq(&self, other: &Self) -> bool {
        self.fields == other.fields
    }
}

/// θ of the unit square's u_θ.
fn u2theta(u: f64) -> f64 {
    u * u * FRAC_PI_2
}

/// φ of the unit square's u_φ.
fn u2phi(u: f64) -> f64 {
    (2.0 * u - 1.0) * PI
}

fn theta2u(theta: f64) -> f64 {
    (theta * (2.0 / PI)).sqrt()
}

fn phi2u(phi: f64) -> f64 {
    (phi + PI) / (2.0 * PI)
}

/// Elevation of a unit vector, stable near the normal (as the plugin computes it).
fn elevation(v: Vec3) -> f64 {
    let d = (v.x * v.x + v.y * v.y + (v.z - 1.0) * (v.z - 1.0)).sqrt();
    2.0 * (0.5 * d).min(1.0).asin()
}

fn spherical(theta: f64, phi: f64) -> Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new(cp * st, sp * st, ct)
}

fn dot(a: Vec3, b: Vec3) -> f64 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// The sign the plugin's `mulsign_neg(x, s)` gives x: flipped unless s < 0.
fn mulsign_neg(x: f64, s: f64) -> f64 {
    if s.is_sign_negative() { x } else { -x }
}

impl RglBsdf {
    /// Reads a material from a tensor file's bytes, checking what the plugin checks.
    pub fn read(bytes: &[u8], path: Option<&Path>) -> Result<RglBsdf, FormatError> {
        RglBsdf::from_fields(tensor::read(bytes, path)?, path)
    }

    /// The tensor file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        tensor::write(&self.fields)
    }

    /// The fields, in the file's order.
    pub fn fields(&self) -> &[Field] {
        &self.fields
    }

    /// True when the file holds one incidence azimuth (φ of the half vector relative
    /// to it).
    pub fn is_isotropic(&self) -> bool {
        self.isotropic
    }

    /// The sample square's nodes a side (`[y, x]`).
    pub fn slice_size(&self) -> [usize; 2] {
        self.slice
    }

    /// Builds a material from its fields (any order; unknown fields are kept).
    pub fn from_fields(fields: Vec<Field>, path: Option<&Path>) -> Result<RglBsdf, FormatError> {
        let bad = |m: String| FormatError::whole(Some(Format::Rgl), path, m);
        let get = |name: &str| {
            fields
                .iter()
                .find(|f| f.name == name)
                .ok_or_else(|| bad(format!("no field `{name}` (an RGL material has it)")))
        };
        let f32s = |name: &str, rank: usize| -> Result<(&[usize], &[f32]), FormatError> {
            let f = get(name)?;
            match &f.values {
                Values::F32(v) if f.shape.len() == rank => Ok((&f.shape, v)),
                v => Err(bad(format!(
                    "field `{name}`: {} of rank {}; the plugin reads f32 of rank {rank}",
                    v.type_name(),
                    f.shape.len()
                ))),
            }
        };
        let bytes = |name: &str| -> Result<&[u8], FormatError> {
            let f = get(name)?;
            match &f.values {
                Values::U8(v) if f.shape.len() == 1 => Ok(v),
                v => Err(bad(format!(
                    "field `{name}`: {} of rank {}; the plugin reads u8 of rank 1",
                    v.type_name(),
                    f.shape.len()
                ))),
            }
        };
        let description = String::from_utf8_lossy(bytes("description")?).into_owned();
        let jac = bytes("jacobian")?;
        if jac.len() != 1 {
            return Err(bad(format!(
                "field `jacobian`: {} values, not 1",
                jac.len()
            )));
        }
        let (_, theta_i) = f32s("theta_i", 1)?;
        let (_, phi_i) = f32s("phi_i", 1)?;
        let (ndf_s, ndf) = f32s("ndf", 2)?;
        let (sig_s, sig) = f32s("sigma", 2)?;
        let (vndf_s, vndf) = f32s("vndf", 4)?;
        let (lum_s, lum) = f32s("luminance", 4)?;
        let spectral = fields.iter().any(|f| f.name == "wavelengths");
        let (spec_s, spec) = f32s(if spectral { "spectra" } else { "rgb" }, 5)?;
        let wavelengths = if spectral {
            Some(
                f32s("wavelengths", 1)?
                    .1
                    .iter()
                    .map(|w| *w as f64)
                    .collect::<Vec<_>>(),
            )
        } else {
            None
        };
        let (np, nt) = (phi_i.len(), theta_i.len());
        let nch = wavelengths.as_ref().map_or(3, Vec::len);
        let shape_ok = vndf_s[..2] == [np, nt]
            && lum_s[..2] == [np, nt]
            && lum_s[2] == lum_s[3]
            && spec_s[..3] == [np, nt, nch]
            && spec_s[3] == spec_s[4]
            && lum_s[2..] == spec_s[3..];
        if !shape_ok {
            return Err(bad(format!(
                "shapes that do not match: theta_i [{nt}], phi_i [{np}], vndf {vndf_s:?}, \
                 luminance {lum_s:?}, {} {spec_s:?} ({nch} channels)",
                if spectral { "spectra" } else { "rgb" }
            )));
        }
        let rad = |v: &[f32]| v.iter().map(|x| *x as f64).collect::<Vec<_>>();
        let params = vec![rad(phi_i), rad(theta_i)];
        let w = |name: &str, r: Result<Warp2D, String>| {
            r.map_err(|e| bad(format!("field `{name}`: {e}")))
        };
        let ndf_w = w(
            "ndf",
            Warp2D::new(ndf, ndf_s[1], ndf_s[0], vec![], false, false),
        )?;
        let sigma_w = w(
            "sigma",
            Warp2D::new(sig, sig_s[1], sig_s[0], vec![], false, false),
        )?;
        // The plugin divides by σ: a node at or below 0 would make values infinite.
        if let Some(x) = sig.iter().find(|x| **x <= 0.0) {
            return Err(bad(format!(
                "field `sigma`: a value {x}; projected areas are positive"
            )));
        }
        let vndf_w = w(
            "vndf",
            Warp2D::new(vndf, vndf_s[3], vndf_s[2], params.clone(), true, true),
        )?;
        // Built as the plugin builds it (which checks it), though Gonio only evaluates.
        w(
            "luminance",
            Warp2D::new(lum, lum_s[3], lum_s[2], params.clone(), true, true),
        )?;
        let lambda = wavelengths.clone().unwrap_or_else(|| vec![0.0, 1.0, 2.0]);
        let mut p3 = params;
        p3.push(lambda);
        let spec_w = w(
            if spectral { "spectra" } else { "rgb" },
            Warp2D::new(spec, spec_s[4], spec_s[3], p3, false, false),
        )?;
        let channels = match &wavelengths {
            Some(wl) => {
                Channels::wavelengths(wl).map_err(|e| bad(format!("field `wavelengths`: {e}")))?
            }
            None => Channels::Rgb,
        };
        let isotropic = np <= 2;
        let reduction = if isotropic {
            0
        } else {
            (2.0 * PI / (phi_i[np - 1] as f64 - phi_i[0] as f64)).round() as i32
        };
        let valid = fields
            .iter()
            .find(|f| f.name == "valid")
            .and_then(|f| match &f.values {
                Values::U8(v) if v.len() == np * nt * spec_s[3] * spec_s[4] => Some(v.clone()),
                _ => None,
            });
        Ok(RglBsdf {
            description,
            theta_i: theta_i.to_vec(),
            phi_i: phi_i.to_vec(),
            valid,
            channels,
            wavelengths,
            ndf: ndf_w,
            sigma: sigma_w,
            vndf: vndf_w,
            spectra: spec_w,
            isotropic,
            jacobian: jac[0] != 0,
            reduction,
            slice: [spec_s[3], spec_s[4]],
            fields,
        })
    }

    /// f_r(wi, wo) cos θo per channel, as the plugin's `eval` gives it (0 unless both
    /// directions are above the surface).
    pub fn eval_cos(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        out.fill(0.0);
        let (mut wi, mut wo) = (wi.vec(), wo.vec());
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return;
        }
        if self.reduction >= 2 {
            let sy = wi.y;
            let sx = if self.reduction == 4 { wi.x } else { sy };
            wi.x = mulsign_neg(wi.x, sx);
            wi.y = mulsign_neg(wi.y, sy);
            wo.x = mulsign_neg(wo.x, sx);
            wo.y = mulsign_neg(wo.y, sy);
        }
        let h = Vec3::new(wi.x + wo.x, wi.y + wo.y, wi.z + wo.z);
        let len = dot(h, h).sqrt();
        if len == 0.0 {
            return;
        }
        let m = Vec3::new(h.x / len, h.y / len, h.z / len);
        let (theta_i, phi_i) = (elevation(wi), wi.y.atan2(wi.x));
        let (theta_m, phi_m) = (elevation(m), m.y.atan2(m.x));
        let u_wi = [theta2u(theta_i), phi2u(phi_i)];
        let mut u_m = [
            theta2u(theta_m),
            phi2u(if self.isotropic { phi_m - phi_i } else { phi_m }),
        ];
        u_m[1] -= u_m[1].floor();
        let params = [phi_i, theta_i];
        let (sample, _) = self.vndf.invert(u_m, &params);
        let scale = if self.jacobian {
            self.ndf.eval(u_m, &[]) / (4.0 * self.sigma.eval(u_wi, &[]))
        } else {
            1.0
        };
        for (c, o) in out.iter_mut().enumerate() {
            let lambda = match &self.wavelengths {
                Some(w) => w[c],
                None => c as f64,
            };
            *o = self.spectra.eval(sample, &[phi_i, theta_i, lambda]) * scale;
        }
    }

    /// Writes `brdf` in the format at the resolutions of `opts` (see the module).
    /// `valid(wi, wo)` says where the source holds data rather than extrapolating;
    /// `description` goes into the file.
    pub fn from_brdf(
        brdf: &dyn Brdf,
        opts: &RglOptions,
        description: &str,
        valid: &(dyn Fn(Dir, Dir) -> bool + Sync),
    ) -> Result<RglBsdf, FormatError> {
        let bad = |m: String| FormatError::whole(Some(Format::Rgl), None, m);
        // Each bound well past the database's resolutions; together they keep the
        // file (and the warps built over it) within MAX_VALUES values.
        for (name, v, max) in [
            ("incidences", opts.incidences, 90),
            ("slice", opts.slice, 256),
            ("vndf", opts.vndf, 512),
            ("ndf", opts.ndf, 512),
            ("azimuths", opts.azimuths, 64),
        ] {
            if !(2..=max).contains(&v) {
                return Err(bad(format!("{name}: {v} nodes; 2 to {max} are written")));
            }
        }
        if !(opts.theta_max_deg > 0.0 && opts.theta_max_deg < 90.0) {
            return Err(bad(format!(
                "largest incidence {}°: it must lie in (0°, 90°)",
                opts.theta_max_deg
            )));
        }
        let channels = brdf.channels().clone();
        let nch_src = channels.len();
        let (nch, wavelengths): (usize, Option<Vec<f64>>) = match &channels {
            Channels::Wavelengths(w) => (w.len(), Some(w.to_vec())),
            _ => (3, None),
        };
        // A single channel is written as grey R = G = B.
        let to_out = move |src: &[f64], out: &mut [f64]| {
            if nch_src == 1 {
                out.fill(src[0]);
            } else {
                out.copy_from_slice(src);
            }
        };
        let lum_of = |v: &[f64]| -> f64 {
            if wavelengths.is_some() {
                v.iter().sum::<f64>() / v.len() as f64
            } else {
                LUMA.iter().zip(v).map(|(a, b)| a * b).sum()
            }
        };
        let isotropic = is_isotropic(brdf);
        let np = if isotropic { 1 } else { opts.azimuths };
        let nt = opts.incidences;
        let values = np * nt * (opts.vndf.pow(2) + (nch + 2) * opts.slice.pow(2));
        if values > MAX_VALUES {
            return Err(bad(format!(
                "{nt} incidences × {np} azimuths of {}² VNDF and {}² slices: {values} \
                 values, more than the {MAX_VALUES} a file is written with",
                opts.vndf, opts.slice
            )));
        }
        let phi_i: Vec<f64> = if isotropic {
            vec![0.0]
        } else {
            (0..np).map(|k| u2phi(k as f64 / (np - 1) as f64)).collect()
        };
        let theta_i: Vec<f64> = (0..nt)
            .map(|k| (opts.theta_max_deg.to_radians()) * k as f64 / (nt - 1) as f64)
            .collect();
        // The NDF and σ.
        let (nd_t, nd_p) = (opts.ndf, if isotropic { 2 } else { opts.ndf });
        let retro: Vec<f64> = (0..nd_p * nd_t)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k / nd_t, k % nd_t);
                let theta = u2theta(j as f64 / (nd_t - 1) as f64).min(89.5f64.to_radians());
                let phi = u2phi(i as f64 / (nd_p - 1) as f64);
                let d = Dir::from_angles(theta, phi);
                let mut src = vec![0.0; nch_src];
                brdf.eval(d, d, &mut src);
                let mut v = vec![0.0; nch];
                to_out(&src, &mut v);
                lum_of(&v).max(0.0)
            })
            .collect();
        let ndf = ndf_from_retro(&retro, nd_t, nd_p, isotropic);
        let ndf_w = Warp2D::new(&ndf, nd_t, nd_p, vec![], false, false).map_err(bad)?;
        let sigma = projected_area(&ndf_w, nd_t, nd_p, isotropic);
        let sigma_w = Warp2D::new(&sigma, nd_t, nd_p, vec![], false, false).map_err(bad)?;
        // The VNDF of each incidence.
        let nv = opts.vndf;
        let vndf: Vec<f32> = (0..np * nt)
            .into_par_iter()
            .flat_map_iter(|k| {
                let (phi, theta) = (phi_i[k / nt], theta_i[k % nt]);
                let wi = spherical(theta, phi);
                let ndf_w = &ndf_w;
                (0..nv * nv).map(move |n| {
                    let u = [
                        (n % nv) as f64 / (nv - 1) as f64,
                        (n / nv) as f64 / (nv - 1) as f64,
                    ];
                    let (tm, pm) = (
                        u2theta(u[0]),
                        u2phi(u[1]) + if isotropic { phi } else { 0.0 },
                    );
                    let m = spherical(tm, pm);
                    let v =
                        ndf_w.eval(u, &[]) * dot(wi, m).max(0.0) * 2.0 * PI * PI * u[0] * tm.sin();
                    v as f32
                })
            })
            .collect();
        let params = vec![phi_i.clone(), theta_i.clone()];
        let vndf_w = Warp2D::new(&vndf, nv, nv, params.clone(), true, true).map_err(bad)?;
        // The values at the warped nodes of each incidence's sample square.
        let ns = opts.slice;
        let slices: Vec<(Vec<f32>, Vec<f32>, Vec<u8>)> = (0..np * nt)
            .into_par_iter()
            .map(|k| {
                let (phi, theta) = (phi_i[k / nt], theta_i[k % nt]);
                let wi_dir = Dir::from_angles(theta, phi);
                let u_wi = [theta2u(theta), phi2u(phi)];
                let four_sigma = 4.0 * sigma_w.eval(u_wi, &[]);
                let mut spec = vec![0f32; nch * ns * ns];
                let mut lum = vec![0f32; ns * ns];
                let mut ok = vec![0u8; ns * ns];
                let (mut src, mut v) = (vec![0.0; nch_src], vec![0.0; nch]);
                for n in 0..ns * ns {
                    let (u_m, wo) = warped(&vndf_w, isotropic, phi, theta, node(n, ns));
                    let d = ndf_w.eval(u_m, &[]);
                    if wo.z <= 0.0 || d <= 0.0 {
                        continue;
                    }
                    let wo_dir = Dir::from_unit(wo);
                    brdf.eval(wi_dir, wo_dir, &mut src);
                    to_out(&src, &mut v);
                    let scale = wo.z * four_sigma / d;
                    for (ch, x) in v.iter().enumerate() {
                        spec[ch * ns * ns + n] = (x * scale) as f32;
                    }
                    lum[n] = (lum_of(&v) * scale).max(0.0) as f32;
                    ok[n] = u8::from(valid(wi_dir, wo_dir));
                }
                // A floor keeps every node reachable by the luminance warp.
                let top = lum.iter().fold(0f32, |a, b| a.max(*b));
                let floor = (top * 1e-4).max(f32::MIN_POSITIVE * 1e6);
                lum.iter_mut().for_each(|l| *l = l.max(floor));
                (spec, lum, ok)
            })
            .collect();
        let mut spec = Vec::with_capacity(np * nt * nch * ns * ns);
        let mut lum = Vec::with_capacity(np * nt * ns * ns);
        let mut ok = Vec::with_capacity(np * nt * ns * ns);
        for (s, l, o) in slices {
            spec.extend(s);
            lum.extend(l);
            ok.extend(o);
        }
        let f = |v: &[f64]| v.iter().map(|x| *x as f32).collect::<Vec<f32>>();
        let mut fields = vec![
            Field::bytes("description", description.as_bytes().to_vec()),
            Field::f32("phi_i", vec![np], f(&phi_i)),
            Field::f32("theta_i", vec![nt], f(&theta_i)),
            Field::f32("ndf", vec![nd_p, nd_t], ndf),
            Field::f32("sigma", vec![nd_p, nd_t], sigma),
            Field::f32("vndf", vec![np, nt, nv, nv], vndf),
            Field::f32("luminance", vec![np, nt, ns, ns], lum),
        ];
        match &wavelengths {
            Some(w) => {
                fields.push(Field::f32("wavelengths", vec![w.len()], f(w)));
                fields.push(Field::f32("spectra", vec![np, nt, nch, ns, ns], spec));
            }
            None => fields.push(Field::f32("rgb", vec![np, nt, 3, ns, ns], spec)),
        }
        fields.push(Field::bytes("jacobian", vec![1]));
        fields.push(Field {
            name: "valid".into(),
            shape: vec![np, nt, ns, ns],
            values: Values::U8(ok),
        });
        RglBsdf::from_fields(fields, None)
    }
}

/// The node `n` of a `ns × ns` sample square (x fastest).
fn node(n: usize, ns: usize) -> [f64; 2] {
    [
        (n % ns) as f64 / (ns - 1) as f64,
        (n / ns) as f64 / (ns - 1) as f64,
    ]
}

/// The half vector's square coordinates and the outgoing direction that the sample
/// `s` warps to for the incidence (φi, θi).
fn warped(vndf: &Warp2D, isotropic: bool, phi: f64, theta: f64, s: [f64; 2]) -> ([f64; 2], Vec3) {
    let wi = spherical(theta, phi);
    let (u_m, _) = vndf.sample(s, &[phi, theta]);
    let (tm, pm) = (
        u2theta(u_m[0]),
        u2phi(u_m[1]) + if isotropic { phi } else { 0.0 },
    );
    let m = spherical(tm, pm);
    let c = 2.0 * dot(wi, m);
    (
        u_m,
        Vec3::new(c * m.x - wi.x, c * m.y - wi.y, c * m.z - wi.z),
    )
}

/// How well a material holds its source, as relative RMS of f_r cos θo over every
/// channel: √(Σ (g − g_src)² / Σ g_src²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterpolationError {
    /// At the file's own nodes (every incidence, every node of its sample square
    /// whose outgoing direction is above the surface).
    pub at_nodes: f64,
    /// Between the nodes: 4096 fixed pairs with θi uniform and ωo distributed as
    /// cos θo, both up to [`InterpolationError::theta_max_deg`].
    pub between: f64,
    /// The largest θi and θo of the pairs between the nodes.
    pub theta_max_deg: f64,
}

impl RglBsdf {
    /// The direction pairs of the file's nodes: each incidence with each node of its
    /// sample square whose outgoing direction is above the surface.
    pub fn node_pairs(&self) -> Vec<(Dir, Dir)> {
        let ns = self.slice;
        let mut out = Vec::new();
        for phi in &self.phi_i {
            for theta in &self.theta_i {
                let (phi, theta) = (*phi as f64, *theta as f64);
                for n in 0..ns[0] * ns[1] {
                    let s = [
                        (n % ns[1]) as f64 / (ns[1] - 1) as f64,
                        (n / ns[1]) as f64 / (ns[0] - 1) as f64,
                    ];
                    let (_, wo) = warped(&self.vndf, self.isotropic, phi, theta, s);
                    if wo.z > 0.0 {
                        out.push((Dir::from_angles(theta, phi), Dir::from_unit(wo)));
                    }
                }
            }
        }
        out
    }

    /// The material against `src`, at its nodes and between them (θ up to
    /// `theta_max_deg`).
    pub fn interpolation_error(&self, src: &dyn Brdf, theta_max_deg: f64) -> InterpolationError {
        let nc = self.channels.len();
        let rms = |pairs: &[(Dir, Dir)]| -> f64 {
            let (num, den) = pairs
                .par_iter()
                .map(|(wi, wo)| {
                    let (mut a, mut b) = (vec![0.0; nc], vec![0.0; src.channels().len()]);
                    self.eval_cos(*wi, *wo, &mut a);
                    src.eval(*wi, *wo, &mut b);
                    let c = wo.cos_theta();
                    let grey = b.len() == 1;
                    (0..nc).fold((0.0, 0.0), |(n, d), ch| {
                        let g = if grey { b[0] } else { b[ch] } * c;
                        (n + (a[ch] - g).powi(2), d + g * g)
                    })
                })
                .reduce(|| (0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
            if den > 0.0 { (num / den).sqrt() } else { 0.0 }
        };
        let tmax = theta_max_deg.to_radians();
        let between: Vec<(Dir, Dir)> = (0..4096)
            .map(|k| {
                // A fixed low-discrepancy set (the additive recurrence of the
                // generalised golden ratio in 4-D).
                let g = |a: f64| (0.5 + a * k as f64).fract();
                let (a, b, c, d) = (
                    g(0.858_418_1),
                    g(0.736_881_7),
                    g(0.632_548_6),
                    g(0.542_989_8),
                );
                let ti = a * tmax;
                let to = (b * tmax.sin().powi(2)).sqrt().asin();
                let pi = if self.isotropic {
                    0.0
                } else {
                    (2.0 * d - 1.0) * PI
                };
                (
                    Dir::from_angles(ti, pi),
                    Dir::from_angles(to, pi + (2.0 * c - 1.0) * PI),
                )
            })
            .collect();
        InterpolationError {
            at_nodes: rms(&self.node_pairs()),
            between: rms(&between),
            theta_max_deg,
        }
    }
}

/// True when `brdf` does not change under a rotation of both directions about the
/// normal (checked at fixed pairs, to 1e-9 relative).
fn is_isotropic(brdf: &dyn Brdf) -> bool {
    let n = brdf.channels().len();
    let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
    (0..48).all(|k| {
        let t = |x: f64| (x * 0.618_033_988_75).fract();
        let (ti, to) = (t(k as f64 + 0.3) * 1.4, t(k as f64 * 1.7 + 0.1) * 1.4);
        let (pi, po) = (
            t(k as f64 * 2.3) * 2.0 * PI,
            t(k as f64 * 3.1 + 0.5) * 2.0 * PI,
        );
        let rot = t(k as f64 * 5.7 + 0.2) * 2.0 * PI;
        brdf.eval(Dir::from_angles(ti, pi), Dir::from_angles(to, po), &mut a);
        brdf.eval(
            Dir::from_angles(ti, pi + rot),
            Dir::from_angles(to, po + rot),
            &mut b,
        );
        a.iter()
            .zip(&b)
            .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(y.abs()).max(1e-300))
    })
}

/// Quadrature nodes over the unit square for integrals over the hemisphere of m:
/// midpoints of a `n × n` grid, each with its solid angle.
fn quadrature(n: usize) -> Vec<([f64; 2], Vec3, f64)> {
    let h = 1.0 / n as f64;
    (0..n * n)
        .map(|k| {
            let u = [((k % n) as f64 + 0.5) * h, ((k / n) as f64 + 0.5) * h];
            let (t, p) = (u2theta(u[0]), u2phi(u[1]));
            (u, spherical(t, p), 2.0 * PI * PI * u[0] * t.sin() * h * h)
        })
        .collect()
}

/// σ(ω) = ∫ D(m) ⟨ω · m⟩ dm on the NDF's grid (φ-independent when isotropic).
fn projected_area(ndf: &Warp2D, nt: usize, np: usize, isotropic: bool) -> Vec<f32> {
    let q = quadrature(192);
    let dq: Vec<f64> = q.iter().map(|(u, _, w)| ndf.eval(*u, &[]) * w).collect();
    let sig = |k: usize| -> f64 {
        let (i, j) = (k / nt, k % nt);
        let phi = if isotropic {
            0.0
        } else {
            u2phi(i as f64 / (np - 1) as f64)
        };
        let w = spherical(u2theta(j as f64 / (nt - 1) as f64), phi);
        q.iter()
            .zip(&dq)
            .map(|((_, m, _), d)| d * dot(w, *m).max(0.0))
            .sum()
    };
    if isotropic {
        let row: Vec<f64> = (0..nt).into_par_iter().map(sig).collect();
        (0..np * nt).map(|k| row[k % nt] as f32).collect()
    } else {
        (0..np * nt)
            .into_par_iter()
            .map(|k| sig(k) as f32)
            .collect()
    }
}

/// The NDF on the `np × nt` grid from the retro-reflection `retro` there:
/// D ∝ f(ω, ω) σ(ω)², iterated, normalised to ∫ D cos θ = 1, mixed with 5% of 1/π.
fn ndf_from_retro(retro: &[f64], nt: usize, np: usize, isotropic: bool) -> Vec<f32> {
    let q = quadrature(192);
    let normalise = |d: &mut Vec<f32>| {
        let w = Warp2D::new(d, nt, np, vec![], false, false);
        let total: f64 = w.map_or(0.0, |w| {
            q.iter().map(|(u, m, dw)| w.eval(*u, &[]) * m.z * dw).sum()
        });
        if total > 0.0 && total.is_finite() {
            d.iter_mut().for_each(|x| *x = (*x as f64 / total) as f32);
            true
        } else {
            false
        }
    };
    let top = retro.iter().fold(0f64, |a, b| a.max(*b));
    let mut d: Vec<f32> = retro.iter().map(|r| (r.max(top * 1e-6)) as f32).collect();
    if !normalise(&mut d) {
        return vec![(1.0 / PI) as f32; np * nt];
    }
    for _ in 0..6 {
        let Ok(w) = Warp2D::new(&d, nt, np, vec![], false, false) else {
            break;
        };
        let sigma = projected_area(&w, nt, np, isotropic);
        let mut next: Vec<f32> = retro
            .iter()
            .zip(&sigma)
            .map(|(r, s)| (r.max(top * 1e-6) * (*s as f64).powi(2)) as f32)
            .collect();
        if !normalise(&mut next) {
            break;
        }
        d = next;
    }
    d.iter()
        .map(|x| (0.95 * *x as f64 + 0.05 / PI) as f32)
        .collect()
}

impl Brdf for RglBsdf {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    /// The plugin's value ([`RglBsdf::eval_cos`]) divided by cos θo.
    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        self.eval_cos(wi, wo, out);
        let c = wo.cos_theta();
        if c > 0.0 {
            out.iter_mut().for_each(|o| *o /= c);
        }
    }

    /// Cosine-weighted about the normal, as for any measured table.
    fn proposals(&self, _wi: Dir, out: &mut Vec<Weighted>) {
        out.push(Weighted::COSINE);
    }

    fn is_reciprocal(&self) -> bool {
        false
    }
}
