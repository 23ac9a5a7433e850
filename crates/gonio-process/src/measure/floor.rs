//! The floor of each of DeYoung's measures: what a BRDF that has the property exactly
//! would read under the same sampling and the same noise. A measure is 0 only for a
//! table that has the property at its nodes; measured data read more from their noise,
//! and a table whose reciprocal or isotropic partners fall between nodes reads more
//! from the interpolation that fetches them. A measure is worth reporting against its
//! floor: "P_r 3.2e-3 (floor 3.1e-3, 95% 4.2e-3)" says the material is as reciprocal
//! as this table can tell.
//!
//! **The counterpart.** For each measure, the data's counterpart that has the
//! property, formed from the data alone:
//! - P_r (DeYoung Eq. 4.1): each node's value averaged with its reciprocal value,
//!   (f(ωi, ωo) + f(ωo, ωi))/2, fetched as the measure fetches it (looked up on a
//!   paired grid, interpolated quadrilinearly otherwise). This is the tabulation of
//!   the exactly reciprocal function sym(F), F the data's interpolant.
//! - P_i (Eq. 4.10): the φi-average μ_i of Eq. 4.8, tabulated back on the table's
//!   nodes (looked up when the azimuth axes agree, interpolated otherwise).
//! - P_ec (Eq. 4.5): every incidence's values scaled by min(1, τ/ρ), so that no
//!   albedo exceeds τ under the same rule.
//! - P_s^(k) (Eq. 4.20): A^(k) of Eq. 4.19, exactly k-separable.
//!
//! **Interpolation.** On a paired grid (and for P_i on equal azimuth axes) the
//! counterpart has the property exactly at the nodes and reads 0. Where partners are
//! interpolated it does not: its interpolation error is the floor's first part. But
//! averaging with interpolated values smooths the counterpart, and its interpolation
//! error is smaller than the data's (by 0.6 to 0.8 on the plan's own grid for
//! reciprocal materials, whose P_r is interpolation alone). So the counterpart is
//! formed three times over, S v, S²v, S³v, each reading less by about the same
//! factor, and its measures M₁, M₂, M₃ are extrapolated back to no averaging, log M
//! quadratic in the number of averagings: M₀ = M₁³ M₃ / M₂³ (at least M₁, at most
//! 4 M₁). This extrapolation is a model, not a measurement: its whole step M₀ − M₁
//! is taken as its standard uncertainty ([`Floor::interpolation_sigma`]). On the
//! plan's own grid it recovers 0.93–0.99 of a reciprocal material's P_r.
//!
//! **Noise.** With the data's σ, K draws (seeded: [`SEED`]; the same numbers on any
//! number of threads) each add Gaussian noise of the data's σ to the counterpart,
//! whose interpolation error is scaled to a draw of N(M₀, (M₀ − M₁)²), and pass it
//! through the very measure code the data went through. The floor is the draws'
//! mean and their 95th percentile (nearest rank); a measure above the percentile
//! exceeds its floor. Without σ (a model file, another tool's table) the floor is
//! the interpolation alone: M₀, and M₀ + 1.645 (M₀ − M₁) as its 95% bound.
//! P_ec's counterpart has no interpolation part: its floor is the noise's (the
//! discretisation's bias is in the albedos' quadrature σ instead), and 0 without
//! drawing when every albedo lies more than 8 of its noise σ below τ; P_s^(k)'s is
//! the noise's too.
//!
//! **Cost.** A draw costs a pass of each measure. K is [`DRAW_BUDGET`] over the
//! table's node-values (nodes × channels), at most [`MAX_DRAWS`] (tables of up to
//! 131 072 node-values: a run's own grid, a 10° 4D table), never fewer
//! than [`MIN_DRAWS`] (a 5° 4D table gets 4; its measures average over 1.7 million
//! nodes, and their draws scatter little). P_s^(k)'s floor needs a full SVD per draw and k, so it
//! is formed only when A has fewer than [`crate::svd::MIN_TRUNCATED`] rows or
//! columns, with at most [`MAX_SVD_DRAWS`] draws.
//!
//! **Memory.** The floors work channel by channel and form no counterpart of the
//! whole table's size: on a paired grid P_r's counterparts (once, twice, three times
//! over) are read where the measure reads them, and on equal azimuth axes P_i's are
//! lookups in μ_i, itself the size of one incident azimuth's table; elsewhere one
//! channel's counterpart is formed. A draw's noise is drawn from its place in the
//! draw's one stream (SplitMix64's state is a counter), so a draw forms at most one
//! channel's values (P_ec's none), the numbers are those of the stream drawn whole,
//! and the four floors run side by side.

