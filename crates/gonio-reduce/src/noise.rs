//! The pooled noise law: the detector's noise per reading, σ of its mean.
//!
//! A reading's own scatter is a poor estimate of its noise (a variance from ten
//! correlated snapshots is uncertain by a third, from two entirely), so the noise
//! is pooled over the run's readings that share a setting ([`NoiseKey`]): their
//! variances are fitted as a + b·R ([`fit_line`]), a line per filter slope for a
//! lock-in (each reading's variance scaled to the slope's first time constant by
//! [`enbw_ratio`]), per range, integration time and sample count for a
//! picoammeter. [`Noise::sigma_mean`] then gives a reading's σ of its mean from the
//! line, the snapshots' correlation entering through [`variance_factors`]; a group
//! with fewer than [`MIN_POOL`] readings keeps each reading's own scatter.

use std::collections::BTreeMap;

use gonio_run::{ReadingRecord, flags};

use crate::{Detector, Options};

/// The variance factors of n snapshots whose noise correlates as ρ^|i−j|:
/// `(A, B)` with Var(mean) = σ² A / n and E\[s²\] = σ² B for the sample variance s²
/// (n − 1 in the denominator). With S = Σ_{k=1}^{n−1} (1 − k/n) ρ^k,
/// A = 1 + 2S and B = 1 − 2S/(n − 1).
pub fn variance_factors(n: u32, rho: f64) -> (f64, f64) {
    if n < 2 {
        return (1.0, 1.0);
    }
    let nf = f64::from(n);
    let s: f64 = (1..n)
        .map(|k| (1.0 - f64::from(k) / nf) * rho.powi(k as i32))
        .sum();
    (1.0 + 2.0 * s, 1.0 - 2.0 * s / (nf - 1.0))
}

/// A noise law pooled over a group of readings: the variance per snapshot (lock-in)
/// or per sample (picoammeter) is a + b·R at the group's reference time constant.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NoiseLine {
    /// The variance at zero signal, V² (A² for a picoammeter).
    pub a: f64,
    /// The variance's growth with the signal, V (A).
    pub b: f64,
    /// The time constant of the group's first reading, s: a lock-in reading at
    /// time constant T has the variance (a + b·R)·[`enbw_ratio`]`(T, t_ref)`.
    pub t_ref: f64,
    /// Whether the readings fitted span more than one time constant.
    pub spans_time_constants: bool,
}

/// The key of readings that share a noise law.
pub(crate) type NoiseKey = (u64, u8, u32);

/// A lock-in's output noise is white noise of density d(R)² (V²/Hz) through its
/// output filter, so a snapshot's variance is d²·ENBW(T, slope): readings of one
/// slope share a law whatever their time constant, and their snapshot count enters
/// only through [`variance_factors`]. The key is the slope alone. A picoammeter's
/// noise depends on its integration time, sample count and range (each range has
/// its own feedback resistor, hence its own noise floor).
fn noise_key(r: &ReadingRecord, detector: Detector) -> NoiseKey {
    match detector {
        Detector::LockIn => (0, r.slope_db, 0),
        Detector::Dc => (r.time_constant_s.to_bits(), r.sensitivity, r.n),
    }
}

/// ENBW(T)/ENBW(t_ref) at one filter slope: t_ref/T, as the SR830's equivalent
/// noise bandwidth is k(slope)/T (`gonio_proto::sr830::FilterSlope::enbw_hz`).
/// Exactly 1.0 when T is t_ref (x/x is exact in IEEE 754, and so are a product and
/// a quotient by 1.0): a run at one time constant pools bit for bit as it did when
/// the key held the time constant. `None` for a time constant that is not finite
/// and positive (such a reading is not pooled with others).
fn enbw_ratio(t: f64, t_ref: f64) -> Option<f64> {
    if t.to_bits() == t_ref.to_bits() {
        Some(1.0)
    } else if t.is_finite() && t > 0.0 && t_ref.is_finite() && t_ref > 0.0 {
        Some(t_ref / t)
    } else {
        None
    }
}

