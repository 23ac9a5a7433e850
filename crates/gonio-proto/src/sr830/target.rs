//! Reading to a target precision: the lock-in's noise law, its filter's transient
//! after a change, the sequential rule that decides when a reading has enough, and the
//! time a reading is expected to take.
//!
//! **The transient.** After the light changes at t₀ (a stage stopped, a range or time
//! constant changed) the input is constant, u, and each output of a cascade of N
//! identical RC stages of time constant T is exactly
//!
//!   y(τ) = u + e^(−τ) (c₀ + c₁τ + … + c_{N−1}τ^{N−1}),  τ = (t − t₀)/T,
//!
//! whatever the stages held at t₀ (the free decay of stage k reaches the output
//! through N − k more stages as e^(−τ)τ^j/j!). The model is linear in (u, c₀ … c_{N−1})
//! and invariant under a constant shift of the time origin, so a reply's latency does
//! not bias it. [`fit_transient`] fits it to the snapshots by generalised least squares
//! under the noise's correlation (below), giving the transient at every snapshot with
//! its uncertainty: the settling is measured, not assumed from a table.
//!
//! **The noise.** The output noise is taken as first-order: correlation e^(−|Δt|/T)
//! between snapshots, the law the simulator draws and the reduction assumes, so its
//! inverse is tridiagonal and whitening is the AR(1) difference
//! (yₖ − ρₖ yₖ₋₁)/√(1 − ρₖ²), ρₖ = e^(−(τₖ − τₖ₋₁)). Its variance per snapshot is
//! d(R)²·ENBW with d² = floor² + shot²·R, white densities ([`NoiseDensity`]).
//!
//! **The rule** ([`Sequential`]). The reading is the least noisy of two estimates of
//! the settled value. One is the mean of a window of the latest snapshots: the one
//! whose mean is least noisy while the fitted transient's share of that mean, plus
//! twice its standard deviation, stays below [`TRANSIENT_FRACTION`] of the target;
//! its standard deviation is the exact sum of its snapshots' correlations, not
//! σ/√n. The other, with a noise law, is the fit's u itself: the generalised
//! least-squares estimate from every snapshot, the transient's included, unbiased
//! under the model whatever the step, its variance the fit's covariance times the
//! law's (Gauss–Markov). Snapshots are added until the chosen estimate meets the
//! target. The window waits out the transient (about 13 T at 24 dB/oct for a step of
//! a quarter of the value read to 1e-4); the fit reads through it, paying only the
//! four coefficients' share of the information, so a reading limited by settling
//! takes about half as long.

use gonio_core::rng::SplitMix64;

use super::{FilterSlope, TimeConstant};

/// The largest transient left in an averaged window, as a fraction of the target
/// standard uncertainty: a bias of at most 0.2 σ adds at most 4 % to χ².
pub const TRANSIENT_FRACTION: f64 = 0.2;

/// The first snapshot after a change waits this many time constants: earlier ones
/// see almost nothing of the new value and only pin the transient.
pub const FIRST_SNAPSHOT_TC: f64 = 0.0;

/// Fewest snapshots a reading's own scatter is trusted from, when no noise law is
/// configured.
pub const MIN_OWN_SCATTER: usize = 5;

/// What a reading must reach: its standard uncertainty at most
/// max(`sigma_relative`·|value|, `sigma_absolute`), within `max_s` seconds, over at
/// least `min_samples` averaged snapshots.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReadTarget {
    /// Target standard uncertainty relative to the value.
    pub sigma_relative: f64,
    /// Floor of the target, in the reading's unit (V); 0 for none.
    pub sigma_absolute: f64,
    /// Cap on the time one reading takes, s: reached first, the reading is kept and
    /// flagged capped.
    pub max_s: f64,
    /// Fewest averaged snapshots.
    pub min_samples: usize,
}

impl ReadTarget {
    /// The target standard uncertainty for a reading of `value`.
    pub fn sigma(&self, value: f64) -> f64 {
        (self.sigma_relative * value.abs()).max(self.sigma_absolute)
    }
}

/// The lock-in's output noise as white densities: floor² + shot²·R, V²/Hz, R in V.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseDensity {
    /// Signal-independent density at the output, V/√Hz.
    pub floor: f64,
    /// Shot-noise density per √V of signal, V/√Hz per √V.
    #[serde(default)]
    pub shot: f64,
}