use gonio_core::Channels;
use gonio_core::rng::{GOLDEN_GAMMA, SplitMix64, splitmix64};
use rayon::prelude::*;
use serde::Serialize;

use crate::grid::interpolate;
use crate::measure::{self, EnergyMethod, Reciprocals, Report};
use crate::{ProcessError, Samples, Table, hemisphere};

/// The seed of the floors' noise draws.
pub const SEED: u64 = 0x676f_6e69_6f66_6c72;

/// The most noise draws a floor takes. The floor's mean from K draws errs by
/// 1/√K of the draws' spread, and every comparison with the floor shares that error:
/// with 32 draws a table that has the property exceeded the 95% bound in 3.5–10.5%
/// of 200 noise seeds (P_i on a 4D grid, the four test materials), with 400 in
/// 5–7%; 64 keeps that error to an eighth of the spread at a fraction of the cost.
pub const MAX_DRAWS: usize = 64;

/// The fewest noise draws a floor takes when the data carry σ.
pub const MIN_DRAWS: usize = 4;

/// Node-values (nodes × channels × draws) the draws of one measure may cost.
pub const DRAW_BUDGET: usize = 1 << 23;

/// The most noise draws of P_s^(k)'s floor (each a full SVD per k and channel): the
/// most expensive of the floors, and the narrowest (its noise adds to A's whole
/// tail), so fewer draws suffice.
pub const MAX_SVD_DRAWS: usize = 16;

/// The standard normal quantile of 0.95.
const Z95: f64 = 1.644_853_626_951_472_2;

/// A measure's floor for one channel.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Floor {
    /// The counterpart's measure, mean over the draws (without noise, the
    /// interpolation estimate M₀).
    pub mean: f64,
    /// Its 95th percentile over the draws (without noise, M₀ + 1.645 σ of M₀).
    pub p95: f64,
    /// Whether the data's measure lies at or below `p95`.
    pub consistent: bool,
    /// The interpolation part M₀, extrapolated (module docs); 0 when partners are
    /// looked up.
    pub interpolation: f64,
    /// The standard uncertainty of `interpolation`: the extrapolation's step M₀ − M₁.
    pub interpolation_sigma: f64,
}

/// The floors of a report's measures (module docs).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Floors {
    /// Noise draws per measure: 0 when the data carry no σ (the floors are then the
    /// interpolation alone).
    pub draws: usize,
    /// The seed of the draws.
    pub seed: u64,
    /// P_r's floor per channel.
    pub reciprocity: Vec<Floor>,
    /// P_ec's floor per channel.
    pub energy: Vec<Floor>,
    /// P_i's floor per channel; none for a table in the isotropic form.
    pub isotropy: Option<Vec<Floor>>,
    /// P_s^(k)'s floor per channel, as (k, floor) in the report's order; none when
    /// A is too large for a full SVD a draw, or P_s was not measured.
    pub separability: Option<Vec<KFloors>>,
}

/// One channel's P_s^(k) floors, as (k, floor).
pub type KFloors = Vec<(usize, Floor)>;

/// The noise draws a table of `values` node-values with σ gets.
pub fn draws_for(values: usize) -> usize {
    (DRAW_BUDGET / values.max(1)).clamp(MIN_DRAWS, MAX_DRAWS)
}

/// The seed of draw `k`'s stream.
fn draw_seed(k: usize, stream: u64) -> u64 {
    splitmix64(
        SEED ^ stream.wrapping_mul(GOLDEN_GAMMA)
            ^ (k as u64 + 1).wrapping_mul(0x2545_f491_4f6c_dd1d),
    )
}

/// The generator of draw `k`.
fn rng(k: usize, stream: u64) -> SplitMix64 {
    SplitMix64::new(draw_seed(k, stream))
}

/// The generator of draw `k` positioned after its first `normals` normal numbers:
/// SplitMix64's state is a counter, advanced by [`GOLDEN_GAMMA`] a word, and a normal
/// takes two words, so any part of a draw's noise is drawn on its own, the very
/// numbers of the one stream (a block, a node, on any thread).
fn rng_at(k: usize, stream: u64, normals: usize) -> SplitMix64 {
    let words = (2 * normals as u64).wrapping_mul(GOLDEN_GAMMA);
    SplitMix64::new(draw_seed(k, stream).wrapping_add(words))
}