/// The ENBW of a slope at T = 1 s, Hz (the manual's 1/4, 1/8, 3/32, 5/64; SR830
/// manual "Noise Measurements", as `FilterSlope::enbw_hz` states them).
fn enbw_per_second(slope_db: u8) -> Option<f64> {
    let slope = gonio_proto::sr830::FilterSlope::from_db(slope_db)?;
    let tc = gonio_proto::sr830::TimeConstant::all().find(|t| t.seconds() == 1.0)?;
    Some(slope.enbw_hz(tc))
}

/// The readings of one noise key while the noise is fitted.
struct Pool {
    /// The first reading's time constant, s: the line is the variance at it.
    t_ref: f64,
    /// The first reading's snapshot count.
    n_ref: u32,
    /// Whether another time constant was seen.
    spans_time_constants: bool,
    /// Whether every reading took `n_ref` snapshots, at least 3 ([`fit_line`]'s
    /// `own_start`).
    one_count: bool,
    /// (R, variance at `t_ref`, relative degrees of freedom) per reading.
    points: Vec<(f64, f64, f64)>,
}

/// The detector's noise: pooled lines where enough readings share a setting, and
/// the lock-in's snapshot correlation.
pub(crate) struct Noise {
    /// The pooled lines, by the readings' setting: for a picoammeter the key's
    /// second field is the range index.
    pub lines: BTreeMap<NoiseKey, NoiseLine>,
    gap_s: f64,
    detector: Detector,
}

/// Fewest readings a pooled noise line is fitted to.
pub(crate) const MIN_POOL: usize = 8;

impl Pool {
    /// An empty pool whose reference is the reading `r`, its first.
    fn new(r: &ReadingRecord) -> Pool {
        Pool {
            t_ref: r.time_constant_s,
            n_ref: r.n,
            spans_time_constants: false,
            one_count: true,
            points: Vec::new(),
        }
    }

    /// Adds a reading's point (x, y), y its variance at its own time constant. A
    /// lock-in's is scaled to `t_ref` by [`enbw_ratio`]; a reading whose time
    /// constant has no ratio is left out.
    fn add(&mut self, r: &ReadingRecord, (x, y): (f64, f64), detector: Detector) {
        let ratio = if detector == Detector::Dc {
            Some(1.0)
        } else {
            enbw_ratio(r.time_constant_s, self.t_ref)
        };
        // A variance from n snapshots has about n − 1 degrees of freedom: its
        // weight relative to the first reading's (exactly 1 when every reading
        // takes the same number, as every run before reading time did; n and
        // n_ref are at least 2 here).
        let dof = if r.n == self.n_ref {
            1.0
        } else {
            f64::from(r.n - 1) / f64::from(self.n_ref - 1)
        };
        // A fitted reading's residuals have n − 1 − order degrees of freedom.
        let dof = match fitted_order(r) {
            Some(p) => dof * f64::from(r.n.saturating_sub(1 + p).max(1)) / f64::from(r.n - 1),
            None => dof,
        };
        if let Some(k) = ratio {
            self.spans_time_constants |= k != 1.0;
            self.one_count &= r.n == self.n_ref && r.n >= 3;
            self.points.push((x, y / k, dof));
        }
    }

    /// The line fitted to the pool, when it has [`MIN_POOL`] points and a fit.
    fn line(&self) -> Option<NoiseLine> {
        if self.points.len() < MIN_POOL {
            return None;
        }
        fit_line(&self.points, self.one_count).map(|(a, b)| NoiseLine {
            a,
            b,
            t_ref: self.t_ref,
            spans_time_constants: self.spans_time_constants,
        })
    }
}

