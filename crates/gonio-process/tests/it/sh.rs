//! The spherical-harmonic representation against models and functions with known
//! answers: exact reciprocity, exact reproduction of what the basis spans, convergence
//! on a lobe, lossless files.

use std::f64::consts::PI;

use gonio_brdf::Model;
use gonio_core::rng::SplitMix64;
use gonio_core::{Channels, Dir};
use gonio_process::sh::{ShBrdf, ShOptions, basis_len};
use gonio_process::{Grid, Table};

/// Deterministic uniform numbers in [0, 1) (splitmix64).
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(SplitMix64::new(seed))
    }

    fn next(&mut self) -> f64 {
        self.0.next_u64() as f64 / 2f64.powi(64)
    }

    /// A direction strictly above the surface.
    fn dir(&mut self) -> Dir {
        let t = 0.001 + 0.998 * self.next();
        Dir::from_angles(t.acos(), 2.0 * PI * self.next())
    }
}

fn model(text: &str) -> Model {
    Model::from_toml(text, None).expect("a valid model file")
}

const LAFORTUNE: &str = r#"
kind = "lafortune"
channels = ["R", "G", "B"]
[diffuse]
rho = [0.3094, 0.39667, 0.70837]
[[lobes]]
cx = [0.870567, 0.857255, 0.670982]
cy = [0.870567, 0.857255, 0.670982]
cz = [0.803624, 0.774290, 0.586674]
n  = [21.820103, 18.597755, 7.472717]
"#;

/// Not reciprocal: the incident and outgoing directions play different parts. Every
/// term is a polynomial in x, y, z² of degree ≤ 2, so within the even basis at l = 2.
fn skewed(ch: usize, wi: Dir, wo: Dir) -> f64 {
    let (a, b) = (wi.vec(), wo.vec());
    (1.0 + a.z * a.z) * b.z * b.z + 0.3 * a.x * b.y + 0.1 * ch as f64 * a.x * a.x
}

/// Not reciprocal, and not in any finite even basis (cos θi is odd about the surface).
fn skewed_odd(_: usize, wi: Dir, wo: Dir) -> f64 {
    let (a, b) = (wi.vec(), wo.vec());
    (1.0 + a.z) * b.z * b.z + 0.3 * a.x * b.y
}

#[test]
fn sh_reciprocity_is_exact_for_a_non_reciprocal_input() {
    let ch = Channels::wavelengths(&[500.0, 600.0]).expect("channels");
    let sh = ShBrdf::project(ch, skewed_odd, &ShOptions::new(6)).expect("projection");
    let mut rng = Rng::new(7);
    let (mut u, mut v) = ([0.0; 2], [0.0; 2]);
    let mut largest_asymmetry_of_input: f64 = 0.0;
    for _ in 0..2000 {
        let (wi, wo) = (rng.dir(), rng.dir());
        sh.eval(wi, wo, &mut u);
        sh.eval(wo, wi, &mut v);
        // Bit for bit, hence also to 1e-12 relative.
        assert_eq!(u, v, "at {wi:?}, {wo:?}");
        largest_asymmetry_of_input =
            largest_asymmetry_of_input.max((skewed_odd(0, wi, wo) - skewed_odd(0, wo, wi)).abs());
    }
    assert!(largest_asymmetry_of_input > 0.5);
    for m in &sh.matrices {
        let k = sh.basis.len();
        for i in 0..k {
            for j in 0..k {
                assert_eq!(m[i * k + j], m[j * k + i]);
            }
        }
    }
}