/// The draws' mean and 95th percentile, the latter as a normal distribution's with
/// the draws' mean and standard deviation: of a few dozen draws it is far steadier
/// than the nearest rank (the 31st of 32 draws scatters by half a standard deviation
/// between seeds, the normal quantile by a quarter), and the measures' draws are
/// sums over many nodes, near normal.
fn mean_p95(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, mean);
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, mean + Z95 * var.sqrt())
}

/// Whether `value` lies at or below `bound`, up to rounding of values of size `scale`.
fn at_most(value: f64, bound: f64, scale: f64) -> bool {
    value <= bound * (1.0 + 1e-9) + 1e-12 * scale
}

/// The interpolation part of a floor from the measures of the counterpart formed
/// once, twice and three times (module docs): (M₀, its σ). `tiny` is the size below
/// which a measure is rounding.
fn extrapolate(m1: f64, m2: f64, m3: f64, tiny: f64) -> (f64, f64) {
    if m1 <= tiny {
        return (m1.max(0.0), 0.0);
    }
    if !(m2 > 0.0 && m3 > 0.0 && m2 < m1 && m3 < m2) {
        // Averaging does not shrink it: no trend to extrapolate, M₁ ± M₁.
        return (m1, m1);
    }
    let m0 = (3.0 * m1.ln() - 3.0 * m2.ln() + m3.ln())
        .exp()
        .clamp(m1, 4.0 * m1);
    (m0, m0 - m1)
}

/// The largest magnitude of a table's values: the scale of rounding.
fn scale_of(values: &[f64]) -> f64 {
    values.iter().fold(0.0, |a, v| a.max(v.abs()))
}

/// A draw of the counterpart `c` (interpolation scaled per channel by `gain`) with
/// noise of σ `sigma` from `g`.
fn noisy(c: &Table, gain: &[f64], sigma: &[f64], g: &mut SplitMix64) -> Table {
    let n = c.grid.len();
    let values = c
        .values
        .iter()
        .zip(sigma)
        .enumerate()
        .map(|(i, (v, s))| gain[i / n] * v + s * g.next_normal())
        .collect();
    c.with_values(values, None)
}

/// What the interpolated floors (P_r's, P_i's) share: the table's σ, the draws and
/// the size of rounding.
struct Interpolated<'a> {
    t: &'a Table,
    draws: usize,
    stream: u64,
    scale: f64,
}

impl Interpolated<'_> {
    /// Channel `ch`'s floor for the data's measure `value`, from its counterpart's
    /// measures formed once, twice and three times `m` (module docs) and, when the
    /// data carry σ, `draw(k, gain, σ)`: the measure of draw `k` of the counterpart
    /// formed once, its interpolation scaled by `gain`, with the noise of σ (the
    /// channel's part of the draw's stream, [`Interpolated::noise_start`]).
    fn channel(
        &self,
        ch: usize,
        value: f64,
        m: [f64; 3],
        draw: impl Fn(usize, f64, &[f64]) -> f64 + Sync,
    ) -> Floor {
        let tiny = 1e-12 * self.scale;
        let (m0, sd) = extrapolate(m[0], m[1], m[2], tiny);
        let sigma = self.t.channel_sigma(ch).filter(|_| self.draws > 0);
        let Some(sig) = sigma else {
            let p = m0 + Z95 * sd;
            return Floor {
                mean: m0,
                p95: p,
                consistent: at_most(value, p, self.scale),
                interpolation: m0,
                interpolation_sigma: sd,
            };
        };
        let runs: Vec<f64> = (0..self.draws)
            .into_par_iter()
            .map(|k| {
                // A draw's stream: one normal a channel for the gains, then the noise
                // of every value in the table's order.
                let z = rng_at(k, self.stream, ch).next_normal();
                let gain = if m[0] > tiny {
                    (m0 + sd * z).max(0.0) / m[0]
                } else {
                    1.0
                };
                draw(k, gain, sig)
            })
            .collect();
        let (mean, p) = mean_p95(&runs);
        Floor {
            mean,
            p95: p,
            consistent: at_most(value, p, self.scale),
            interpolation: m0,
            interpolation_sigma: sd,
        }
    }

    /// Where channel `ch`'s noise starts in a draw's stream, in normals.
    fn noise_start(&self, ch: usize) -> usize {
        self.t.channels.len() + ch * self.t.grid.len()
    }

    /// Draw `k` of channel `ch`'s counterpart whose value at node i is `base(i)`,
    /// scaled by `gain`, with noise of σ `sig`: one channel's values, formed in order.
    fn formed(
        &self,
        k: usize,
        ch: usize,
        gain: f64,
        sig: &[f64],
        base: impl Fn(usize) -> f64,
    ) -> Vec<f64> {
        let mut g = rng_at(k, self.stream, self.noise_start(ch));
        (0..self.t.grid.len())
            .map(|i| gain * base(i) + sig[i] * g.next_normal())
            .collect()
    }
}

