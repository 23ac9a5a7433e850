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
//! **The rule** ([`Sequential`]). A window of snapshots is averaged once the fitted
//! transient, plus twice its standard deviation, is below [`TRANSIENT_FRACTION`] of
//! the target at every snapshot in it; the window then grows until the standard
//! deviation of its mean — from the exact sum of the correlations of its snapshots,
//! not σ/√n — meets the target.

use super::{FilterSlope, TimeConstant};

/// The largest transient left in an averaged window, as a fraction of the target
/// standard uncertainty: a bias of at most 0.2 σ adds at most 4 % to χ².
pub const TRANSIENT_FRACTION: f64 = 0.2;

/// The first snapshot after a change waits this many time constants: earlier ones
/// see almost nothing of the new value and only pin the transient.
pub const FIRST_SNAPSHOT_TC: f64 = 2.0;

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
        let e = (-tau).exp();
        let mut b = [0.0; MAX_PARAMS];
        let mut p = e;
        for v in b.iter_mut().skip(1).take(k) {
            *v = p;
            p *= tau;
        }
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
/// when there are fewer snapshots than the full model's parameters + 1, or the value
/// itself is not determined.
pub fn fit_transient(taus: &[f64], values: &[f64], order: usize) -> Option<TransientFit> {
    let m = taus.len().min(values.len());
    let order = order.min(MAX_PARAMS - 1);
    if m < order + 2 {
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

/// One whitened design row and its value.
fn whitened_rows<'a>(
    taus: &'a [f64],
    values: &'a [f64],
    m: usize,
    kept: usize,
) -> impl Iterator<Item = ([f64; MAX_PARAMS], f64)> + 'a {
    let row = move |tau: f64| {
        let mut r = [0.0; MAX_PARAMS];
        r[0] = 1.0;
        let mut p = (-tau).exp();
        for v in r.iter_mut().skip(1).take(kept) {
            *v = p;
            p *= tau;
        }
        r
    };
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
    let rows: Vec<([f64; MAX_PARAMS], f64)> = whitened_rows(taus, values, m, kept).collect();
    let mut scale = [0.0; MAX_PARAMS];
    for (w, _) in &rows {
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
    // Columns of the scaled design, and the right-hand side, reduced in place.
    let mut a: Vec<[f64; MAX_PARAMS]> = rows
        .iter()
        .map(|(w, _)| {
            let mut r = [0.0; MAX_PARAMS];
            for j in 0..p {
                r[j] = w[j] / scale[j];
            }
            r
        })
        .collect();
    let mut y: Vec<f64> = rows.iter().map(|(_, y)| *y).collect();
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
    /// The averaged window's first snapshot, once the transient allows one.
    pub window_start: Option<usize>,
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
}

/// The sequential rule for one reading after a change: snapshots go in as they come
/// ([`push`](Self::push)); [`assess`](Self::assess) says whether the transient has
/// died out enough to average and whether the average is precise enough.
#[derive(Clone, Debug)]
pub struct Sequential {
    order: usize,
    snaps: Vec<Snap>,
    /// Fixed once the transient allows; never moved back.
    start: Option<usize>,
    /// Snapshots in the window so far.
    count: usize,
    /// Σ_{i,j ∈ window} e^(−|τᵢ − τⱼ|) and Σ_{i < last} e^(−(τ_last − τᵢ)).
    corr_sum: f64,
    tail: f64,
    /// Welford accumulators of R over the window.
    mean_r: f64,
    m2_r: f64,
    sum_x: f64,
    sum_y: f64,
    /// A change long enough ago that no step can still show (see [`Self::new`]).
    settled_before: bool,
}

impl Sequential {
    /// A reading of a filter with `order` stages (1 … 4); `first_tau` is when its first
    /// snapshot will be, in time constants since the change: at 60 time constants or
    /// more a step of 10¹⁵ times the value has decayed below it at 24 dB/oct, so no
    /// transient is fitted.
    pub fn new(order: usize, first_tau: f64) -> Self {
        Sequential {
            order: order.clamp(1, MAX_PARAMS - 1),
            snaps: Vec::new(),
            start: None,
            count: 0,
            corr_sum: 0.0,
            tail: 0.0,
            mean_r: 0.0,
            m2_r: 0.0,
            sum_x: 0.0,
            sum_y: 0.0,
            settled_before: step_residual(order.clamp(1, MAX_PARAMS - 1), first_tau) < 1e-15,
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

    /// The window's first snapshot, once fixed.
    pub fn window_start(&self) -> Option<usize> {
        self.start
    }

    /// A snapshot (X, Y) at `tau` time constants after the change.
    pub fn push(&mut self, tau: f64, x: f64, y: f64) {
        let r = x.hypot(y);
        self.snaps.push(Snap { tau, x, y, r });
        if self.start.is_some() {
            self.add_to_window(self.snaps.len() - 1);
        }
    }

    fn add_to_window(&mut self, k: usize) {
        let s = self.snaps[k];
        let n_before = self.count;
        self.count += 1;
        if n_before == 0 {
            self.tail = 0.0;
        } else {
            let prev = self.snaps[k - 1];
            self.tail = (-(s.tau - prev.tau).max(0.0)).exp() * (1.0 + self.tail);
        }
        self.corr_sum += 1.0 + 2.0 * self.tail;
        let n = (n_before + 1) as f64;
        let d = s.r - self.mean_r;
        self.mean_r += d / n;
        self.m2_r += d * (s.r - self.mean_r);
        self.sum_x += s.x;
        self.sum_y += s.y;
    }

    fn window_len(&self) -> usize {
        self.count
    }

    fn fix_window(&mut self, start: usize) {
        self.start = Some(start);
        for k in start..self.snaps.len() {
            self.add_to_window(k);
        }
    }

    /// Decides, after the latest snapshot: fixes the window when the transient allows
    /// (`noise` the snapshot variance at a signal R, when known), and says whether the
    /// window's mean meets `target`. Without a noise law the window's own scatter is
    /// used, corrected for its correlation, from [`MIN_OWN_SCATTER`] snapshots on.
    pub fn assess(
        &mut self,
        target: &ReadTarget,
        noise: Option<&dyn Fn(f64) -> f64>,
    ) -> Assessment {
        if self.start.is_none() {
            self.try_window(target, noise);
        }
        let n = self.window_len();
        if n == 0 {
            return Assessment {
                window_start: None,
                sigma_mean: f64::INFINITY,
                target: f64::INFINITY,
                done: false,
            };
        }
        let mean = self.mean_r;
        let goal = target.sigma(mean);
        let var = match noise {
            Some(f) => Some(f(mean)),
            None => self.own_variance(),
        };
        let sigma_mean = var.map_or(f64::INFINITY, |v| {
            (v.max(0.0) * self.corr_sum).sqrt() / n as f64
        });
        Assessment {
            window_start: self.start,
            sigma_mean,
            target: goal,
            done: sigma_mean <= goal && n >= target.min_samples.max(1),
        }
    }

    /// The snapshot variance the window's own scatter estimates: E[s²] = σ²(n − S/n)/(n − 1)
    /// for correlations summing to S, so σ̂² = s²(n − 1)/(n − S/n).
    fn own_variance(&self) -> Option<f64> {
        let n = self.window_len();
        if n < MIN_OWN_SCATTER {
            return None;
        }
        let nf = n as f64;
        let denom = nf - self.corr_sum / nf;
        (denom > 0.0).then(|| self.m2_r / denom)
    }

    fn try_window(&mut self, target: &ReadTarget, noise: Option<&dyn Fn(f64) -> f64>) {
        if self.snaps.is_empty() {
            return;
        }
        if self.settled_before {
            self.fix_window(0);
            return;
        }
        let taus: Vec<f64> = self.snaps.iter().map(|s| s.tau).collect();
        let rs: Vec<f64> = self.snaps.iter().map(|s| s.r).collect();
        let Some(fit) = fit_transient(&taus, &rs, self.order) else {
            return;
        };
        let var = match noise {
            Some(f) => f(fit.value),
            None => match fit.residual_variance() {
                Some(v) if fit.dof >= 2 => v,
                _ => return,
            },
        };
        let allowed = TRANSIENT_FRACTION * target.sigma(fit.value);
        // The largest bound from each snapshot to the last, scanning backwards.
        let mut worst = 0.0f64;
        let mut start = None;
        for (k, tau) in taus.iter().enumerate().rev() {
            let bound =
                fit.transient(*tau).abs() + 2.0 * (var * fit.transient_variance(*tau)).sqrt();
            worst = worst.max(bound);
            if worst <= allowed {
                start = Some(k);
            } else {
                break;
            }
        }
        if let Some(s) = start {
            self.fix_window(s);
        }
    }

    /// The window's means, or, when no window could be fixed (a capped reading), the
    /// later half of the snapshots.
    pub fn result(&mut self) -> Option<WindowMean> {
        if self.snaps.is_empty() {
            return None;
        }
        if self.start.is_none() {
            self.fix_window(self.snaps.len() / 2);
        }
        let n = self.window_len();
        let start = self.start?;
        let nf = n as f64;
        Some(WindowMean {
            r_mean: self.mean_r,
            r_std: if n > 1 {
                (self.m2_r / (nf - 1.0)).sqrt()
            } else {
                0.0
            },
            x_mean: self.sum_x / nf,
            y_mean: self.sum_y / nf,
            n,
            settle_tc: self.snaps[start].tau,
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

/// The expected time of a reading of `expected` V after a step of `step` V, at time
/// constant `tc` and `slope`, with `exchange_s` the time of one `SNAP?` exchange:
/// snapshots one time constant plus an exchange apart from [`FIRST_SNAPSHOT_TC`] on;
/// the window opens when the step's residual ([`step_residual`]) is under
/// [`TRANSIENT_FRACTION`] of the target and the transient's parameters have a
/// snapshot each; it holds as many snapshots as the noise needs, by the large-n sum
/// of first-order correlations, (1 + ρ)/(1 − ρ) per snapshot. The cap is not applied.
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
    let spacing_tc = 1.0 + exchange_s.max(0.0) / t;
    let order = usize::from(slope.index()) + 1;
    let goal = target.sigma(expected);
    let allowed = TRANSIENT_FRACTION * goal;
    let residual_tau = if step.abs() > allowed && goal > 0.0 {
        slope.settle_factor_for((allowed / step.abs()).min(0.5))
    } else {
        0.0
    };
    let fit_tau = FIRST_SNAPSHOT_TC + (order + 1) as f64 * spacing_tc;
    let settle_tc = residual_tau.max(fit_tau);
    let rho = (-spacing_tc).exp();
    let var = noise.snapshot_variance(expected, slope, tc);
    let per = (1.0 + rho) / (1.0 - rho);
    let needed = if goal > 0.0 {
        (var * per / (goal * goal)).ceil()
    } else {
        f64::INFINITY
    };
    let samples = needed.clamp(target.min_samples.max(1) as f64, 1e9) as usize;
    ReadEstimate {
        time_constant: tc,
        settle_s: settle_tc * t,
        averaging_s: (samples.saturating_sub(1)) as f64 * spacing_tc * t,
        samples,
    }
}

/// The time constant among `choices` that reads `expected` fastest ([`estimate`],
/// a step of the signal's own size assumed), with its estimate; `None` for no
/// choices.
pub fn choose_time_constant(
    expected: f64,
    target: &ReadTarget,
    noise: &NoiseDensity,
    slope: FilterSlope,
    choices: impl IntoIterator<Item = TimeConstant>,
    exchange_s: f64,
) -> Option<ReadEstimate> {
    choices
        .into_iter()
        .map(|tc| estimate(expected, expected, target, noise, slope, tc, exchange_s))
        .min_by(|a, b| a.total_s().total_cmp(&b.total_s()))
}
