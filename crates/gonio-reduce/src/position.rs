//! The position term: a sample is reported at its nominal directions, but was read
//! where the stages stood — a target rounds to an encoder count, a stage settles
//! within its tolerance. The run keeps both, so the offset Δx of each angle is
//! known; what the reduction does not know is how fast the BRDF changes there. It
//! estimates the slope from the neighbouring samples along each angle, in log
//! space (central differences of ln f are exact for a Gaussian lobe, and zero at
//! its peak, where a small offset does not matter), and states
//!
//!   σ_pos = f · √(Σ_x (∂ln f/∂x · Δx)²)
//!
//! as an independent term: each reading's offset is its own. It matters only on
//! steep lobes: an offset of 5e-4° on a lobe 5° wide is 1e-4 of f.

use std::collections::BTreeMap;

use gonio_core::dirfile::PairDeg;

/// Angles keyed in micro-degrees.
fn key(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

/// The angle coordinates the BRDF depends on: (θi, θo, φo − φi) for isotropic
/// data, else (θi, φi, θo, φo), degrees; and which of them is an azimuth, with the
/// polar angle that makes it meaningful.
fn coords(p: &PairDeg, isotropic: bool) -> Vec<f64> {
    let (i, o) = (p.incident, p.outgoing);
    if isotropic {
        vec![i.theta_deg, o.theta_deg, o.phi_deg - i.phi_deg]
    } else {
        vec![i.theta_deg, i.phi_deg, o.theta_deg, o.phi_deg]
    }
}

/// Whether coordinate `d` is an azimuth, and so undefined at a pole: its polar
/// angle's index.
fn azimuth_pole(d: usize, isotropic: bool) -> Option<usize> {
    match (isotropic, d) {
        (true, 2) => Some(1),
        (false, 1) => Some(0),
        (false, 3) => Some(2),
        _ => None,
    }
}

/// A difference of two angles, wrapped to [−180°, 180°) for an azimuth.
fn delta(a: f64, b: f64, azimuth: bool) -> f64 {
    let d = a - b;
    if azimuth {
        d - 360.0 * ((d + 180.0) / 360.0).floor()
    } else {
        d
    }
}

/// Neighbours farther apart than this along an angle say nothing of the slope, deg.
const MAX_STEP_DEG: f64 = 45.0;

/// The position term of every sample and channel, 1/sr: `values[i][c]` the samples'
/// values at their nominal `pairs[i]`, `reads[i][c]` where the stages stood for
/// channel c's reading (none: no offset known).
pub(crate) fn sigmas(
    pairs: &[PairDeg],
    values: &[Vec<f64>],
    reads: &[Vec<Option<PairDeg>>],
    isotropic: bool,
) -> Vec<Vec<f64>> {
    let n = pairs.len();
    let nc = values.first().map_or(0, Vec::len);
    let x: Vec<Vec<f64>> = pairs.iter().map(|p| coords(p, isotropic)).collect();
    let dims = if isotropic { 3 } else { 4 };
    let mut out = vec![vec![0.0f64; nc]; n];
    for d in 0..dims {
        let pole = azimuth_pole(d, isotropic);
        // The samples on each line along coordinate d, in order.
        let mut lines: BTreeMap<Vec<i64>, Vec<usize>> = BTreeMap::new();
        for (i, xi) in x.iter().enumerate() {
            let rest = (0..dims).filter(|&e| e != d).map(|e| key(xi[e])).collect();
            lines.entry(rest).or_default().push(i);
        }
        for line in lines.values_mut() {
            line.sort_by(|&a, &b| x[a][d].total_cmp(&x[b][d]));
            for (k, &i) in line.iter().enumerate() {
                if pole.is_some_and(|p| x[i][p].abs() < 0.5) {
                    continue;
                }
                let near = |j: Option<&usize>| {
                    j.copied()
                        .filter(|&j| (x[j][d] - x[i][d]).abs() <= MAX_STEP_DEG)
                };
                let (lo, hi) = (
                    near(k.checked_sub(1).and_then(|k| line.get(k))),
                    near(line.get(k + 1)),
                );
                for c in 0..nc {
                    let Some(read) = reads[i][c] else { continue };
                    let dx = delta(coords(&read, isotropic)[d], x[i][d], pole.is_some());
                    let slope = log_slope(values, c, i, lo, hi, |j| x[j][d]);
                    out[i][c] += (slope * dx).powi(2);
                }
            }
        }
    }
    for (o, v) in out.iter_mut().zip(values) {
        for (s, f) in o.iter_mut().zip(v) {
            *s = f.abs() * s.sqrt();
        }
    }
    out
}

/// ∂ln f/∂x at sample `i` of channel `c` from its neighbours `lo` and `hi` along x
/// (central where it has both, else one-sided), 1/deg; 0 without a neighbour or
/// where a value is not positive.
fn log_slope(
    values: &[Vec<f64>],
    c: usize,
    i: usize,
    lo: Option<usize>,
    hi: Option<usize>,
    x: impl Fn(usize) -> f64,
) -> f64 {
    let ln = |j: usize| {
        let v = values[j][c];
        (v > 0.0).then(|| v.ln())
    };
    let (a, b) = match (lo, hi) {
        (Some(l), Some(h)) => (l, h),
        (Some(l), None) => (l, i),
        (None, Some(h)) => (i, h),
        (None, None) => return 0.0,
    };
    match (ln(a), ln(b)) {
        (Some(fa), Some(fb)) if x(b) != x(a) => (fb - fa) / (x(b) - x(a)),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gonio_core::SphericalDeg;

    fn pair(ti: f64, to: f64, po: f64) -> PairDeg {
        PairDeg {
            incident: SphericalDeg::new(ti, 0.0),
            outgoing: SphericalDeg::new(to, po),
        }
    }

    /// A Gaussian lobe in θo, f = exp(−(θo − 30)²/50), sampled every 5°: the
    /// central log difference is its exact derivative −2(θo − 30)/50, so a sample
    /// read 0.01° off carries f·|∂ln f/∂θo|·0.01; one at the peak carries none, and
    /// one read where it should be carries none.
    #[test]
    fn a_gaussian_lobe_gives_its_exact_slope() {
        let thetas = [15.0, 20.0, 25.0, 30.0, 35.0, 40.0];
        let f = |t: f64| (-(t - 30.0) * (t - 30.0) / 50.0).exp();
        let pairs: Vec<PairDeg> = thetas.iter().map(|t| pair(20.0, *t, 180.0)).collect();
        let values: Vec<Vec<f64>> = thetas.iter().map(|t| vec![f(*t)]).collect();
        let reads: Vec<Vec<Option<PairDeg>>> = thetas
            .iter()
            .enumerate()
            .map(|(k, t)| vec![Some(pair(20.0, if k == 4 { *t } else { t + 0.01 }, 180.0))])
            .collect();
        let s = sigmas(&pairs, &values, &reads, true);
        // θo = 25: slope 2·5/50 = 0.2 per degree.
        assert!(
            (s[2][0] - f(25.0) * 0.2 * 0.01).abs() < 1e-9 * f(25.0),
            "{:?}",
            s[2]
        );
        assert!(s[3][0].abs() < 1e-12, "the peak: {:?}", s[3]);
        assert_eq!(s[4][0], 0.0, "read where it should be");
        // The ends are one-sided: (ln f(20) − ln f(15))/5 = (−2 + 4.5)/5 = 0.5.
        assert!((s[0][0] - f(15.0) * 0.5 * 0.01).abs() < 1e-9 * f(15.0));
    }

    /// An azimuth offset at the normal means nothing; elsewhere it wraps.
    #[test]
    fn azimuths_wrap_and_mean_nothing_at_the_pole() {
        assert!((delta(359.9, 0.1, true) + 0.2).abs() < 1e-9);
        assert!((delta(0.1, 359.9, true) - 0.2).abs() < 1e-9);
        assert_eq!(delta(10.0, 5.0, false), 5.0);
        let pairs = vec![pair(0.0, 0.0, 0.0), pair(0.0, 0.0, 90.0)];
        let values = vec![vec![1.0], vec![2.0]];
        let reads = vec![
            vec![Some(pair(0.0, 0.0, 1.0))],
            vec![Some(pair(0.0, 0.0, 91.0))],
        ];
        assert_eq!(sigmas(&pairs, &values, &reads, true), [[0.0], [0.0]]);
    }
}