/// A reading's point for the noise fit, (R or I, variance of one snapshot or
/// sample), or `None` for a reading that says nothing of its noise: a lock-in's
/// bright reading gives s²/B, a dark one (R pure noise, Rayleigh-distributed) half
/// its mean R², both unbiased for the snapshot variance σ² of X; a lock-in reading
/// neither dark nor well above its scatter gives none. A DC reading's samples are
/// independent conversions and its mean current is signed: every reading (the
/// darks too) gives (I, s²), I clamped at 0 (a dark current a little below zero
/// has the noise of zero current).
fn point(r: &ReadingRecord, dark: bool, gap_s: f64, detector: Detector) -> Option<(f64, f64)> {
    if !(r.r_std.is_finite() && r.r_mean.is_finite()) || r.n < 2 {
        return None;
    }
    if detector == Detector::Dc {
        (r.r_std > 0.0).then(|| (r.x_mean.max(0.0), r.r_std * r.r_std))
    } else if dark {
        Some((0.0, rayleigh_variance(r)))
    } else if r.r_mean > 3.0 * r.r_std && r.r_std > 0.0 {
        // A fitted reading's r_std is already the snapshot σ (whitened residuals).
        let b = match fitted_order(r) {
            Some(_) => 1.0,
            None => variance_factors(r.n, rho(r, gap_s)).1,
        };
        Some((r.r_mean, r.r_std * r.r_std / b))
    } else {
        None
    }
}

impl Noise {
    /// The run's noise: [`Noise::fit`] to its readings that are kept (each with
    /// whether it is a dark), without the lines of a DC run when
    /// [`Options::dc_pool_noise`] is off (each reading then keeps its own s).
    pub(crate) fn of_run(
        readings: &[(&ReadingRecord, bool)],
        opts: &Options,
        detector: Detector,
    ) -> Noise {
        let mut noise = Noise::fit(readings, opts.snapshot_gap_s, detector);
        if detector == Detector::Dc && !opts.dc_pool_noise {
            noise.lines.clear();
        }
        noise
    }

    /// Fits a + b·R to the readings' snapshot variances ([`point`]), per
    /// [`noise_key`]. A lock-in's points are divided by [`enbw_ratio`] of their
    /// time constant to the group's first, so that the line is the variance at
    /// that one time constant. Weighted least squares, re-weighted by the fitted
    /// variance (the scatter of a variance estimate grows with it).
    fn fit(readings: &[(&ReadingRecord, bool)], gap_s: f64, detector: Detector) -> Noise {
        let mut groups: BTreeMap<NoiseKey, Pool> = BTreeMap::new();
        for (r, dark) in readings {
            let Some(p) = point(r, *dark, gap_s, detector) else {
                continue;
            };
            groups
                .entry(noise_key(r, detector))
                .or_insert_with(|| Pool::new(r))
                .add(r, p, detector);
        }
        let lines = groups
            .into_iter()
            .filter_map(|(k, p)| p.line().map(|line| (k, line)))
            .collect();
        let noise = Noise {
            lines,
            gap_s,
            detector,
        };
        noise.warn_uncovered(readings);
        noise
    }

    /// Warns of the single-snapshot readings that no line covers: they have no
    /// scatter of their own, so their noise term is 0.
    fn warn_uncovered(&self, readings: &[(&ReadingRecord, bool)]) {
        let uncovered = readings
            .iter()
            .filter(|(r, dark)| r.n < 2 && !(*dark && self.detector == Detector::LockIn))
            .filter(|(r, _)| self.line_for(r).is_none())
            .count();
        if uncovered > 0 {
            tracing::warn!(
                readings = uncovered,
                "single-snapshot readings with no pooled noise line to take their σ from: their noise term is 0"
            );
        }
    }

    /// The pooled line for a reading and the factor its variance takes from it:
    /// its own group's line (scaled by [`enbw_ratio`] for a lock-in). A reading of
    /// one snapshot (n < 2, whose own scatter says nothing) without one borrows
    /// the nearest group's: for a lock-in, the line of the nearest slope scaled by
    /// the ratio of the two filters' ENBW (the density d² behind them is the same);
    /// for a picoammeter, the line of the same range and integration time at the
    /// nearest sample count (its samples are independent, so the variance of one
    /// does not depend on how many are taken).
    pub(crate) fn line_for(&self, r: &ReadingRecord) -> Option<(NoiseLine, f64)> {
        let key = noise_key(r, self.detector);
        if let Some(l) = self.lines.get(&key) {
            let k = match self.detector {
                Detector::LockIn => enbw_ratio(r.time_constant_s, l.t_ref),
                Detector::Dc => Some(1.0),
            };
            if let Some(k) = k {
                return Some((*l, k));
            }
        }
        if r.n >= 2 {
            return None;
        }
        match self.detector {
            Detector::LockIn => {
                let own = enbw_per_second(r.slope_db)? / r.time_constant_s;
                let (&(_, slope, _), l) = self
                    .lines
                    .iter()
                    .min_by_key(|((_, slope, _), _)| slope.abs_diff(r.slope_db))?;
                let theirs = enbw_per_second(slope)? / l.t_ref;
                let k = own / theirs;
                (k.is_finite() && k > 0.0).then_some((*l, k))
            }
            Detector::Dc => self
                .lines
                .iter()
                .filter(|((t, range, _), _)| *t == key.0 && *range == key.1)
                .min_by_key(|((_, _, n), _)| n.abs_diff(r.n))
                .map(|(_, l)| (*l, 1.0)),
        }
    }