impl NoiseDensity {
    /// The variance of one snapshot of X (or Y) at signal `r`, V²: the density through
    /// the filter's equivalent noise bandwidth.
    pub fn snapshot_variance(&self, r: f64, slope: FilterSlope, tc: TimeConstant) -> f64 {
        (self.floor * self.floor + self.shot * self.shot * r.max(0.0)) * slope.enbw_hz(tc)
    }
}

/// The fraction of a step the output of an `order`-stage cascade still lacks after
/// `tau` time constants: e^(−τ) Σ_{j<N} τ^j/j!.
pub fn step_residual(order: usize, tau: f64) -> f64 {
    let (mut term, mut sum) = (1.0, 1.0);
    for j in 1..order {
        term *= tau / j as f64;
        sum += term;
    }
    (-tau).exp() * sum
}

/// Most parameters of the transient model: the value and four coefficients (24 dB/oct).
const MAX_PARAMS: usize = 5;

/// The model's basis at `tau` for `k` transient terms: 1 (the value), then
/// e^(−τ) τ^j for j < k; the rest 0.
fn basis(tau: f64, k: usize) -> [f64; MAX_PARAMS] {
    let mut b = [0.0; MAX_PARAMS];
    b[0] = 1.0;
    let mut p = (-tau).exp();
    for v in b.iter_mut().skip(1).take(k) {
        *v = p;
        p *= tau;
    }
    b
}

/// The transient model fitted to snapshots ([`fit_transient`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TransientFit {
    /// The settled value u.
    pub value: f64,
    /// Coefficients c₀ … of the kept transient terms.
    pub coefficients: Vec<f64>,
    /// Covariance of (u, c₀, …) for unit snapshot variance; multiply by σ².
    covariance: [[f64; MAX_PARAMS]; MAX_PARAMS],
    /// Whitened residual sum of squares and its degrees of freedom.
    rss: f64,
    dof: usize,
}

impl TransientFit {
    /// The fitted transient at `tau`, in the value's unit.
    pub fn transient(&self, tau: f64) -> f64 {
        let e = (-tau).exp();
        let mut p = 1.0;
        let mut sum = 0.0;
        for c in &self.coefficients {
            sum += c * p;
            p *= tau;
        }
        e * sum
    }

    /// The variance of the fitted transient at `tau`, for unit snapshot variance.
    pub fn transient_variance(&self, tau: f64) -> f64 {
        let k = self.coefficients.len();
        let mut b = basis(tau, k);
        b[0] = 0.0;
        quad(&self.covariance, &b, k + 1)
    }

    /// The variance of the settled value, for unit snapshot variance.
    pub fn value_variance(&self) -> f64 {
        self.covariance[0][0]
    }

    /// The snapshot variance the residuals estimate (unbiased under the model), when
    /// there are degrees of freedom left.
    pub fn residual_variance(&self) -> Option<f64> {
        (self.dof > 0).then(|| self.rss / self.dof as f64)
    }
}

/// bᵀ C b over the first `n` entries.
fn quad(c: &[[f64; MAX_PARAMS]; MAX_PARAMS], b: &[f64; MAX_PARAMS], n: usize) -> f64 {
    let mut s = 0.0;
    for i in 0..n {
        for j in 0..n {
            s += b[i] * c[i][j] * b[j];
        }
    }
    s
}

/// Fits y(τ) = u + e^(−τ) Σ_{j<order} c_j τ^j to `values` at `taus` (time constants
/// since the change, increasing) by least squares whitened for first-order noise.
/// Transient terms the snapshots cannot tell apart (their columns nearly dependent,
/// as when every snapshot is many time constants after the change) are dropped from
/// the top order down: over the snapshots the kept terms represent them. `None`
/// when there are fewer snapshots than the full model's parameters, or the value
/// itself is not determined.
pub fn fit_transient(taus: &[f64], values: &[f64], order: usize) -> Option<TransientFit> {
    let m = taus.len().min(values.len());
    let order = order.min(MAX_PARAMS - 1);
    if m < order + 1 {
        return None;
    }
    let mut kept = order;
    loop {
        if let Some(fit) = solve(taus, values, m, kept) {
            return Some(fit);
        }
        if kept == 0 {
            return None;
        }
        kept -= 1;
    }
}