#[test]
fn sh_symmetrisation_is_the_projection_of_the_reciprocal_part() {
    let opts = ShOptions::new(5);
    let sh = ShBrdf::project(Channels::Single, skewed, &opts).expect("projection");
    let rec = |ch, wi, wo| 0.5 * (skewed(ch, wi, wo) + skewed(ch, wo, wi));
    let sr = ShBrdf::project(Channels::Single, rec, &opts).expect("projection");
    let worst = sh.matrices[0]
        .iter()
        .zip(&sr.matrices[0])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-13, "{worst:e}");
    // The reciprocal part of this input lies in the span at l_max = 2, so the
    // representation equals it away from the nodes too.
    let mut rng = Rng::new(11);
    let mut out = [0.0];
    for _ in 0..200 {
        let (wi, wo) = (rng.dir(), rng.dir());
        sh.eval(wi, wo, &mut out);
        let want = rec(0, wi, wo);
        assert!((out[0] - want).abs() < 1e-12, "{} vs {want}", out[0]);
    }
}

#[test]
fn sh_a_lambertian_surface_is_exact_at_every_degree() {
    let m = model(
        r#"
        kind = "lambert"
        channels = ["R", "G", "B"]
        rho = [0.2, 0.5, 0.8]
        "#,
    );
    let table = Table::from_brdf(m.as_brdf(), Grid::hemisphere(9, 36)).expect("table");
    let rho = [0.2, 0.5, 0.8];
    let mut rng = Rng::new(3);
    let mut out = [0.0; 3];
    for l_max in [0, 1, 3, 8] {
        let sh = ShBrdf::from_table(&table, &ShOptions::new(l_max)).expect("projection");
        let err = sh.error_against(&table).expect("same channels");
        for ch in 0..3 {
            assert!(err.relative_rms[ch] < 1e-12, "l_max {l_max}: {err:?}");
            assert!(err.max_abs[ch] < 1e-12, "l_max {l_max}: {err:?}");
        }
        for _ in 0..50 {
            sh.eval(rng.dir(), rng.dir(), &mut out);
            for ch in 0..3 {
                assert!((out[ch] - rho[ch] / PI).abs() < 1e-13);
            }
        }
    }
    // One coefficient a channel at l_max = 0.
    let sh = ShBrdf::from_table(&table, &ShOptions::new(0)).expect("projection");
    assert_eq!(sh.coefficient_count(), 3);
}

#[test]
fn sh_a_finite_combination_of_even_harmonics_is_reproduced() {
    // cos²θ = (1 + 2 P_2(cos θ))/3 lies in the even basis at l = 2, so
    // a + b cos²θi cos²θo is exact from l_max = 2 on.
    let (a, b) = (0.15, 0.7);
    let f = |ch: usize, wi: Dir, wo: Dir| {
        let s = 1.0 + ch as f64;
        s * (a + b * wi.cos_theta().powi(2) * wo.cos_theta().powi(2))
    };
    let mut rng = Rng::new(5);
    for l_max in [2, 3, 6] {
        let sh = ShBrdf::project(Channels::Rgb, f, &ShOptions::new(l_max)).expect("projection");
        let mut out = [0.0; 3];
        let mut worst: f64 = 0.0;
        for _ in 0..500 {
            let (wi, wo) = (rng.dir(), rng.dir());
            sh.eval(wi, wo, &mut out);
            for (ch, o) in out.iter().enumerate() {
                worst = worst.max((o - f(ch, wi, wo)).abs());
            }
        }
        assert!(worst < 1e-12, "l_max {l_max}: {worst:e}");
    }
    // The smallest exact quadrature (l_max + 1 polar nodes) is enough.
    let opts = ShOptions::new(2).with_quadrature(3);
    let sh = ShBrdf::project(Channels::Rgb, f, &opts).expect("projection");
    let (wi, wo) = (rng.dir(), rng.dir());
    let mut out = [0.0; 3];
    sh.eval(wi, wo, &mut out);
    assert!((out[2] - f(2, wi, wo)).abs() < 1e-12);
    // Below the horizon, nothing.
    sh.eval(wi, wo.flip_z(), &mut out);
    assert_eq!(out, [0.0; 3]);
}

/// A Phong-like cosine lobe about the mirror direction over a weak diffuse term.
const MIRROR_LOBE: &str = r#"
kind = "lafortune"
channels = ["value"]
[diffuse]
rho = [0.1]
[[lobes]]
cx = [-1.0]
cy = [-1.0]
cz = [1.0]
n  = [10.0]
"#;

