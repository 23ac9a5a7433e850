//! Non-negative least squares on the normal equations (Lawson & Hanson).

use nalgebra::{DMatrix, DVector};

/// Solves min ‖A c − b‖ with c ≥ 0 from the normal equations G = AᵀA, h = Aᵀb
/// (Lawson & Hanson's active-set method); K is a handful, so this is exact and cheap.
/// The columns are equilibrated first (unit diagonal): a sharp lobe's column can be
/// 10⁻¹³ of the diffuse one's and still carry a strength of 10¹³.
pub fn nnls(g: &[f64], h: &[f64], k: usize) -> Vec<f64> {
    let dscale: Vec<f64> = (0..k).map(|i| g[i * k + i].max(0.0).sqrt()).collect();
    let usable: Vec<bool> = dscale.iter().map(|d| *d > 0.0 && d.is_finite()).collect();
    let gs = |i: usize, j: usize| g[i * k + j] / (dscale[i] * dscale[j]);
    let hs = |i: usize| h[i] / dscale[i];
    let mut free = vec![false; k];
    let mut c = vec![0.0; k];
    let solve_free = |free: &[bool]| -> Vec<f64> {
        let idx: Vec<usize> = (0..k).filter(|&i| free[i]).collect();
        let n = idx.len();
        let mut out = vec![0.0; k];
        if n == 0 {
            return out;
        }
        // A tiny ridge keeps collinear columns (two identical lobes) solvable.
        let m = DMatrix::from_fn(n, n, |a, b| {
            gs(idx[a], idx[b]) + if a == b { 1e-13 } else { 0.0 }
        });
        let r = DVector::from_fn(n, |a, _| hs(idx[a]));
        let x = m
            .clone()
            .cholesky()
            .map(|ch| ch.solve(&r))
            .or_else(|| m.lu().solve(&r))
            .unwrap_or_else(|| DVector::zeros(n));
        for (a, &i) in idx.iter().enumerate() {
            out[i] = x[a];
        }
        out
    };
    for _outer in 0..3 * k + 3 {
        // The negative gradient of ½‖Ac − b‖² in the equilibrated variables.
        let w: Vec<f64> = (0..k)
            .map(|i| {
                if usable[i] {
                    hs(i)
                        - (0..k)
                            .filter(|&j| usable[j])
                            .map(|j| gs(i, j) * c[j])
                            .sum::<f64>()
                } else {
                    0.0
                }
            })
            .collect();
        let tol = 1e-12
            * (0..k)
                .filter(|&i| usable[i])
                .map(|i| hs(i).abs())
                .fold(1e-300, f64::max);
        let pick = (0..k)
            .filter(|&i| usable[i] && !free[i] && w[i] > tol)
            .max_by(|&a, &b| w[a].total_cmp(&w[b]));
        let Some(j) = pick else { break };
        free[j] = true;
        loop {
            let z = solve_free(&free);
            if (0..k).all(|i| !free[i] || z[i] > 0.0) {
                c = z;
                break;
            }
            // Step back to the first coefficient that reaches 0 and drop it.
            let mut alpha = 1.0f64;
            for i in 0..k {
                if free[i] && z[i] <= 0.0 {
                    alpha = alpha.min(c[i] / (c[i] - z[i]));
                }
            }
            for i in 0..k {
                c[i] += alpha * (z[i] - c[i]);
                if free[i] && c[i] <= 1e-300 {
                    free[i] = false;
                    c[i] = 0.0;
                }
            }
        }
    }
    (0..k)
        .map(|i| if usable[i] { c[i] / dscale[i] } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nnls_matches_the_constrained_optimum() {
        // Columns e1, e2, (e1 + e2)/√2 in 2-D: b = (1, −1) is best fit by c = (1, 0, 0).
        let a = [
            [1.0, 0.0, std::f64::consts::FRAC_1_SQRT_2],
            [0.0, 1.0, std::f64::consts::FRAC_1_SQRT_2],
        ];
        let b = [1.0, -1.0];
        let k = 3;
        let mut g = vec![0.0; 9];
        let mut h = vec![0.0; 3];
        for u in 0..k {
            for r in 0..2 {
                h[u] += a[r][u] * b[r];
                for v in 0..k {
                    g[u * k + v] += a[r][u] * a[r][v];
                }
            }
        }
        let c = nnls(&g, &h, k);
        assert!(
            (c[0] - 1.0).abs() < 1e-12 && c[1] == 0.0 && c[2] == 0.0,
            "{c:?}"
        );
        // Unconstrained optimum inside the orthant is returned as is.
        let c = nnls(&[2.0, 0.0, 0.0, 3.0], &[4.0, 6.0], 2);
        assert!((c[0] - 2.0).abs() < 1e-12 && (c[1] - 2.0).abs() < 1e-12);
    }
}