/// The variance of the settled value [`fit_transient`] fits to `n` snapshots
/// `spacing` time constants apart, for unit snapshot variance: the precision of a
/// fitted reading, given only its count and spacing (the model is invariant under
/// a shift of the time origin). `None` when the fit does not keep every term (the
/// rule then reads no fitted value) or is not determined; `n` is bounded by
/// [`MAX_FITTED`].
pub fn fitted_value_variance(n: usize, spacing: f64, order: usize) -> Option<f64> {
    if n > MAX_FITTED || !(spacing.is_finite() && spacing > 0.0) {
        return None;
    }
    let order = order.min(MAX_PARAMS - 1);
    let taus: Vec<f64> = (1..=n).map(|i| spacing * i as f64).collect();
    fit_transient(&taus, &vec![0.0; n], order)
        .filter(|f| f.coefficients.len() == order)
        .map(|f| f.value_variance())
}

/// The 99.9 % quantile of χ² with `dof` degrees of freedom, by Wilson and
/// Hilferty's cube-root normal approximation (1931; within 3 % from one degree of
/// freedom on: 11.16 for the exact 10.83 at one, 29.76 for 29.59 at ten).
fn chi2_quantile_999(dof: usize) -> f64 {
    const Z: f64 = 3.090_232; // the normal's 99.9 % quantile
    let k = dof.max(1) as f64;
    let c = 2.0 / (9.0 * k);
    k * (1.0 - c + Z * c.sqrt()).powi(3)
}

/// Most snapshots a fitted reading holds: the rule stops refitting the transient
/// after this many (a bound on its cost), and the window decides from there.
pub const MAX_FITTED: usize = MAX_REFITS;

/// One whitened design row and its value.
fn whitened_rows<'a>(
    taus: &'a [f64],
    values: &'a [f64],
    m: usize,
    kept: usize,
) -> impl Iterator<Item = ([f64; MAX_PARAMS], f64)> + 'a {
    let row = move |tau: f64| basis(tau, kept);
    (0..m).map(move |i| {
        let (x, y) = (row(taus[i]), values[i]);
        if i == 0 {
            return (x, y);
        }
        let rho = (-(taus[i] - taus[i - 1]).max(0.0)).exp();
        let s = (1.0 - rho * rho).max(1e-300).sqrt();
        let xp = row(taus[i - 1]);
        let mut w = [0.0; MAX_PARAMS];
        for j in 0..=kept {
            w[j] = (x[j] - rho * xp[j]) / s;
        }
        (w, (y - rho * values[i - 1]) / s)
    })
}