/// Relative RMS errors at the nodes of a 9 × 36 hemisphere table of `model_text`
/// for each degree, checked to fall monotonically. `from_model` projects the model
/// itself instead of the table's interpolant.
fn converge(model_text: &str, degrees: &[usize], from_model: bool) -> Vec<Vec<f64>> {
    let m = model(model_text);
    let table = Table::from_brdf(m.as_brdf(), Grid::hemisphere(9, 36)).expect("table");
    let nc = table.channels.len();
    let mut last = vec![f64::INFINITY; nc];
    let mut measured = Vec::new();
    for &l_max in degrees {
        let opts = ShOptions::new(l_max);
        let sh = if from_model {
            let f = |ch: usize, wi: Dir, wo: Dir| {
                let mut out = [0.0; 3];
                m.as_brdf().eval(wi, wo, &mut out[..nc]);
                out[ch]
            };
            ShBrdf::project(table.channels.clone(), f, &opts)
        } else {
            ShBrdf::from_table(&table, &opts)
        }
        .expect("projection");
        let err = sh.error_against(&table).expect("same channels");
        eprintln!(
            "{} l_max {l_max:2}: K = {:3}, {:6} coefficients ({:.4} of the table), \
             relative RMS {:.4?}, max abs {:.4?}",
            if from_model { "model" } else { "table" },
            basis_len(l_max),
            sh.coefficient_count(),
            sh.compression(&table),
            err.relative_rms,
            err.max_abs
        );
        for (ch, (e, l)) in err.relative_rms.iter().zip(&mut last).enumerate() {
            assert!(*e < *l, "l_max {l_max}, channel {ch}: {e} after {l}");
            *l = *e;
        }
        measured.push(err.relative_rms.clone());
    }
    measured
}

#[test]
fn sh_a_tabulated_mirror_lobe_converges_as_the_degree_grows() {
    let measured = converge(MIRROR_LOBE, &[2, 4, 8], false);
    // Measured 0.566, 0.269, 0.0446; bounds with ~10% margin. Beyond l_max = 8 the
    // error at the nodes stays near 0.045: the projection reproduces the table's
    // quadrilinear interpolant, which cuts the lobe's peak between 10° nodes.
    let bound = [0.62, 0.30, 0.050];
    for (got, want) in measured.iter().zip(bound) {
        assert!(got[0] < want, "{got:?} against {want}");
    }
}

#[test]
fn sh_a_mirror_lobe_projected_from_the_model_keeps_converging() {
    let measured = converge(MIRROR_LOBE, &[4, 8, 12, 16], true);
    // Measured 0.264, 0.0265, 0.0096, 0.0078; bounds with ~10% margin.
    let bound = [0.29, 0.029, 0.0106, 0.0086];
    for (got, want) in measured.iter().zip(bound) {
        assert!(got[0] < want, "{got:?} against {want}");
    }
}

#[test]
fn sh_a_measured_lafortune_fit_converges_as_the_degree_grows() {
    let measured = converge(LAFORTUNE, &[2, 4, 8], false);
    // Measured values with ~10% margin; the diffuse term dominates the RMS, so the
    // errors are small from the start.
    let bound = [
        [0.031, 0.028, 0.020],
        [0.022, 0.019, 0.0084],
        [0.0075, 0.0059, 0.0017],
    ];
    for (got, want) in measured.iter().zip(bound) {
        for ch in 0..3 {
            assert!(got[ch] < want[ch], "{got:?} against {want:?}");
        }
    }
}

#[test]
fn sh_a_degree_8_table_projection_stores_the_upper_triangle_per_channel() {
    // The speed of this projection is measured in benches/process.rs.
    let m = model(LAFORTUNE);
    let table = Table::from_brdf(m.as_brdf(), Grid::hemisphere(9, 36)).expect("table");
    let sh = ShBrdf::from_table(&table, &ShOptions::new(8)).expect("projection");
    assert_eq!(sh.coefficient_count(), 3 * 45 * 46 / 2);
}

