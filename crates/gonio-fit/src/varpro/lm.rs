//! The Levenberg–Marquardt driver: the projected problem compressed to P + 1 rows
//! as the `levenberg-marquardt` crate sees it, and the searches.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

use super::eval::{ChannelConstraint, Evaluation, Full, evaluate_prepared};
use super::{Basis, Prepared};
use crate::data::FitData;

/// Levenberg–Marquardt's view of JᵀJ and Jᵀr: a (P + 1) × P Jacobian R and residual
/// r̃ with RᵀR = JᵀJ, Rᵀr̃ = Jᵀr and ‖r̃‖² = Σr². Every quantity the crate's steps
/// and tests use (gradient, column norms, predicted and actual reductions) is the
/// same as for the m-row problem, at O(P²) memory instead of O(mP).
fn compress(jtj: &[f64], jtr: &[f64], cost: f64, p: usize) -> (DVector<f64>, DMatrix<f64>) {
    if p == 0 {
        return (
            DVector::from_element(1, cost.max(0.0).sqrt()),
            DMatrix::zeros(1, 0),
        );
    }
    // Equilibrate (unit diagonal) before the eigen-decomposition: columns differ by
    // many orders of magnitude.
    let d: Vec<f64> = (0..p)
        .map(|a| {
            let x = jtj[a * p + a];
            if x > 0.0 && x.is_finite() {
                x.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let s = DMatrix::from_fn(p, p, |a, b| {
        if d[a] > 0.0 && d[b] > 0.0 {
            jtj[a * p + b] / (d[a] * d[b])
        } else {
            0.0
        }
    });
    let eig = s.symmetric_eigen();
    let mut r = DMatrix::zeros(p + 1, p);
    let mut rt = DVector::zeros(p + 1);
    let mut explained = 0.0;
    for e in 0..p {
        let lam = eig.eigenvalues[e];
        if lam <= 1e-15 * p as f64 {
            continue;
        }
        let sl = lam.sqrt();
        let q = eig.eigenvectors.column(e);
        // Row e of R = √λ qᵀ D; r̃_e = qᵀ D⁻¹ Jᵀr / √λ.
        let mut proj = 0.0;
        for a in 0..p {
            r[(e, a)] = sl * q[a] * d[a];
            if d[a] > 0.0 {
                proj += q[a] * jtr[a] / d[a];
            }
        }
        rt[e] = proj / sl;
        explained += rt[e] * rt[e];
    }
    rt[p] = (cost - explained).max(0.0).sqrt();
    (rt, r)
}

/// The projected problem as the `levenberg-marquardt` crate sees it: compressed to
/// P + 1 rows (see `compress`).
pub struct Projected<'a> {
    basis: &'a dyn Basis,
    prep: Prepared<'a>,
    theta: DVector<f64>,
    /// The compressed Jacobian computed with the last residuals (the crate asks for
    /// it at the point it has just accepted, so one pass serves both).
    cached: std::sync::Mutex<Option<(Vec<f64>, DMatrix<f64>)>>,
    /// θ and the evaluation with the smallest cost yet (where the crate ends).
    last: std::sync::Mutex<Option<(Vec<f64>, Evaluation)>>,
}

impl<'a> Projected<'a> {
    /// The problem at a starting θ.
    pub fn new(basis: &'a dyn Basis, data: &'a FitData, theta: &[f64]) -> Self {
        Projected {
            basis,
            prep: Prepared::new(data),
            theta: DVector::from_column_slice(theta),
            cached: std::sync::Mutex::new(None),
            last: std::sync::Mutex::new(None),
        }
    }

    fn compressed(&self) -> Option<(DVector<f64>, DMatrix<f64>)> {
        let mut e = evaluate_prepared(self.basis, &self.prep, self.theta.as_slice(), true);
        let (jtj, jtr) = e.normal.take()?;
        let finite = e.cost.is_finite() && jtj.iter().chain(&jtr).all(|x| x.is_finite());
        let out = finite.then(|| compress(&jtj, &jtr, e.cost, self.basis.n_params()));
        if let Ok(mut l) = self.last.lock() {
            if finite && l.as_ref().is_none_or(|b| e.cost <= b.1.cost) {
                if let Some((_, old)) = l.replace((self.theta.as_slice().to_vec(), e)) {
                    self.prep.give_back(old);
                }
            } else {
                self.prep.give_back(e);
            }
        }
        out
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Projected<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let (r, j) = self.compressed()?;
        if let Ok(mut c) = self.cached.lock() {
            *c = Some((self.theta.as_slice().to_vec(), j));
        }
        Some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let cached = self
            .cached
            .lock()
            .ok()
            .and_then(|mut c| c.take())
            .filter(|(t, _)| t.as_slice() == self.theta.as_slice())
            .map(|(_, j)| j);
        match cached {
            Some(j) => Some(j),
            None => self.compressed().map(|x| x.1),
        }
    }
}

/// The outcome of one Levenberg–Marquardt search.
pub struct Solved {
    /// The non-linear parameters.
    pub theta: Vec<f64>,
    /// The linear coefficients per channel.
    pub coef: Vec<Vec<f64>>,
    /// Sum of squared residuals.
    pub cost: f64,
    /// Residual evaluations the search made.
    pub evaluations: usize,
    /// Why it stopped.
    pub termination: TerminationReason,
    /// Residuals and Gram matrices at θ (for the standard errors).
    pub full: Full,
    /// Under the energy constraint: per channel, the albedo and multiplier at each
    /// limit direction at θ (empty without it).
    pub constraints: Vec<ChannelConstraint>,
}

/// Minimises the projected problem from `theta` to full precision (relative cost
/// reduction 1e-10, relative step 1e-8): far below χ²'s own statistical spread,
/// √(2/N) relative.
pub fn solve(basis: &dyn Basis, data: &FitData, theta: &[f64], patience: usize) -> Solved {
    solve_to(basis, data, theta, patience, 1e-10)
}

/// [`solve`] stopping once a step reduces the cost by less than `ftol` relative (and
/// moves θ by less than 100 `ftol`): the start search's refinements need a basin, not
/// its last digits, which the final refinement supplies.
pub fn solve_to(
    basis: &dyn Basis,
    data: &FitData,
    theta: &[f64],
    patience: usize,
    ftol: f64,
) -> Solved {
    solve_with(basis, data, theta, patience, ftol, None)
}

/// [`solve_to`] with the directional albedo held ≤ 1 at the incident directions
/// `limits` (every θ's linear coefficients then solve the constrained problem exactly,
/// [`qp`](super::qp), and Levenberg–Marquardt searches θ on the constrained projected
/// cost); `None` is [`solve_to`].
pub fn solve_with(
    basis: &dyn Basis,
    data: &FitData,
    theta: &[f64],
    patience: usize,
    ftol: f64,
    limits: Option<Vec<[f64; 3]>>,
) -> Solved {
    if basis.n_params() == 0 {
        // Nothing non-linear (a Lambertian fit): the projection is the whole answer.
        let mut prep = Prepared::new(data);
        prep.limits = limits;
        let e = evaluate_prepared(basis, &prep, theta, true);
        return Solved {
            theta: theta.to_vec(),
            coef: e.coef,
            cost: e.cost,
            evaluations: 1,
            termination: TerminationReason::Converged {
                ftol: true,
                xtol: true,
            },
            full: e.full.unwrap_or(Full {
                residuals: Vec::new(),
                grams: Vec::new(),
            }),
            constraints: e.constraints,
        };
    }
    let lm = LevenbergMarquardt::new()
        .with_patience(patience)
        .with_ftol(ftol)
        .with_xtol((100.0 * ftol).max(1e-10))
        .with_gtol(1e-12);
    let mut start = Projected::new(basis, data, theta);
    start.prep.limits = limits;
    let (problem, report) = lm.minimize(start);
    let theta = problem.theta.as_slice().to_vec();
    // The crate leaves θ at an accepted point, whose evaluation is usually kept.
    let kept = problem
        .last
        .lock()
        .ok()
        .and_then(|mut l| l.take())
        .filter(|(t, _)| *t == theta)
        .map(|x| x.1);
    let e = kept.unwrap_or_else(|| evaluate_prepared(basis, &problem.prep, &theta, true));
    Solved {
        theta,
        coef: e.coef,
        cost: e.cost,
        evaluations: report.number_of_evaluations,
        termination: report.termination,
        full: e.full.unwrap_or(Full {
            residuals: Vec::new(),
            grams: Vec::new(),
        }),
        constraints: e.constraints,
    }
}