/// Least squares by Householder QR of the whitened design (columns scaled to unit
/// norm), which keeps the precision the normal equations would square away; a
/// diagonal of R under 1e-12 of its column means nearly dependent columns: `None`.
// Householder reflections and back substitution read best as the index formulas.
#[allow(clippy::needless_range_loop)]
fn solve(taus: &[f64], values: &[f64], m: usize, kept: usize) -> Option<TransientFit> {
    let p = kept + 1;
    // Columns of the scaled design, and the right-hand side, reduced in place.
    let (mut a, mut y): (Vec<[f64; MAX_PARAMS]>, Vec<f64>) =
        whitened_rows(taus, values, m, kept).unzip();
    let mut scale = [0.0; MAX_PARAMS];
    for w in &a {
        for j in 0..p {
            scale[j] += w[j] * w[j];
        }
    }
    for v in scale.iter_mut().take(p) {
        if !(*v > 0.0 && v.is_finite()) {
            return None;
        }
        *v = v.sqrt();
    }
    for w in &mut a {
        for j in 0..p {
            w[j] /= scale[j];
        }
    }
    for j in 0..p {
        let norm = (j..m).map(|i| a[i][j] * a[i][j]).sum::<f64>().sqrt();
        if norm <= 1e-12 {
            return None;
        }
        let alpha = if a[j][j] > 0.0 { -norm } else { norm };
        let mut v: Vec<f64> = (j..m).map(|i| a[i][j]).collect();
        v[0] -= alpha;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        if vv > 0.0 {
            for c in j..p {
                let d: f64 = (j..m).map(|i| v[i - j] * a[i][c]).sum::<f64>() * 2.0 / vv;
                for i in j..m {
                    a[i][c] -= d * v[i - j];
                }
            }
            let d: f64 = (j..m).map(|i| v[i - j] * y[i]).sum::<f64>() * 2.0 / vv;
            for i in j..m {
                y[i] -= d * v[i - j];
            }
        }
    }
    // R θ' = (Qᵀy)[..p]; R⁻¹ by back substitution; undo the scaling.
    let mut rinv = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    for c in 0..p {
        for i in (0..=c).rev() {
            let mut v = if i == c { 1.0 } else { 0.0 };
            for k in i + 1..=c {
                v -= a[i][k] * rinv[k][c];
            }
            rinv[i][c] = v / a[i][i];
        }
    }
    let mut theta = [0.0; MAX_PARAMS];
    let mut cov = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    for i in 0..p {
        theta[i] = (i..p).map(|k| rinv[i][k] * y[k]).sum::<f64>() / scale[i];
        for j in 0..p {
            let v: f64 = (i.max(j)..p).map(|k| rinv[i][k] * rinv[j][k]).sum();
            cov[i][j] = v / (scale[i] * scale[j]);
        }
    }
    if !theta
        .iter()
        .chain(cov.iter().flatten())
        .all(|v| v.is_finite())
    {
        return None;
    }
    let rss: f64 = y[p..m].iter().map(|v| v * v).sum();
    Some(TransientFit {
        value: theta[0],
        coefficients: theta[1..p].to_vec(),
        covariance: cov,
        rss,
        dof: m - p,
    })
}

/// One snapshot: when (time constants since the change) and what.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Snap {
    tau: f64,
    x: f64,
    y: f64,
    r: f64,
}

/// What [`Sequential::assess`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Assessment {
    /// The averaged window's first snapshot, once the transient allows one (0 when
    /// the fitted value is chosen: every snapshot counts).
    pub window_start: Option<usize>,
    /// The fitted settled value is the reading, not a window's mean.
    pub fitted: bool,
    /// The standard deviation of the window's mean R, V (infinite before a window).
    pub sigma_mean: f64,
    /// The target for the window's mean, V.
    pub target: f64,
    /// The window meets the target and has enough snapshots.
    pub done: bool,
}

/// The averaged reading a [`Sequential`] ends with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowMean {
    /// Mean R over the window, V.
    pub r_mean: f64,
    /// Sample standard deviation of R over the window (n − 1), V.
    pub r_std: f64,
    /// Mean X, V.
    pub x_mean: f64,
    /// Mean Y, V.
    pub y_mean: f64,
    /// Snapshots averaged.
    pub n: usize,
    /// Time constants from the change to the window's first snapshot.
    pub settle_tc: f64,
    /// The means are the transient fit's settled values (X, Y and R each fitted),
    /// and `r_std` the snapshot σ its whitened residuals estimate.
    pub fitted: bool,
    /// The mean interval between the averaged snapshots, in time constants (`None`
    /// for one snapshot).
    pub interval_tc: Option<f64>,
}

/// The mean interval of snapshots at `taus`, `None` for fewer than two.
fn mean_interval(taus: impl ExactSizeIterator<Item = f64> + Clone) -> Option<f64> {
    let n = taus.len();
    let first = taus.clone().next()?;
    let last = taus.last()?;
    (n > 1).then(|| (last - first) / (n - 1) as f64)
}

/// Refits stop after this many snapshots, a bound on the rule's cost (each fit is
/// linear in the snapshots); the last fit stands. Snapshots come at least an
/// eighth of a time constant apart on the shipped range (a 37.5 ms exchange at
/// 300 ms), so by then they are 50 time constants on, where a step's residual is
/// 4e-18 at 24 dB/oct.
const MAX_REFITS: usize = 400;

/// The sequential rule (module doc) for one reading after a change: snapshots go in
/// as they come ([`push`](Self::push)); [`assess`](Self::assess) chooses the window and
/// says whether its mean is precise enough.
#[derive(Clone, Debug)]
pub struct Sequential {
    order: usize,
    snaps: Vec<Snap>,
    fit: Option<TransientFit>,
    /// Snapshots `fit` was made from.
    fit_len: usize,
    start: Option<usize>,
    /// The last assessment chose the fitted value.
    fitted: bool,
    /// A change long enough ago that no step can still show (see [`Self::new`]).
    settled_before: bool,
}

