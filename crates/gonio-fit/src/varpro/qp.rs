//! The linear part under the energy constraint: min ‖A c − b‖² subject to c ≥ 0 and
//! B c ≤ 1, a small convex quadratic programme solved exactly as Lawson & Hanson
//! (*Solving Least Squares Problems*, Ch. 23) do: least squares with inequality
//! constraints turned into a least-distance problem, solved by non-negative least
//! squares ([`nnls`]) — robust where adjacent incidences give nearly parallel rows.

use nalgebra::{DMatrix, DVector};

use super::nnls::nnls;

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
    /// Per row of B: whether it binds with a positive multiplier.
    pub row_active: Vec<bool>,
}

/// Solves min ½cᵀGc − hᵀc subject to c ≥ 0 and B c ≤ 1 (`b` row-major, `rows` × `k`),
/// from the normal equations G = AᵀA, h = Aᵀb. Columns are equilibrated as in
/// [`nnls`] (unit diagonal, the same 1e-13 ridge); a column with a zero diagonal stays
/// at 0. With G = RᵀR and f = R⁻ᵀh the cost is ½‖Rc − f‖² + const; z = Rc − f turns
/// the constraints C c ≥ d (C = [I; −B], d = [0; −1]) into Ĉ z ≥ d̂ with Ĉ = C R⁻¹,
/// d̂ = d − Ĉ f, and the least-distance z is Ĉᵀu / (1 − d̂ᵀu) with u ≥ 0 minimising
/// ‖Ĉᵀu‖² + (d̂ᵀu − 1)² (Lawson & Hanson Alg. 23.27); u / (1 − d̂ᵀu) are the
/// multipliers.
pub fn qp(g: &[f64], h: &[f64], k: usize, b: &[f64], rows: usize) -> QpSolution {
    let d: Vec<f64> = (0..k).map(|i| g[i * k + i].max(0.0).sqrt()).collect();
    let idx: Vec<usize> = (0..k).filter(|&i| d[i] > 0.0 && d[i].is_finite()).collect();
    let n = idx.len();
    let zero = QpSolution {
        c: vec![0.0; k],
        at_bound: vec![true; k],
        multiplier: vec![0.0; rows],
        row_active: vec![false; rows],
    };
    if n == 0 {
        return zero;
    }
    let gs = DMatrix::from_fn(n, n, |x, y| {
        g[idx[x] * k + idx[y]] / (d[idx[x]] * d[idx[y]]) + if x == y { 1e-13 } else { 0.0 }
    });
    let hs = DVector::from_fn(n, |x, _| h[idx[x]] / d[idx[x]]);
    let Some(chol) = gs.cholesky() else {
        return zero;
    };
    let l = chol.l();
    // R = Lᵀ; f = R⁻ᵀ h = L⁻¹ h; R⁻¹ = (Lᵀ)⁻¹.
    let Some(f) = l.solve_lower_triangular(&hs) else {
        return zero;
    };
    let Some(rinv) = l
        .transpose()
        .solve_upper_triangular(&DMatrix::identity(n, n))
    else {
        return zero;
    };
    let m = n + rows;
    let con = DMatrix::from_fn(m, n, |r, x| {
        if r < n {
            if r == x { 1.0 } else { 0.0 }
        } else {
            -b[(r - n) * k + idx[x]] / d[idx[x]]
        }
    });
    let rhs = DVector::from_fn(m, |r, _| if r < n { 0.0 } else { -1.0 });
    let ch = &con * &rinv;
    let dh = rhs - &ch * &f;
    // The normal equations of min ‖[Ĉᵀ; d̂ᵀ] u − e‖, u ≥ 0.
    let gram = &ch * ch.transpose() + &dh * dh.transpose();
    let gv: Vec<f64> = (0..m * m).map(|i| gram[(i / m, i % m)]).collect();
    let hv: Vec<f64> = dh.iter().copied().collect();
    let u = DVector::from_vec(nnls(&gv, &hv, m));
    let denom = 1.0 - dh.dot(&u);
    if denom <= 1e-300 || !denom.is_finite() {
        // Infeasible, which c = 0 never is: numerics; 0 is safe.
        return zero;
    }
    let z = ch.transpose() * &u / denom;
    let x = &rinv * (z + f);
    let mut c = vec![0.0; k];
    for (j, &i) in idx.iter().enumerate() {
        c[i] = (x[j] / d[i]).max(0.0);
    }
    // Rounding can leave a row a few ulp above 1: scale back onto it.
    let worst = (0..rows)
        .map(|r| (0..k).map(|i| b[r * k + i] * c[i]).sum::<f64>())
        .fold(0.0, f64::max);
    if worst > 1.0 {
        c.iter_mut().for_each(|v| *v /= worst);
    }
    let mu: Vec<f64> = u.iter().map(|v| v / denom).collect();
    let mut at_bound = vec![true; k];
    for (j, &i) in idx.iter().enumerate() {
        at_bound[i] = mu[j] > 0.0 || c[i] == 0.0;
    }
    QpSolution {
        c,
        at_bound,
        // Multipliers of the ½-cost; the cost ‖Ac − b‖² has twice them.
        multiplier: (0..rows).map(|r| 2.0 * mu[n + r]).collect(),
        row_active: (0..rows).map(|r| mu[n + r] > 0.0).collect(),
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
