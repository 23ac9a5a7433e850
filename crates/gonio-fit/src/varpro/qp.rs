//! The linear part under the energy constraint: min ‖A c − b‖² subject to c ≥ 0 and
//! B c ≤ 1, a small convex quadratic programme solved exactly by a primal active-set
//! method (Nocedal & Wright, *Numerical Optimization*, Algorithm 16.3) on the normal
//! equations.

use nalgebra::{DMatrix, DVector};

/// The solution of [`qp`] and its active set.
#[derive(Clone, Debug, PartialEq)]
pub struct QpSolution {
    /// The coefficients.
    pub c: Vec<f64>,
    /// Per coefficient: whether its bound c ≥ 0 is active (held at 0).
    pub at_bound: Vec<bool>,
    /// Per row of B: the Lagrange multiplier of B c ≤ 1 for the cost ‖A c − b‖²,
    /// i.e. how much the cost would fall per unit the bound 1 were raised; 0 where the
    /// row is inactive.
    pub multiplier: Vec<f64>,
    /// Per row of B: whether it is in the final active set.
    pub row_active: Vec<bool>,
}

/// Solves min ½cᵀGc − hᵀc subject to c ≥ 0 and B c ≤ 1 (`b` row-major, `rows` × `k`),
/// from the normal equations G = AᵀA, h = Aᵀb. Columns are equilibrated as in
/// [`nnls`](super::nnls) (unit diagonal); a column with a zero diagonal stays at 0. The
/// start c = 0 is feasible, and every iterate stays feasible.
pub fn qp(g: &[f64], h: &[f64], k: usize, b: &[f64], rows: usize) -> QpSolution {
    let d: Vec<f64> = (0..k).map(|i| g[i * k + i].max(0.0).sqrt()).collect();
    let usable: Vec<bool> = d.iter().map(|x| *x > 0.0 && x.is_finite()).collect();
    let gs = DMatrix::from_fn(k, k, |i, j| {
        if usable[i] && usable[j] {
            g[i * k + j] / (d[i] * d[j]) + if i == j { 1e-13 } else { 0.0 }
        } else if i == j {
            1.0
        } else {
            0.0
        }
    });
    let hs = DVector::from_fn(k, |i, _| if usable[i] { h[i] / d[i] } else { 0.0 });
    // Constraint i < k: −x_i ≤ 0; constraint k + l: (B D⁻¹)_l x ≤ 1.
    let n_con = k + rows;
    let a_row = |ci: usize| -> DVector<f64> {
        if ci < k {
            let mut v = DVector::zeros(k);
            v[ci] = -1.0;
            v
        } else {
            let l = ci - k;
            DVector::from_fn(k, |u, _| if usable[u] { b[l * k + u] / d[u] } else { 0.0 })
        }
    };
    let rhs = |ci: usize| if ci < k { 0.0 } else { 1.0 };
    let mut x = DVector::<f64>::zeros(k);
    let mut work: Vec<usize> = (0..k).collect();
    let mut lambda = vec![0.0; n_con];
    for _ in 0..100 + 10 * n_con {
        // min ½pᵀGp + gᵀp subject to a_iᵀp = 0 on the working set: the KKT system.
        let grad = &gs * &x - &hs;
        let m = work.len();
        let mut kkt = DMatrix::<f64>::zeros(k + m, k + m);
        let mut r = DVector::<f64>::zeros(k + m);
        kkt.view_mut((0, 0), (k, k)).copy_from(&gs);
        for (wi, &ci) in work.iter().enumerate() {
            let a = a_row(ci);
            for u in 0..k {
                kkt[(k + wi, u)] = a[u];
                kkt[(u, k + wi)] = a[u];
            }
        }
        for u in 0..k {
            r[u] = -grad[u];
        }
        let Some(sol) = kkt.lu().solve(&r) else {
            break;
        };
        let p = sol.rows(0, k).into_owned();
        let scale = 1.0 + x.amax();
        if p.amax() <= 1e-13 * scale {
            lambda.fill(0.0);
            for (wi, &ci) in work.iter().enumerate() {
                lambda[ci] = sol[k + wi];
            }
            // The most negative multiplier leaves the working set; none: optimal.
            let worst = work
                .iter()
                .enumerate()
                .filter(|(_, ci)| usable.get(**ci).is_none_or(|u| *u))
                .map(|(wi, &ci)| (wi, lambda[ci]))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match worst {
                Some((wi, l)) if l < -1e-12 * (1.0 + hs.amax()) => {
                    lambda[work[wi]] = 0.0;
                    work.remove(wi);
                }
                _ => break,
            }
            continue;
        }
        // The longest step along p that keeps every constraint satisfied.
        let mut alpha = 1.0;
        let mut blocking = None;
        for ci in 0..n_con {
            if work.contains(&ci) {
                continue;
            }
            let a = a_row(ci);
            let ap = a.dot(&p);
            if ap > 1e-300 {
                let step = (rhs(ci) - a.dot(&x)) / ap;
                if step < alpha {
                    alpha = step.max(0.0);
                    blocking = Some(ci);
                }
            }
        }
        x += alpha * &p;
        if let Some(ci) = blocking {
            work.push(ci);
        }
    }
    let c: Vec<f64> = (0..k)
        .map(|u| {
            if usable[u] {
                (x[u] / d[u]).max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    // Multipliers of the ½-cost; the cost ‖Ac − b‖² has twice them.
    QpSolution {
        at_bound: (0..k).map(|u| work.contains(&u) || c[u] == 0.0).collect(),
        multiplier: (0..rows).map(|l| 2.0 * lambda[k + l].max(0.0)).collect(),
        row_active: (0..rows).map(|l| work.contains(&(k + l))).collect(),
        c,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_binding_row_is_met_with_its_multiplier() {
        // min (c0 − 2)² + (c1 − 2)² subject to c0 + c1 ≤ 1: c = (½, ½), and the cost
        // 2(c − 2)² at c0 = c1 = t = s/2 falls by 2 (2 − s/2) = 3 per unit of the bound s.
        let s = qp(&[1.0, 0.0, 0.0, 1.0], &[2.0, 2.0], 2, &[1.0, 1.0], 1);
        assert!(
            (s.c[0] - 0.5).abs() < 1e-12 && (s.c[1] - 0.5).abs() < 1e-12,
            "{s:?}"
        );
        assert!((s.multiplier[0] - 3.0).abs() < 1e-9, "{s:?}");
        assert!(s.row_active[0]);
        // A row the unconstrained optimum satisfies changes nothing.
        let s = qp(&[1.0, 0.0, 0.0, 1.0], &[2.0, 2.0], 2, &[0.1, 0.1], 1);
        assert!((s.c[0] - 2.0).abs() < 1e-12 && (s.c[1] - 2.0).abs() < 1e-12);
        assert_eq!(s.multiplier[0], 0.0);
        // With a bound active too: min (c0 + 1)² + (c1 − 3)², c1 ≤ 1 → c = (0, 1).
        let s = qp(&[1.0, 0.0, 0.0, 1.0], &[-1.0, 3.0], 2, &[0.0, 1.0], 1);
        assert!(s.c[0] == 0.0 && (s.c[1] - 1.0).abs() < 1e-12, "{s:?}");
        assert!(s.at_bound[0] && (s.multiplier[0] - 4.0).abs() < 1e-9);
    }
}