impl Sequential {
    /// A reading of a filter with `order` stages (1 … 4); `first_tau` is when its first
    /// snapshot will be, in time constants since the change: at 60 time constants or
    /// more a step of 10¹⁵ times the value has decayed below it at 24 dB/oct, so no
    /// transient is fitted.
    pub fn new(order: usize, first_tau: f64) -> Self {
        let order = order.clamp(1, MAX_PARAMS - 1);
        Sequential {
            order,
            snaps: Vec::new(),
            fit: None,
            fit_len: 0,
            start: None,
            fitted: false,
            settled_before: step_residual(order, first_tau) < 1e-15,
        }
    }

    /// Snapshots taken.
    pub fn len(&self) -> usize {
        self.snaps.len()
    }

    /// True before the first snapshot.
    pub fn is_empty(&self) -> bool {
        self.snaps.is_empty()
    }

    /// The window's first snapshot at the last assessment.
    pub fn window_start(&self) -> Option<usize> {
        self.start
    }

    /// The last assessment chose the fitted settled value.
    pub fn fitted(&self) -> bool {
        self.fitted
    }

    /// A snapshot (X, Y) at `tau` time constants after the change.
    pub fn push(&mut self, tau: f64, x: f64, y: f64) {
        self.snaps.push(Snap {
            tau,
            x,
            y,
            r: x.hypot(y),
        });
    }

    /// Chooses the window after the latest snapshot (`noise` the snapshot variance
    /// at a signal R, when known) and says whether its mean meets `target`. Without a
    /// noise law the fit's residuals bound the transient and the window's own
    /// scatter, corrected for its correlation, gives its noise, from
    /// [`MIN_OWN_SCATTER`] snapshots on.
    pub fn assess(
        &mut self,
        target: &ReadTarget,
        noise: Option<&dyn Fn(f64) -> f64>,
    ) -> Assessment {
        let best = self.best_window(target, noise);
        let fitted = self.fitted_sigma(target, noise);
        self.fitted = fitted.is_some_and(|(f, _)| best.is_none_or(|(_, w)| f < w));
        if let (true, Some((sigma, value))) = (self.fitted, fitted) {
            self.start = Some(0);
            let goal = target.sigma(value);
            return Assessment {
                window_start: Some(0),
                fitted: true,
                sigma_mean: sigma,
                target: goal,
                done: sigma <= goal,
            };
        }
        self.start = best.map(|(s, _)| s);
        let Some((s, sigma)) = best else {
            return Assessment {
                window_start: None,
                fitted: false,
                sigma_mean: f64::INFINITY,
                target: f64::INFINITY,
                done: false,
            };
        };
        let n = self.snaps.len() - s;
        let mean = self.snaps[s..].iter().map(|x| x.r).sum::<f64>() / n as f64;
        let goal = target.sigma(mean);
        Assessment {
            window_start: Some(s),
            fitted: false,
            sigma_mean: sigma,
            target: goal,
            done: sigma <= goal && n >= target.min_samples.max(1),
        }
    }

    /// The standard deviation of the fitted settled value and the value, when the
    /// fit is of every snapshot and kept every transient term, a noise law gives the
    /// snapshot variance, and there are at least `min_samples` snapshots and one
    /// degree of freedom (so that the residuals say something of the snapshots'
    /// scatter): Var(û) = σ²·(XᵀV⁻¹X)⁻¹₀₀. A fit that dropped terms is not used: over
    /// a short stretch of the transient the dropped terms are represented by the
    /// kept ones and the constant, so its û would carry part of them.
    fn fitted_sigma(
        &self,
        target: &ReadTarget,
        noise: Option<&dyn Fn(f64) -> f64>,
    ) -> Option<(f64, f64)> {
        let (f, law) = (self.fit.as_ref()?, noise?);
        let k = self.snaps.len();
        let full = f.coefficients.len() == self.order;
        if self.fit_len != k || !full || f.dof < 1 || k < target.min_samples.max(1) {
            return None;
        }
        let var = law(f.value).max(0.0);
        // Residuals beyond the law's 99.9 % say the model does not hold (the light
        // was not constant, the snapshots' times are off): no fitted value.
        if f.rss > var * chi2_quantile_999(f.dof) {
            return None;
        }
        let sigma = (var * f.value_variance()).sqrt();
        sigma.is_finite().then_some((sigma, f.value))
    }