    /// The standard deviation of a reading's mean X (or Y), V, or of a DC
    /// reading's mean current, A.
    pub(crate) fn sigma_mean(&self, r: &ReadingRecord, dark: bool) -> f64 {
        if self.detector == Detector::Dc {
            return self.sigma_mean_dc(r, dark);
        }
        let var = match self.line_for(r) {
            Some((l, k)) if !dark => (l.a + l.b * r.r_mean.max(0.0)) * k,
            // A dark's variance is the law's at R = 0: what every reading of the run
            // says of the floor, not the two degrees of freedom of its own R².
            Some((l, k)) => l.a * k,
            _ if dark => rayleigh_variance(r),
            _ if fitted_order(r).is_some() => r.r_std * r.r_std,
            _ => {
                let (_, b) = variance_factors(r.n, rho(r, self.gap_s));
                r.r_std * r.r_std / b
            }
        };
        if let Some(c) = fitted_order(r).and_then(|p| self.fitted_variance(r, p)) {
            return (var.max(0.0) * c).sqrt();
        }
        let (a, _) = variance_factors(r.n, rho(r, self.gap_s));
        (var.max(0.0) * a / f64::from(r.n.max(1))).sqrt()
    }

    /// A fitted reading's Var(û) for unit snapshot variance: the transient fit's
    /// covariance over its `n` snapshots, taken one gap apart as for a window
    /// (`gonio_proto::sr830::target::fitted_value_variance`; the model is invariant
    /// under a shift of the time origin, so where the first one fell does not
    /// matter). `None` without a time constant.
    fn fitted_variance(&self, r: &ReadingRecord, order: u32) -> Option<f64> {
        let gap_s = sample_interval_s(r).unwrap_or(self.gap_s);
        (r.time_constant_s > 0.0).then_some(())?;
        gonio_proto::sr830::target::fitted_value_variance(
            r.n as usize,
            gap_s.max(0.0) / r.time_constant_s,
            order as usize,
        )
    }

    /// A DC reading's σ of the mean, s/√n: its n samples are independent
    /// conversions (ρ = 0, [`variance_factors`] gives A = B = 1), so the sample
    /// variance s² (n − 1 in the denominator) is unbiased and needs no correction.
    /// s² is the pooled a + b·I where the reading's setting has a line, else the
    /// reading's own, a dark's too: the law knows the floor better than a dark's
    /// few samples.
    fn sigma_mean_dc(&self, r: &ReadingRecord, _dark: bool) -> f64 {
        let own = r.r_std * r.r_std;
        let var = match self.line_for(r) {
            Some((l, _)) => l.a + l.b * r.x_mean.max(0.0),
            _ => own,
        };
        (var.max(0.0) / f64::from(r.n.max(1))).sqrt()
    }
}

/// The snapshots' correlation ρ = e^−(T + gap)/T, or e^−gap/T for a reading taken to
/// a target (`flags::TARGETED`), whose snapshots follow one another without a pause;
/// a reading through the SR830's buffer (`flags::BUFFER_RATE`) has its samples one
/// sample period apart instead of `gap_s`, and one by snapshots that recorded their
/// measured interval (`flags::SNAP_INTERVAL`) that interval.
fn rho(r: &ReadingRecord, gap_s: f64) -> f64 {
    let gap_s = sample_interval_s(r).unwrap_or(gap_s);
    if r.time_constant_s > 0.0 {
        let pause = if r.flags & flags::TARGETED != 0 {
            0.0
        } else {
            r.time_constant_s
        };
        (-(pause + gap_s.max(0.0)) / r.time_constant_s).exp()
    } else {
        0.0
    }
}