/// P_r's counterpart: each node averaged with its reciprocal value where that lies
/// in the table (module docs).
pub fn reciprocal_counterpart(t: &Table) -> Table {
    let g = &t.grid;
    let n = g.len();
    let rec = Reciprocals::new(g);
    let mut values = t.values.clone();
    // Each node on its own: the same numbers on any number of threads.
    values
        .par_chunks_mut(n.max(1))
        .enumerate()
        .for_each(|(ch, out)| {
            let v = t.channel(ch);
            out.par_iter_mut().enumerate().for_each(|(i, x)| {
                if let Some(r) = rec.value(g, v, i) {
                    *x = 0.5 * (v[i] + r);
                }
            });
        });
    t.with_values(values, t.sigma.clone())
}

/// P_i's counterpart: the φi-average μ_i (Eq. 4.8) tabulated back on the table's
/// nodes (module docs). A table in the isotropic form is its own.
pub fn isotropic_counterpart(t: &Table) -> Result<Table, ProcessError> {
    if t.grid.isotropic {
        return Ok(t.clone());
    }
    let (mu, _) = measure::isotropic_mean(t, false)?;
    let g = &t.grid;
    let n = g.len();
    let mut values = vec![0.0; t.values.len()];
    // Both azimuth axes the same full turn: φo − φi is node (c − a) mod n of μ_i's
    // φ+ axis (`isotropic_mean` builds it so), a lookup rather than an interpolation
    // (a tenth of `gonio check`'s time on a 5° × 2.5° table).
    let same_phi = g.phi_i.same_as(&g.phi_o) && g.phi_o.is_periodic();
    let np = g.phi_o.n;
    // Each node on its own: the same numbers on any number of threads.
    values
        .par_chunks_mut(n.max(1))
        .enumerate()
        .for_each(|(ch, out)| {
            let m = mu.channel(ch);
            out.par_iter_mut().enumerate().for_each(|(i, v)| {
                *v = if same_phi {
                    let [a, b, c, d] = g.unindex(i);
                    m[mu.grid.index(0, b, (c + np - a) % np, d)]
                } else {
                    mu.eval_angles(ch, g.angles(i))
                }
            });
        });
    Ok(t.with_values(values, t.sigma.clone()))
}

/// The floors of `report`'s measures of `t` (and of the `measured` samples its energy
/// measure integrated, when given), with `draws` noise draws when the data carry σ
/// ([`draws_for`] is what [`measure::report_with`] gives).
pub fn floors(
    t: &Table,
    measured: Option<&Samples>,
    report: &Report,
    ks: &[usize],
    draws: usize,
) -> Result<Floors, ProcessError> {
    let draws = if t.sigma.is_some() { draws } else { 0 };
    // The four floors are independent: formed side by side, each the same numbers
    // on any number of threads.
    let (three, separability) = rayon::join(
        || {
            three_floors(
                t,
                measured,
                &report.reciprocity,
                &report.energy,
                &report.isotropy,
                draws,
            )
        },
        || separability_floor(t, report.separability.as_deref(), ks, draws),
    );
    assemble(draws, three, separability)
}

/// The floors of P_r, P_ec and P_i (each the same numbers on any number of
/// threads), side by side, given their measures.
pub(crate) type Three = (
    Result<Vec<Floor>, ProcessError>,
    Result<Vec<Floor>, ProcessError>,
    Result<Option<Vec<Floor>>, ProcessError>,
);

/// [`floors`]' floors of P_r, P_ec and P_i, side by side, from the measures
/// `reciprocity`, `energy` and `isotropy`; `draws` is 0 without σ.
pub(crate) fn three_floors(
    t: &Table,
    measured: Option<&Samples>,
    reciprocity: &[f64],
    energy: &measure::Energy,
    isotropy: &[f64],
    draws: usize,
) -> Three {
    // No floor forms a counterpart table of the whole table's size (each forms at
    // most one channel's values a draw in flight), so all run side by side.
    let ((reciprocity, isotropy), energy) = rayon::join(
        || {
            rayon::join(
                || reciprocity_floor(t, reciprocity, draws),
                || {
                    if t.grid.isotropic {
                        Ok(None)
                    } else {
                        isotropy_floor(t, isotropy, draws).map(Some)
                    }
                },
            )
        },
        || energy_floor(t, measured, energy, draws),
    );
    (reciprocity, energy, isotropy)
}