    /// The transient refitted (up to [`MAX_REFITS`]), then the window's first snapshot
    /// and the standard deviation of its mean, when a window can be chosen.
    fn best_window(
        &mut self,
        target: &ReadTarget,
        noise: Option<&dyn Fn(f64) -> f64>,
    ) -> Option<(usize, f64)> {
        let k = self.snaps.len();
        if k == 0 {
            return None;
        }
        if !self.settled_before && (self.fit.is_none() || k <= MAX_REFITS) {
            let taus: Vec<f64> = self.snaps.iter().map(|s| s.tau).collect();
            let rs: Vec<f64> = self.snaps.iter().map(|s| s.r).collect();
            if let Some(f) = fit_transient(&taus, &rs, self.order) {
                self.fit = Some(f);
                self.fit_len = k;
            }
        }
        if !self.settled_before && self.fit.is_none() {
            return None;
        }
        let value = self.fit.as_ref().map_or(self.snaps[k - 1].r, |f| f.value);
        let var = match noise {
            Some(f) => Some(f(value)),
            None => self
                .fit
                .as_ref()
                .and_then(|f| (f.dof >= 2).then(|| f.residual_variance()).flatten()),
        };
        let var_bias = match (&self.fit, var) {
            (None, _) => 0.0,
            (Some(_), Some(v)) => v,
            (Some(_), None) => return None,
        };
        let allowed = TRANSIENT_FRACTION * target.sigma(value);
        // Backwards over the window's start s: the sums of R, R², the transient's
        // basis, and the correlations Σ_{i,j ≥ s} e^(−|τᵢ − τⱼ|).
        let p = self.fit.as_ref().map_or(0, |f| f.coefficients.len());
        let (mut sum_r, mut sum_r2) = (0.0, 0.0);
        let shift = self.snaps[k - 1].r;
        let mut sum_b = [0.0; MAX_PARAMS];
        let (mut corr, mut tail) = (0.0, 0.0);
        let mut best: Option<(usize, f64)> = None;
        for s in (0..k).rev() {
            let snap = self.snaps[s];
            if s + 1 < k {
                let gap = (self.snaps[s + 1].tau - snap.tau).max(0.0);
                tail = (-gap).exp() * (1.0 + tail);
            } else {
                tail = 0.0;
            }
            corr += 1.0 + 2.0 * tail;
            sum_r += snap.r - shift;
            sum_r2 += (snap.r - shift).powi(2);
            let n = (k - s) as f64;
            let bias = match &self.fit {
                Some(f) => {
                    let b = basis(snap.tau, p);
                    let mut mean_b = [0.0; MAX_PARAMS];
                    for j in 1..=p {
                        sum_b[j] += b[j];
                        mean_b[j] = sum_b[j] / n;
                    }
                    let t: f64 = (1..=p).map(|j| mean_b[j] * f.coefficients[j - 1]).sum();
                    t.abs() + 2.0 * (var_bias * quad(&f.covariance, &mean_b, p + 1)).sqrt()
                }
                None => 0.0,
            };
            if bias > allowed {
                continue;
            }
            let mean = shift + sum_r / n;
            let snap_var = match noise {
                Some(f) => Some(f(mean)),
                None if n >= MIN_OWN_SCATTER as f64 => {
                    let m2 = (sum_r2 - sum_r * sum_r / n).max(0.0);
                    let denom = n - corr / n;
                    (denom > 0.0).then(|| m2 / denom)
                }
                None => None,
            };
            let Some(v) = snap_var else { continue };
            let sigma = (v.max(0.0) * corr).sqrt() / n;
            if best.is_none_or(|(_, b)| sigma <= b) {
                best = Some((s, sigma));
            }
        }
        best
    }