#[test]
fn sh_filtering_damps_the_ringing_of_a_sharp_lobe() {
    // A narrow Phong-like lobe about the mirror direction: truncation rings and
    // goes negative; the taper trades some peak for less ringing.
    let lobe = |_: usize, wi: Dir, wo: Dir| {
        let r = wi.mirror().vec();
        let c = (r.x * wo.vec().x + r.y * wo.vec().y + r.z * wo.vec().z).max(0.0);
        c.powi(40)
    };
    let sharp = ShBrdf::project(Channels::Single, lobe, &ShOptions::new(8)).expect("sh");
    let soft =
        ShBrdf::project(Channels::Single, lobe, &ShOptions::new(8).with_filter(3)).expect("sh");
    assert_eq!(soft.l_filter, 3);
    let mut rng = Rng::new(17);
    let (mut a, mut b) = ([0.0], [0.0]);
    let (mut min_sharp, mut min_soft) = (0.0_f64, 0.0_f64);
    for _ in 0..20000 {
        let (wi, wo) = (rng.dir(), rng.dir());
        sharp.eval(wi, wo, &mut a);
        soft.eval(wi, wo, &mut b);
        min_sharp = min_sharp.min(a[0]);
        min_soft = min_soft.min(b[0]);
    }
    eprintln!("most negative value: unfiltered {min_sharp:.4}, filtered {min_soft:.4}");
    assert!(min_sharp < -0.05);
    assert!(min_soft > 0.5 * min_sharp);
}

#[test]
fn sh_an_isotropic_table_gives_the_same_representation_as_its_full_form() {
    let m = model(LAFORTUNE);
    let t = gonio_process::Axis::polar_midpoints(9);
    let iso = Table::from_brdf(
        m.as_brdf(),
        Grid::isotropic(t, gonio_process::Axis::full_turn(36), t),
    )
    .expect("table");
    let full = iso.to_full(36).expect("full");
    // 36 quadrature azimuths fall on the table's, where both interpolations are exact.
    let opts = ShOptions::new(4).with_quadrature(18);
    let a = ShBrdf::from_table(&iso, &opts).expect("sh");
    let b = ShBrdf::from_table(&full, &opts).expect("sh");
    for (ma, mb) in a.matrices.iter().zip(&b.matrices) {
        let worst = ma
            .iter()
            .zip(mb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst:e}");
    }
    let e = a.error_against(&iso).expect("channels");
    let f = b.error_against(&full).expect("channels");
    for ch in 0..3 {
        assert!((e.relative_rms[ch] - f.relative_rms[ch]).abs() < 1e-9);
    }
}

#[test]
fn sh_the_toml_file_round_trips_losslessly() {
    let opts = ShOptions::new(4).with_filter(2);
    let sh = ShBrdf::project(Channels::Rgb, skewed, &opts).expect("projection");
    let text = sh.to_toml();
    assert!(text.contains("kind = \"spherical-harmonics\""));
    let back = ShBrdf::from_toml(&text, None).expect("reads back");
    assert_eq!(back, sh);

    // Extreme magnitudes survive as well, up to the cap a file may hold
    // (gonio_process::MAX_MAGNITUDE, 1e100).
    let mut tiny = sh.clone();
    tiny.matrices[1][0] = 1.234_567_890_123_456_7e-300;
    tiny.matrices[1][1] = -9.87e99;
    tiny.matrices[1][basis_len(4)] = -9.87e99;
    let back = ShBrdf::from_toml(&tiny.to_toml(), None).expect("reads back");
    assert_eq!(back, tiny);
}