/// The four floors as one, the first error (P_r, P_ec, P_i, P_s) if any.
pub(crate) fn assemble(
    draws: usize,
    (reciprocity, energy, isotropy): Three,
    separability: Result<Option<Vec<KFloors>>, ProcessError>,
) -> Result<Floors, ProcessError> {
    Ok(Floors {
        draws,
        seed: SEED,
        reciprocity: reciprocity?,
        energy: energy?,
        isotropy: isotropy?,
        separability: separability?,
    })
}

/// P_r's floor per channel for a table whose P_r is `value` (module docs), with
/// `draws` noise draws when the table carries σ (0: the interpolation alone).
///
/// Channel by channel. On a paired grid the counterpart formed once, twice and three
/// times over is read where the measure reads it (two, four, eight lookups a value),
/// never stored; else each is formed for one channel. A noise draw forms one
/// channel's values at a time.
pub fn reciprocity_floor(
    t: &Table,
    value: &[f64],
    draws: usize,
) -> Result<Vec<Floor>, ProcessError> {
    let g = &t.grid;
    let n = g.len();
    let rec = Reciprocals::new(g);
    let ctx = Interpolated {
        t,
        draws,
        stream: 1,
        scale: scale_of(&t.values),
    };
    let measure = |x: &(dyn Fn(usize) -> f64 + Sync)| measure::reciprocity_by(g, &rec, x).0;
    let floors = (0..t.channels.len())
        .map(|ch| {
            let v = t.channel(ch);
            let draw_of = |k: usize, gain: f64, sig: &[f64], s1: &(dyn Fn(usize) -> f64 + Sync)| {
                let x = ctx.formed(k, ch, gain, sig, s1);
                measure(&|i| x[i])
            };
            match rec.map() {
                Some(m) => {
                    // (f + f∘r)/2, as `reciprocal_counterpart` forms it.
                    let s1 = |i: usize| 0.5 * (v[i] + v[m[i]]);
                    let s2 = |i: usize| 0.5 * (s1(i) + s1(m[i]));
                    let s3 = |i: usize| 0.5 * (s2(i) + s2(m[i]));
                    let levels = [measure(&s1), measure(&s2), measure(&s3)];
                    ctx.channel(ch, value[ch], levels, |k, gain, sig| {
                        draw_of(k, gain, sig, &s1)
                    })
                }
                None => {
                    let sym = |x: &[f64]| -> Vec<f64> {
                        (0..n)
                            .into_par_iter()
                            .map(|i| match rec.value(g, x, i) {
                                Some(r) => 0.5 * (x[i] + r),
                                None => x[i],
                            })
                            .collect()
                    };
                    let s1 = sym(v);
                    let m1 = measure(&|i| s1[i]);
                    let (m2, m3) = {
                        let s2 = sym(&s1);
                        let s3 = sym(&s2);
                        (measure(&|i| s2[i]), measure(&|i| s3[i]))
                    };
                    ctx.channel(ch, value[ch], [m1, m2, m3], |k, gain, sig| {
                        draw_of(k, gain, sig, &|i| s1[i])
                    })
                }
            }
        })
        .collect();
    Ok(floors)
}