    /// The window's means, or the fitted values when the last assessment chose them,
    /// or, when no window could be chosen (a capped reading), the later half of the
    /// snapshots.
    pub fn result(&mut self) -> Option<WindowMean> {
        if self.snaps.is_empty() {
            return None;
        }
        if self.fitted {
            if let Some(w) = self.fitted_result() {
                return Some(w);
            }
            // No window was chosen beside it: as for a capped reading.
            self.start = None;
        }
        let start = self.start.unwrap_or(self.snaps.len() / 2);
        let w = &self.snaps[start..];
        let n = w.len();
        let nf = n as f64;
        let mean_r = w.iter().map(|s| s.r).sum::<f64>() / nf;
        let r_std = if n > 1 {
            (w.iter().map(|s| (s.r - mean_r).powi(2)).sum::<f64>() / (nf - 1.0)).sqrt()
        } else {
            0.0
        };
        Some(WindowMean {
            r_mean: mean_r,
            r_std,
            x_mean: w.iter().map(|s| s.x).sum::<f64>() / nf,
            y_mean: w.iter().map(|s| s.y).sum::<f64>() / nf,
            n,
            settle_tc: w[0].tau,
            fitted: false,
            interval_tc: mean_interval(w.iter().map(|s| s.tau)),
        })
    }

    /// The settled X, Y and R fitted from every snapshot (one design, every term
    /// kept), `r_std` the residuals' snapshot σ; `None` if a fit does not keep them.
    fn fitted_result(&self) -> Option<WindowMean> {
        let taus: Vec<f64> = self.snaps.iter().map(|s| s.tau).collect();
        let of = |v: fn(&Snap) -> f64| {
            let vs: Vec<f64> = self.snaps.iter().map(v).collect();
            fit_transient(&taus, &vs, self.order).filter(|g| g.coefficients.len() == self.order)
        };
        let r = of(|s| s.r)?;
        Some(WindowMean {
            r_mean: r.value,
            r_std: r.residual_variance().unwrap_or(0.0).sqrt(),
            x_mean: of(|s| s.x)?.value,
            y_mean: of(|s| s.y)?.value,
            n: self.snaps.len(),
            settle_tc: self.snaps[0].tau,
            fitted: true,
            interval_tc: mean_interval(taus.iter().copied()),
        })
    }
}

/// How long a reading is expected to take ([`estimate`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReadEstimate {
    /// The time constant.
    pub time_constant: TimeConstant,
    /// From the change to the first averaged snapshot, s.
    pub settle_s: f64,
    /// From the first averaged snapshot to the last, s.
    pub averaging_s: f64,
    /// Snapshots averaged.
    pub samples: usize,
}

impl ReadEstimate {
    /// Settling and averaging, s.
    pub fn total_s(&self) -> f64 {
        self.settle_s + self.averaging_s
    }
}

const ESTIMATE_SNAPSHOTS: usize = 48;

const ESTIMATE_SEEDS: [u64; 2] = [0x5EED_0001, 0x5EED_0002];

/// Σ_{i,j<n} ρ^|i−j| for snapshots equally spaced with correlation ρ.
fn correlation_sum(n: usize, rho: f64) -> f64 {
    let nf = n as f64;
    if rho <= 0.0 {
        return nf;
    }
    nf * (1.0 + rho) / (1.0 - rho) - 2.0 * rho * (1.0 - rho.powi(n as i32)) / (1.0 - rho).powi(2)
}