#[test]
fn sh_a_bad_file_names_its_field() {
    let sh = ShBrdf::project(Channels::Rgb, skewed, &ShOptions::new(2)).expect("projection");
    let text = sh.to_toml();
    let err = |t: &str| match ShBrdf::from_toml(t, None) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted:\n{t}"),
    };
    let e = err(&text.replace("spherical-harmonics", "lafortune"));
    assert!(e.contains("`kind`"), "{e}");
    let e = err(&text.replace("l_filter = 2", "l_filter = 3"));
    assert!(e.contains("`l_filter`"), "{e}");
    let e = err(&text.replace("channel = \"G\"", "channel = \"B\""));
    assert!(e.contains("`matrices[1].channel`"), "{e}");
    let e = err(&text.replace("l_max = 2", "l_max = 3"));
    assert!(e.contains("`matrices[0].upper`"), "{e}");
    let e = err(&text.replace("l_max = 2", "l_max = 2\nbogus = 1"));
    assert!(e.contains("bogus"), "{e}");
    let e = err(&text.replace("l_max = 2\n", ""));
    assert!(e.contains("l_max"), "{e}");
}

#[test]
fn sh_the_closed_form_albedo_is_the_cubature_of_the_representation() {
    // A representation with every kind of coefficient: the projection of a lobe model
    // at degree 8 (it rings, and has m ≠ 0 terms that must integrate to nothing).
    let m = model(LAFORTUNE);
    let f = |ch: usize, wi: Dir, wo: Dir| {
        let mut out = [0.0; 3];
        gonio_brdf::Brdf::eval(&m, wi, wo, &mut out);
        out[ch]
    };
    let sh = ShBrdf::project(Channels::Rgb, f, &ShOptions::new(8)).expect("projection");
    let (mut exact, mut numeric) = ([0.0; 3], [0.0; 3]);
    for theta in [0.0f64, 20.0, 45.0, 70.0, 89.0] {
        for phi in [0.0f64, 100.0] {
            let wi = Dir::from_angles(theta.to_radians(), phi.to_radians());
            gonio_brdf::Brdf::albedo(&sh, wi, &mut exact);
            gonio_brdf::albedo::numerical_into(&sh, wi, &mut numeric);
            for ch in 0..3 {
                assert!(
                    (exact[ch] - numeric[ch]).abs() <= 1e-8 * numeric[ch].abs().max(1e-3),
                    "θi {theta}, φi {phi}, channel {ch}: {} vs cubature {}",
                    exact[ch],
                    numeric[ch]
                );
            }
        }
    }
    // Below the horizon there is no albedo.
    gonio_brdf::Brdf::albedo(&sh, Dir::from_angles(2.0, 0.0), &mut exact);
    assert_eq!(exact, [0.0; 3]);
}

#[test]
fn sh_the_albedo_of_a_lambertian_surface_is_its_rho() {
    let rho = [0.2, 0.5, 0.8];
    let f = |ch: usize, _: Dir, _: Dir| rho[ch] / PI;
    let mut out = [0.0; 3];
    for l_max in [0, 2, 9] {
        let sh = ShBrdf::project(Channels::Rgb, f, &ShOptions::new(l_max)).expect("projection");
        for theta in [0.0f64, 30.0, 60.0, 85.0] {
            sh.albedo(Dir::from_angles(theta.to_radians(), 0.3), &mut out);
            for ch in 0..3 {
                assert!((out[ch] - rho[ch]).abs() < 1e-13, "l_max {l_max}: {out:?}");
            }
        }
    }
}

#[test]
fn sh_a_file_with_an_absurd_coefficient_is_refused_naming_it() {
    let sh = ShBrdf::project(Channels::Rgb, skewed, &ShOptions::new(2)).expect("projection");
    let text = sh.to_toml();
    // The first coefficient of the second channel's matrix made absurd.
    let at = text.find("channel = \"G\"").expect("G block");
    let open = at + text[at..].find("[\n").expect("upper") + 2;
    let end = open + text[open..].find(',').expect("a value");
    let bad = format!("{} 1e300{}", &text[..open + 1], &text[end..]);
    let e = ShBrdf::from_toml(&bad, None).expect_err("1e300 refused");
    assert!(
        e.to_string().contains(
            "field `matrices[1].upper`: value 0 (1e300) is larger in magnitude than 1e100"
        ),
        "{e}"
    );
}