/// P_i's floor per channel for a 4D table whose P_i is `value` (module docs), with
/// `draws` noise draws when the table carries σ (0: the interpolation alone).
///
/// Channel by channel. Where both azimuth axes are the same full turn the
/// counterpart is a lookup in μ_i, formed and measured through μ_i alone (a table
/// the size of one incident azimuth's), its noise draws node by node from their
/// place in the stream; else each counterpart is formed for one channel.
pub fn isotropy_floor(t: &Table, value: &[f64], draws: usize) -> Result<Vec<Floor>, ProcessError> {
    let g = &t.grid;
    let n = g.len();
    let scale = scale_of(&t.values);
    if g.isotropic {
        // Its own counterpart: every measure 0.
        return Ok(value
            .iter()
            .map(|v| Floor {
                mean: 0.0,
                p95: 0.0,
                consistent: at_most(*v, 0.0, scale),
                interpolation: 0.0,
                interpolation_sigma: 0.0,
            })
            .collect());
    }
    let ctx = Interpolated {
        t,
        draws,
        stream: 2,
        scale,
    };
    let mg = measure::mean_grid(g);
    let same_phi = g.phi_i.same_as(&g.phi_o) && g.phi_o.is_periodic();
    let np = g.phi_o.n;
    // The node of μ_i at node k: φo − φi is node (c − a) mod n of μ_i's φ+ axis
    // (`isotropic_counterpart`).
    let at = |k: usize| {
        let [a, b, c, d] = g.unindex(k);
        mg.index(0, b, (c + np - a) % np, d)
    };
    let floors = (0..t.channels.len())
        .map(|ch| {
            let v = t.channel(ch);
            let (mu1, _) = measure::isotropy_by(g, |k| v[k]);
            if same_phi {
                let (mu2, m1) = measure::isotropy_by(g, |k| mu1[at(k)]);
                let (mu3, m2) = measure::isotropy_by(g, |k| mu2[at(k)]);
                let (_, m3) = measure::isotropy_by(g, |k| mu3[at(k)]);
                let start = ctx.noise_start(ch);
                ctx.channel(ch, value[ch], [m1, m2, m3], |k, gain, sig| {
                    // Each node is read once: its noise drawn where it lies in the stream.
                    let x = |i: usize| {
                        gain * mu1[at(i)] + sig[i] * rng_at(k, ctx.stream, start + i).next_normal()
                    };
                    measure::isotropy_by(g, x).1
                })
            } else {
                let eval = |mu: &[f64]| -> Vec<f64> {
                    (0..n)
                        .into_par_iter()
                        .map(|i| interpolate(&mg, mu, g.angles(i)))
                        .collect()
                };
                let s1 = eval(&mu1);
                let (mu2, m1) = measure::isotropy_by(g, |k| s1[k]);
                let (m2, m3) = {
                    let s2 = eval(&mu2);
                    let (mu3, m2) = measure::isotropy_by(g, |k| s2[k]);
                    drop(s2);
                    let s3 = eval(&mu3);
                    (m2, measure::isotropy_by(g, |k| s3[k]).1)
                };
                ctx.channel(ch, value[ch], [m1, m2, m3], |k, gain, sig| {
                    let x = ctx.formed(k, ch, gain, sig, |i| s1[i]);
                    measure::isotropy_by(g, |i| x[i]).1
                })
            }
        })
        .collect();
    Ok(floors)
}

/// P_ec of albedos `[channel][row]` at τ.
fn p_ec(albedo: &[Vec<f64>], tau: f64) -> Vec<f64> {
    albedo
        .iter()
        .map(|a| a.iter().map(|x| (x - tau).max(0.0)).sum::<f64>() / a.len().max(1) as f64)
        .collect()
}