/// The expected time of a reading of `expected` V after a step of `step` V, at time
/// constant `tc` and `slope`, with `exchange_s` the time of one `SNAP?` exchange. The
/// rule itself is run ([`Sequential`]) on snapshots back to back from
/// [`FIRST_SNAPSHOT_TC`] on, the step's exact response plus first-order noise of the
/// law's variance, for two fixed seeds (so that it is a function of its arguments);
/// past 48 snapshots the window's start is taken as found (it has settled by then)
/// and its length as the noise needs (the exact correlation sum). The mean of the two is returned; the cap is not applied.
pub fn estimate(
    expected: f64,
    step: f64,
    target: &ReadTarget,
    noise: &NoiseDensity,
    slope: FilterSlope,
    tc: TimeConstant,
    exchange_s: f64,
) -> ReadEstimate {
    let t = tc.seconds();
    let spacing = exchange_s.max(1e-6) / t;
    let rho = (-spacing).exp();
    let order = usize::from(slope.index()) + 1;
    let var = noise.snapshot_variance(expected, slope, tc);
    let sigma = var.sqrt();
    let law = move |_: f64| var;
    let goal = target.sigma(expected);
    let needed = |from_n: usize| {
        let mut n = from_n.max(target.min_samples.max(1));
        while n < 10_000_000 && var * correlation_sum(n, rho) > goal * goal * (n * n) as f64 {
            n = (n + n / 8).max(n + 1);
        }
        n
    };
    let (mut settle, mut total, mut samples) = (0.0, 0.0, 0.0);
    for seed in ESTIMATE_SEEDS {
        let mut rng = SplitMix64::new(seed);
        let mut seq = Sequential::new(order, FIRST_SNAPSHOT_TC);
        let mut n_v = sigma * rng.next_normal();
        let mut outcome = None;
        let mut tau = FIRST_SNAPSHOT_TC + spacing;
        for k in 0..ESTIMATE_SNAPSHOTS {
            if k > 0 {
                n_v = rho * n_v + sigma * (1.0 - rho * rho).sqrt() * rng.next_normal();
                tau += spacing;
            }
            seq.push(tau, expected + step * step_residual(order, tau) + n_v, 0.0);
            let a = seq.assess(target, Some(&law));
            if a.done {
                let s = a.window_start.unwrap_or(0);
                outcome = Some((FIRST_SNAPSHOT_TC + spacing * (s + 1) as f64, tau, k + 1 - s));
                break;
            }
        }
        let (start_tau, end_tau, n) = outcome.unwrap_or_else(|| {
            let s = seq.window_start().unwrap_or(seq.len());
            let start = FIRST_SNAPSHOT_TC + spacing * (s + 1) as f64;
            let n = needed(seq.len() - s.min(seq.len()));
            (start, start + spacing * (n - 1) as f64, n)
        });
        settle += start_tau * t;
        total += end_tau * t;
        samples += n as f64;
    }
    let m = ESTIMATE_SEEDS.len() as f64;
    ReadEstimate {
        time_constant: tc,
        settle_s: settle / m,
        averaging_s: (total - settle) / m,
        samples: (samples / m).round() as usize,
    }
}

/// The time constant among `choices` that reads `expected` fastest ([`estimate`],
/// a step of a quarter of the signal assumed: neighbouring points of a plan ordered
/// for least motion differ by a fraction of their value — on the hemisphere plan 7 %
/// at the median, 22 % at the 75th percentile), with its estimate; `None` for no
/// choices.
pub fn choose_time_constant(
    expected: f64,
    target: &ReadTarget,
    noise: &NoiseDensity,
    slope: FilterSlope,
    choices: impl IntoIterator<Item = TimeConstant>,
    exchange_s: f64,
) -> Option<ReadEstimate> {
    let step = 0.25 * expected;
    let time = |tc| estimate(expected, step, target, noise, slope, tc, exchange_s);
    let fastest = |a: &ReadEstimate, b: &ReadEstimate| a.total_s().total_cmp(&b.total_s());
    choices.into_iter().map(time).min_by(fastest)
}

/// The absolute floor a plan without `sigma_absolute` reads to: `sigma_relative` of
/// the dimmest signal read within half the cap ([`choose_time_constant`]'s estimate
/// equal to `max_s`/2), so that a dark reading, whose value is noise, is read about
/// as long as that point and well within its cap. `None` for no
/// choices or a cap no signal up to 10 V meets.
pub fn floor_sigma(
    target: &ReadTarget,
    noise: &NoiseDensity,
    slope: FilterSlope,
    choices: &[TimeConstant],
    exchange_s: f64,
) -> Option<f64> {
    let time = |s: f64| {
        choose_time_constant(s, target, noise, slope, choices.iter().copied(), exchange_s)
            .map(|e| e.total_s())
    };
    let budget = 0.5 * target.max_s;
    let (mut lo, mut hi) = (-15.0f64, 1.0f64);
    if time(10f64.powf(hi))? > budget {
        return None;
    }
    // The time falls as the signal grows (σ_rel·S outgrows √(floor² + shot²·S)).
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if time(10f64.powf(mid))? > budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(target.sigma_relative * 10f64.powf(hi))
}