/// The interval a targeted reading's samples were taken at, when its flags hold it:
/// the buffer's sample period, or the snapshots' measured mean interval.
fn sample_interval_s(r: &ReadingRecord) -> Option<f64> {
    flags::buffer_interval_s(r.flags).or_else(|| flags::snap_interval_s(r.flags))
}

/// The transient terms of a reading fitted through its filter's transient
/// (`flags::FITTED`): one per 6 dB/oct of its slope.
fn fitted_order(r: &ReadingRecord) -> Option<u32> {
    (r.flags & flags::FITTED != 0).then(|| u32::from(r.slope_db / 6).clamp(1, 4))
}

/// Half the mean R² of a reading's snapshots, (r̄² + s²(n − 1)/n)/2: for a reading
/// of noise alone (X, Y zero-mean normals of variance σ²) it is unbiased for σ²,
/// where R's own scatter is only 0.655 σ.
fn rayleigh_variance(r: &ReadingRecord) -> f64 {
    let n = f64::from(r.n.max(1));
    (r.r_mean * r.r_mean + r.r_std * r.r_std * (n - 1.0) / n) / 2.0
}

/// Weighted least squares of y = a + b x (a, b ≥ 0), re-weighted by the fit: a
/// point (x, y, f) weighs f/m², m the fitted variance at x and f its relative
/// degrees of freedom (a variance from more snapshots scatters less).
///
/// The first pass weighs each point by its own 1/y² when `own_start` (every run
/// before reading time: one snapshot count of at least three, and the fit as it
/// always was), else by f/ȳ², ȳ the points' mean: a variance from two snapshots
/// (one degree of freedom) can lie arbitrarily near zero, and weighted by its own
/// 1/y² it would pin the line there.
fn fit_line(p: &[(f64, f64, f64)], own_start: bool) -> Option<(f64, f64)> {
    let mean = p.iter().map(|(_, y, _)| y).sum::<f64>() / p.len().max(1) as f64;
    let mut w: Vec<f64> = p
        .iter()
        .map(|(_, y, f)| {
            let y = if own_start { *y } else { mean };
            1.0 / (y * y).max(1e-300) * f
        })
        .collect();
    let mut line = None;
    for _ in 0..4 {
        let (mut s, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for ((x, y, _), w) in p.iter().zip(&w) {
            s += w;
            sx += w * x;
            sy += w * y;
            sxx += w * x * x;
            sxy += w * x * y;
        }
        let det = s * sxx - sx * sx;
        let (mut a, mut b) = if det > 0.0 {
            ((sxx * sy - sx * sxy) / det, (s * sxy - sx * sy) / det)
        } else {
            (sy / s, 0.0)
        };
        if a < 0.0 {
            a = 0.0;
            b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        }
        if b < 0.0 {
            b = 0.0;
            a = sy / s;
        }
        if !(a.is_finite() && b.is_finite()) || a + b <= 0.0 {
            return None;
        }
        for ((x, _, f), w) in p.iter().zip(w.iter_mut()) {
            let m = a + b * x;
            *w = 1.0 / (m * m).max(1e-300) * f;
        }
        line = Some((a, b));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::reading;

    #[test]
    fn variance_factors_match_the_closed_forms() {
        // Independent snapshots: Var(mean) = σ²/n, E[s²] = σ².
        assert_eq!(variance_factors(10, 0.0), (1.0, 1.0));
        // Two snapshots: Var((x1 + x2)/2) = σ²(1 + ρ)/2, E[(x1 − x2)²/2] = σ²(1 − ρ).
        let (a, b) = variance_factors(2, 0.3);
        assert!(
            (a - 1.3).abs() < 1e-15 && (b - 0.7).abs() < 1e-15,
            "{a} {b}"
        );
        // Ten snapshots one time constant apart: A/B = 2.22, the old factor 2.2.
        let (a, b) = variance_factors(10, (-1.0f64).exp());
        assert!((a / b - 2.222).abs() < 1e-3, "{}", a / b);
    }

    #[test]
    fn a_noise_line_is_recovered_from_exact_variances() {
        let p: Vec<(f64, f64, f64)> = (0..12)
            .map(|k| {
                let x = 1e-4 * f64::from(k);
                (x, 3e-16 + 3e-12 * x, 1.0)
            })
            .collect();
        let (a, b) = fit_line(&p, true).expect("fits");
        let (a2, b2) = fit_line(&p, false).expect("fits");
        assert!((a2 / 3e-16 - 1.0).abs() < 1e-9 && (b2 / 3e-12 - 1.0).abs() < 1e-9);
        assert!((a / 3e-16 - 1.0).abs() < 1e-9 && (b / 3e-12 - 1.0).abs() < 1e-9);
    }

    #[test]
    fn half_the_mean_r_squared_of_a_dark_reading_is_its_variance() {
        // (r̄² + s²(n − 1)/n)/2 with r̄ = 3, s = 2, n = 5: (9 + 4·4/5)/2 = 6.1.
        let r = ReadingRecord {
            r_mean: 3.0,
            r_std: 2.0,
            n: 5,
            ..reading()
        };
        assert!((rayleigh_variance(&r) - 6.1).abs() < 1e-15);
        // One snapshot: its R² alone.
        let r = ReadingRecord { n: 1, ..r };
        assert_eq!(rayleigh_variance(&r), 4.5);
    }

    #[test]
    fn the_snapshots_correlate_over_a_time_constant_and_the_gap() {
        let r = ReadingRecord {
            time_constant_s: 0.1,
            flags: 0,
            ..reading()
        };
        assert_eq!(rho(&r, 0.05), (-(0.1f64 + 0.05) / 0.1).exp());
        // Read to a target, the snapshots follow one another: the gap alone.
        let targeted = ReadingRecord {
            flags: flags::TARGETED,
            ..r
        };
        assert_eq!(rho(&targeted, 0.05), (-0.05f64 / 0.1).exp());
        // Through the SR830's buffer at 64 Hz (SRAT 10): the sample period, not the gap.
        let buffered = ReadingRecord {
            flags: flags::TARGETED | flags::buffered(10),
            ..r
        };
        assert_eq!(rho(&buffered, 0.05), (-(1.0f64 / 64.0) / 0.1).exp());
        assert_eq!(
            rho(
                &ReadingRecord {
                    time_constant_s: 0.0,
                    ..r
                },
                0.05
            ),
            0.0
        );
    }

    #[test]
    fn the_enbw_ratio_is_exactly_one_at_the_reference_time_constant() {
        assert_eq!(enbw_ratio(0.03, 0.03), Some(1.0));
        assert_eq!(enbw_ratio(0.1, 0.01), Some(0.01 / 0.1));
        assert_eq!(enbw_ratio(0.0, 0.01), None);
        assert_eq!(enbw_ratio(f64::NAN, 0.01), None);
        // 12 dB/oct: ENBW = 1/(8T).
        assert_eq!(enbw_per_second(12), Some(0.125));
    }

    /// Ten bright lock-in readings whose scatter is exactly B·(a + b·R): the pool
    /// recovers the line, and a reading's σ of its mean is ((a + b·R)·A/n)^½.
    #[test]
    fn a_pool_of_exact_readings_gives_the_line_and_the_sigma_of_the_mean() {
        let (a, b, gap) = (1e-12, 1e-9, 0.0425);
        let make = |k: u32| {
            let r = ReadingRecord {
                r_mean: 1e-4 * f64::from(k + 1),
                x_mean: 1e-4 * f64::from(k + 1),
                n: 10,
                time_constant_s: 0.1,
                slope_db: 12,
                ..reading()
            };
            let (_, bf) = variance_factors(r.n, rho(&r, gap));
            ReadingRecord {
                r_std: ((a + b * r.r_mean) * bf).sqrt(),
                ..r
            }
        };
        let rs: Vec<ReadingRecord> = (0..10).map(make).collect();
        let kept: Vec<(&ReadingRecord, bool)> = rs.iter().map(|r| (r, false)).collect();
        let noise = Noise::fit(&kept, gap, Detector::LockIn);
        let line = noise.lines[&(0, 12, 0)];
        assert!((line.a / a - 1.0).abs() < 1e-6 && (line.b / b - 1.0).abs() < 1e-6);
        assert!(!line.spans_time_constants);
        let r = &rs[4];
        let (af, _) = variance_factors(r.n, rho(r, gap));
        let want = ((a + b * r.r_mean) * af / 10.0).sqrt();
        assert!((noise.sigma_mean(r, false) / want - 1.0).abs() < 1e-6);
        // Fewer than MIN_POOL readings: no line, each reading its own scatter.
        let few = Noise::fit(&kept[..MIN_POOL - 1], gap, Detector::LockIn);
        assert!(few.lines.is_empty());
        let own = (r.r_std * r.r_std / variance_factors(10, rho(r, gap)).1 * af / 10.0).sqrt();
        assert_eq!(few.sigma_mean(r, false), own);
    }

    /// A targeted reading that recorded its snapshots' measured interval correlates
    /// over that interval, not the nominal gap; a file without it keeps the gap.
    #[test]
    fn a_measured_snapshot_interval_replaces_the_nominal_gap() {
        let r = ReadingRecord {
            time_constant_s: 0.03,
            flags: flags::TARGETED | flags::snap_interval(0.039),
            ..reading()
        };
        assert_eq!(flags::snap_interval_s(r.flags), Some(390.0 * 1e-4));
        assert_eq!(rho(&r, 0.0425), (-(390.0 * 1e-4) / 0.03f64).exp());
        let old = ReadingRecord {
            flags: flags::TARGETED,
            ..r
        };
        assert_eq!(rho(&old, 0.0425), (-0.0425f64 / 0.03).exp());
        // Out of the bits' range: none recorded.
        assert_eq!(flags::snap_interval(0.5), 0);
        assert_eq!(flags::snap_interval(f64::NAN), 0);
        assert!(!flags::questioned(r.flags | flags::FITTED));
    }

    /// A reading fitted through its transient: its r_std is the snapshot σ itself
    /// (no correlation factor), its σ of the value the fit's covariance over its n
    /// snapshots at the measured interval, which is larger than a window mean's of
    /// as many snapshots (the four coefficients take their share) and smaller than
    /// a window's of the snapshots left after a settling of 13 T.
    #[test]
    fn a_fitted_reading_s_sigma_is_the_fit_s() {
        let (t, dt, n) = (0.03, 0.039, 17u32);
        let r = ReadingRecord {
            r_mean: 3e-4,
            r_std: 6e-8,
            n,
            time_constant_s: t,
            slope_db: 24,
            flags: flags::TARGETED | flags::FITTED | flags::snap_interval(dt),
            ..reading()
        };
        let noise = Noise::fit(&[(&r, false)], 0.0425, Detector::LockIn);
        assert!(noise.lines.is_empty());
        let c = gonio_proto::sr830::target::fitted_value_variance(17, dt / t, 4).expect("fit");
        let got = noise.sigma_mean(&r, false);
        assert!((got / (6e-8 * c.sqrt()) - 1.0).abs() < 1e-12, "{got}");
        let rho = (-dt / t).exp();
        let window = |m: u32| 6e-8 * (variance_factors(m, rho).0 / f64::from(m)).sqrt();
        assert!(
            got > window(n) && got < window(n - 10),
            "{got} {} {}",
            window(n),
            window(n - 10)
        );
        // Its point for the pooled law is r_std² as it stands.
        assert_eq!(
            point(&r, false, 0.0425, Detector::LockIn),
            Some((3e-4, 6e-8 * 6e-8))
        );
    }

    /// A DC reading's σ of its mean is s/√n, its samples independent.
    #[test]
    fn a_dc_reading_s_sigma_is_its_scatter_over_root_n() {
        let r = ReadingRecord {
            r_std: 2e-12,
            x_mean: 1e-9,
            n: 4,
            ..reading()
        };
        let noise = Noise::fit(&[(&r, false)], 0.0, Detector::Dc);
        assert!(noise.lines.is_empty());
        assert_eq!(noise.sigma_mean(&r, false), 1e-12);
    }
}