/// P_ec's floor: the values of every incidence whose albedo exceeds τ scaled down to
/// it, then the data's noise, through the same albedo rule (module docs).
fn energy_floor(
    t: &Table,
    measured: Option<&Samples>,
    e: &measure::Energy,
    draws: usize,
) -> Result<Vec<Floor>, ProcessError> {
    const TAU: f64 = 1.0;
    let nc = t.channels.len();
    let factor = |ch: usize, row: usize| {
        let a = e.albedo[ch][row];
        if a > TAU { TAU / a } else { 1.0 }
    };
    // An incidence whose albedo lies more than 8 of its noise σ below τ adds nothing
    // to any draw (a chance of 1e-15): when all do, the floor is 0 without drawing.
    if let Some(sig) = &e.albedo_sigma
        && e.albedo
            .iter()
            .zip(sig)
            .all(|(a, s)| a.iter().zip(s).all(|(a, s)| a + 8.0 * s < TAU))
    {
        return Ok((0..nc)
            .map(|ch| Floor {
                mean: 0.0,
                p95: 0.0,
                consistent: e.p_ec[ch] <= 0.0,
                interpolation: 0.0,
                interpolation_sigma: 0.0,
            })
            .collect());
    }
    let scale;
    let runs: Vec<Vec<f64>> = match measured {
        Some(s) => {
            // Rows of the report are the samples' incidences, in key order.
            let keys: Vec<(i64, i64)> = e
                .incident
                .iter()
                .map(|(ti, pi)| {
                    hemisphere::incidence_key(
                        s.isotropic,
                        &gonio_core::dirfile::PairDeg {
                            incident: gonio_core::SphericalDeg::new(*ti, *pi),
                            outgoing: gonio_core::SphericalDeg::new(0.0, 0.0),
                        },
                    )
                })
                .collect();
            let mut c = s.clone();
            for x in &mut c.samples {
                let key = hemisphere::incidence_key(s.isotropic, &x.pair);
                if let Some(row) = keys.iter().position(|k| *k == key) {
                    for (ch, v) in x.value.iter_mut().enumerate() {
                        *v *= factor(ch, row);
                    }
                }
            }
            scale = c
                .samples
                .iter()
                .flat_map(|x| x.value.iter())
                .fold(0.0f64, |a, v| a.max(v.abs()));
            let with_sigma = c.samples.iter().all(|x| x.sigma.is_some());
            let run = |k: Option<usize>| -> Result<Vec<f64>, ProcessError> {
                let mut d = c.clone();
                if let Some(k) = k {
                    let mut g = rng(k, 3);
                    for x in &mut d.samples {
                        let sig = x.sigma.clone().unwrap_or_default();
                        for (v, s) in x.value.iter_mut().zip(&sig) {
                            *v += s * g.next_normal();
                        }
                    }
                }
                let rows = hemisphere::albedos_with(&d, false)?;
                let a: Vec<Vec<f64>> = (0..nc)
                    .map(|ch| rows.iter().map(|r| r.albedo[ch]).collect())
                    .collect();
                Ok(p_ec(&a, TAU))
            };
            if with_sigma && draws > 0 {
                (0..draws)
                    .into_par_iter()
                    .map(|k| run(Some(k)))
                    .collect::<Result<_, _>>()?
            } else {
                vec![run(None)?]
            }
        }
        None if e.method == EnergyMethod::Sum => {
            let g = &t.grid;
            let (n, p, q) = (g.len(), g.n_in(), g.n_out());
            let w = measure::out_weights(g);
            scale = (0..nc)
                .into_par_iter()
                .map(|ch| {
                    let v = t.channel(ch);
                    (0..p)
                        .map(|row| {
                            let f = factor(ch, row);
                            v[row * q..(row + 1) * q]
                                .iter()
                                .fold(0.0f64, |a, x| a.max((x * f).abs()))
                        })
                        .fold(0.0f64, f64::max)
                })
                .reduce(|| 0.0, f64::max);
            // Row `row`'s albedo of the scaled values, with draw `k`'s noise: each
            // row on its own, its noise drawn from its place in the stream (the
            // values' order), so no table of the draw is formed.
            let albedo = |ch: usize, row: usize, k: Option<usize>| -> f64 {
                let f = factor(ch, row);
                let at = row * q..(row + 1) * q;
                let v = &t.channel(ch)[at.clone()];
                match (k, &t.sigma) {
                    (Some(k), Some(sig)) => {
                        let s = &sig[ch * n..(ch + 1) * n][at];
                        let mut g = rng_at(k, 3, ch * n + row * q);
                        v.iter()
                            .zip(s)
                            .zip(&w)
                            .map(|((x, s), w)| (x * f + s * g.next_normal()) * w)
                            .sum()
                    }
                    _ => v.iter().zip(&w).map(|(x, w)| (x * f) * w).sum(),
                }
            };
            let run = |k: Option<usize>| -> Vec<f64> {
                let a: Vec<Vec<f64>> = (0..nc)
                    .map(|ch| {
                        (0..p)
                            .into_par_iter()
                            .map(|row| albedo(ch, row, k))
                            .collect()
                    })
                    .collect();
                p_ec(&a, TAU)
            };
            if t.sigma.is_some() && draws > 0 {
                (0..draws).into_par_iter().map(|k| run(Some(k))).collect()
            } else {
                vec![run(None)]
            }
        }
        None => {
            let (n, q) = (t.grid.len(), t.grid.n_out());
            let mut c = t.clone();
            for ch in 0..nc {
                for row in 0..t.grid.n_in() {
                    let f = factor(ch, row);
                    for v in &mut c.values[ch * n + row * q..ch * n + (row + 1) * q] {
                        *v *= f;
                    }
                }
            }
            scale = scale_of(&c.values);
            let run = |k: Option<usize>| -> Result<Vec<f64>, ProcessError> {
                let d = match (k, &c.sigma) {
                    (Some(k), Some(sig)) => {
                        let mut g = rng(k, 3);
                        noisy(&c, &vec![1.0; nc], sig, &mut g)
                    }
                    _ => c.clone(),
                };
                let rows = hemisphere::albedos_of_table_with(&d, false)?;
                let a: Vec<Vec<f64>> = (0..nc)
                    .map(|ch| rows.iter().map(|r| r.albedo[ch]).collect())
                    .collect();
                Ok(p_ec(&a, TAU))
            };
            if c.sigma.is_some() && draws > 0 {
                (0..draws)
                    .into_par_iter()
                    .map(|k| run(Some(k)))
                    .collect::<Result<_, _>>()?
            } else {
                vec![run(None)?]
            }
        }
    };
    Ok((0..nc)
        .map(|ch| {
            let v: Vec<f64> = runs.iter().map(|r| r[ch]).collect();
            let (mean, p) = mean_p95(&v);
            Floor {
                mean,
                p95: p,
                consistent: at_most(e.p_ec[ch], p, scale),
                interpolation: 0.0,
                interpolation_sigma: 0.0,
            }
        })
        .collect())
}

