//! P_s^(k) (DeYoung Eq. 4.16–4.20) on tables large enough for the truncated SVD:
//! against the full SVD of the same matrix, and 0 for a separable table.

use gonio_core::Channels;
use gonio_process::measure::separability;
use gonio_process::{Axis, Grid, Table, svd};

/// 16 φ × 18 θ nodes on each side: A is 288 × 288, over the truncation threshold.
fn grid() -> Grid {
    Grid::full(
        Axis::full_turn(16),
        Axis::polar_midpoints(18),
        Axis::full_turn(16),
        Axis::polar_midpoints(18),
    )
}

fn table(f: impl Fn([f64; 4]) -> f64) -> Table {
    let g = grid();
    let values = (0..g.len()).map(|i| f(g.angles(i))).collect();
    Table::new(Channels::Single, g, values, None).expect("table")
}

/// A glossy lobe about the mirror direction: far from separable.
fn lobe([pi, ti, po, to]: [f64; 4]) -> f64 {
    let wi = [ti.sin() * pi.cos(), ti.sin() * pi.sin(), ti.cos()];
    let wo = [to.sin() * po.cos(), to.sin() * po.sin(), to.cos()];
    let r = [-wi[0], -wi[1], wi[2]];
    let c: f64 = r.iter().zip(&wo).map(|(a, b)| a * b).sum();
    0.1 + c.max(0.0).powi(8)
}

#[test]
fn truncated_p_s_equals_the_full_svd_s() {
    let t = table(lobe);
    let ks = [1, 2, 5, 10];
    let sep = separability(&t, &ks).expect("P_s");
    assert_eq!(sep[0].singular_values.len(), 10, "only the leading values");
    let (p, q) = (t.grid.n_in(), t.grid.n_out());
    let a = faer::Mat::from_fn(p, q, |r, c| t.values[r * q + c]);
    let full = svd::full(a.as_ref()).expect("full SVD");
    let n = t.grid.len() as f64;
    for (j, &k) in ks.iter().enumerate() {
        let want = (full.values.iter().skip(k).map(|s| s * s).sum::<f64>() / n).sqrt();
        let got = sep[0].p_s[j].1;
        assert!(
            (got - want).abs() <= 1e-9 * want,
            "P_s^({k}): {got} vs {want}"
        );
        assert!(got > 1e-3, "the lobe is not separable: {got}");
    }
    for (x, y) in sep[0].singular_values.iter().zip(&full.values) {
        assert!((x - y).abs() <= 1e-10 * full.values[0]);
    }
}

#[test]
fn a_separable_table_has_p_s_zero() {
    // f = g(ωi) h(ωo) (Eq. 4.13 of rank 1); f + 0.5 g2 h2 is of rank 2.
    let g = |pi: f64, ti: f64| 1.0 + ti.cos() + 0.1 * pi.sin();
    let h = |po: f64, to: f64| 0.2 + to.cos().powi(2) + 0.1 * po.cos();
    let t = table(|[pi, ti, po, to]| g(pi, ti) * h(po, to));
    let sep = separability(&t, &[1, 3]).expect("P_s");
    assert_eq!(
        sep[0].singular_values.len(),
        3,
        "truncated, not the full SVD"
    );
    let rms = (t.values.iter().map(|v| v * v).sum::<f64>() / t.values.len() as f64).sqrt();
    assert!(sep[0].p_s[0].1 <= 1e-12 * rms, "{:?}", sep[0].p_s);
    let t2 = table(|[pi, ti, po, to]| g(pi, ti) * h(po, to) + 0.5 * ti.sin() * to.sin());
    let sep = separability(&t2, &[1, 2, 3]).expect("P_s");
    assert!(sep[0].p_s[0].1 > 1e-3 * rms, "rank 2 is not separable");
    assert!(sep[0].p_s[1].1 <= 1e-12 * rms, "{:?}", sep[0].p_s);
}