/// P_s^(k)'s floor: A^(k) (Eq. 4.19) of the table's 4D form plus the data's noise
/// (drawn on the table's own nodes, then expanded as the table is), through the same
/// measure; none when A is too large for a full SVD a draw, or P_s (`sep`) was not
/// measured. `draws` is 0 without σ, and at most [`MAX_SVD_DRAWS`] are drawn.
pub(crate) fn separability_floor(
    t: &Table,
    sep: Option<&[measure::Separability]>,
    ks: &[usize],
    draws: usize,
) -> Result<Option<Vec<KFloors>>, ProcessError> {
    let Some(sep) = sep else {
        return Ok(None);
    };
    let draws = draws.min(MAX_SVD_DRAWS);
    // A's shape in the 4D form, before that form is made (a copy of the table).
    let g = &t.grid;
    let (p, q) = if g.isotropic {
        (g.phi_o.n * g.theta_i.n, g.phi_o.n * g.theta_o.n)
    } else {
        (g.n_in(), g.n_out())
    };
    if p.min(q) >= crate::svd::MIN_TRUNCATED {
        return Ok(None);
    }
    let full = measure::full_form(t)?;
    let nc = t.channels.len();
    let n = full.grid.len();
    let mut out = Vec::with_capacity(nc);
    for (ch, measured) in sep.iter().enumerate().take(nc) {
        let a = measure::matrix(&full, ch);
        let (s, u, v) = crate::svd::thin(a.as_ref())?;
        let scale = scale_of(full.channel(ch));
        let mut per_k = Vec::with_capacity(ks.len());
        for (j, &k) in ks.iter().enumerate() {
            let k = k.min(s.len());
            // A^(k) in the table's value order: rows (φi, θi), columns (φo, θo).
            let mut ak = vec![0.0; n];
            // Each value on its own: rows on rayon, the same bits.
            ak.par_chunks_mut(q).enumerate().for_each(|(r, row)| {
                for (c, x) in row.iter_mut().enumerate() {
                    *x = (0..k).map(|m| u[(r, m)] * s[m] * v[(c, m)]).sum();
                }
            });
            let counterpart = Table::new(Channels::Single, full.grid, ak, None)?;
            let measure_of = |x: &Table| -> Result<f64, ProcessError> {
                Ok(measure::separability(x, &[k])?[0].p_s[0].1)
            };
            let sigma = t.channel_sigma(ch).filter(|_| draws > 0);
            let runs: Vec<f64> = match sigma {
                Some(sig) => (0..draws)
                    .into_par_iter()
                    .map(|d| {
                        let mut g = rng(d, 4 + ch as u64);
                        // Noise on the table's own nodes, expanded as the table is.
                        let own = Table::new(
                            Channels::Single,
                            t.grid,
                            sig.iter().map(|s| s * g.next_normal()).collect(),
                            None,
                        )?;
                        let noise = measure::full_form(&own)?;
                        let values = counterpart
                            .values
                            .iter()
                            .zip(&noise.values)
                            .map(|(a, b)| a + b)
                            .collect();
                        measure_of(&counterpart.with_values(values, None))
                    })
                    .collect::<Result<_, _>>()?,
                None => vec![measure_of(&counterpart)?],
            };
            let (mean, p) = mean_p95(&runs);
            let value = measured.p_s[j].1;
            per_k.push((
                ks[j],
                Floor {
                    mean,
                    p95: p,
                    consistent: at_most(value, p, scale),
                    interpolation: 0.0,
                    interpolation_sigma: 0.0,
                },
            ));
        }
        out.push(per_k);
    }
    Ok(Some(out))
}
