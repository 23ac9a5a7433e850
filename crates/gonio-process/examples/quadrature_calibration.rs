//! How well the albedos' stated quadrature σ matches their real error, on materials
//! other than the tests' hidden ones: the shipped models and families of
//! Cook–Torrance (GGX and Beckmann, α 0.1–0.5, two diffuse levels) and Ward (α
//! 0.06–0.4), each at the directions `config/plan-hemisphere.toml` measures (the
//! triangulated form) and on 10° × 15° polar band midpoints (DeYoung's sum, θi up to
//! 75°), without noise. Prints every |z| above 2.5 (σ taken at least 1e-12 of the
//! albedo, its rounding) and the distribution of |z| =
//! |albedo − truth| / σ_quad: a σ that fits has a mean z² near 1.
//!
//! `cargo run -p gonio-process --profile ci --example quadrature_calibration`

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, Dir, SphericalDeg};
use gonio_process::{Grid, Sample, Samples, Table, hemisphere, measure};

/// The σ below which an albedo's error is rounding (a rotationally symmetric BRDF at
/// normal incidence integrates exactly, and both its error and its σ are a few ulp).
const ROUNDING: f64 = 1e-12;

fn steps(from: f64, to: f64, step: f64) -> Vec<f64> {
    let n = ((to - from) / step).round() as usize;
    (0..=n).map(|k| from + k as f64 * step).collect()
}

/// (name, model file text) of every material measured.
fn materials() -> Vec<(String, String)> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/models");
    let mut out: Vec<(String, String)> = [
        "blinn-phong-plastic",
        "cook-torrance-gold",
        "lafortune-fig9",
        "minnaert-matte",
        "oren-nayar-plaster",
        "phong-shading",
        "conventions-example",
    ]
    .iter()
    .map(|f| {
        let text = std::fs::read_to_string(format!("{root}/{f}.toml")).expect("shipped model");
        (f.to_string(), text)
    })
    .collect();
    for d in ["ggx", "beckmann"] {
        for a in [0.1, 0.15, 0.2, 0.3, 0.5] {
            for rd in [0.02, 0.3] {
                out.push((
                    format!("cook-torrance {d} α {a} ρd {rd}"),
                    format!(
                        "kind = \"cook-torrance\"\nchannels = [\"value\"]\ndistribution = \
                         \"{d}\"\nf0 = [0.04]\nalpha = [{a}]\n[diffuse]\nrho = [{rd}]"
                    ),
                ));
            }
        }
    }
    for a in [0.06, 0.12, 0.25, 0.4] {
        out.push((
            format!("ward α {a}"),
            format!(
                "kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.1]\nalpha_x = [{a}]\n\
                 alpha_y = [{a}]\n[diffuse]\nrho = [0.2]"
            ),
        ));
    }
    out
}

/// The first channel's albedo of `m` at θi.
fn truth(m: &Model, ti: f64) -> f64 {
    let mut a = vec![0.0; m.channels().len()];
    m.albedo(Dir::from(SphericalDeg::new(ti, 0.0)), &mut a);
    a[0]
}

/// Count, median, 90th percentile, largest and mean square of |z|, and how many σ
/// exceed 10% of their albedo.
fn summary(name: &str, z: &mut [f64], large: usize) {
    z.sort_by(f64::total_cmp);
    let n = z.len();
    println!(
        "{name}: {n} albedos, |z| median {:.2}, 90% {:.2}, largest {:.2}, mean z² {:.2}; \
         σ above 10% of the albedo: {large}",
        z[n / 2],
        z[n * 9 / 10],
        z[n - 1],
        z.iter().map(|x| x * x).sum::<f64>() / n as f64
    );
}

fn main() {
    let (mut zt, mut zs, mut large_t, mut large_s) = (Vec::new(), Vec::new(), 0, 0);
    for (name, text) in materials() {
        let m = Model::from_toml(&text, None).expect("model");
        let mut samples = Vec::new();
        for ti in steps(0.0, 75.0, 15.0) {
            for to in steps(0.0, 80.0, 10.0) {
                for d in steps(0.0, 180.0, 15.0) {
                    let mut v = vec![0.0; m.channels().len()];
                    m.eval(
                        Dir::from(SphericalDeg::new(ti, 0.0)),
                        Dir::from(SphericalDeg::new(to, d)),
                        &mut v,
                    );
                    samples.push(Sample {
                        pair: PairDeg {
                            incident: SphericalDeg::new(ti, 0.0),
                            outgoing: SphericalDeg::new(to, d),
                        },
                        value: vec![v[0]],
                        sigma: None,
                        flags: 0,
                    });
                }
            }
        }
        let s = Samples {
            channels: Channels::Single,
            samples,
            isotropic: true,
        };
        let (u, _) = hemisphere::unfold(&s);
        for r in hemisphere::albedos(&u).expect("albedos") {
            let t = truth(&m, r.theta_i_deg);
            let z = (r.albedo[0] - t).abs() / r.quadrature[0].max(ROUNDING * t);
            if z > 2.5 {
                println!("triangulated {name} θi {}: |z| {z:.2}", r.theta_i_deg);
            }
            large_t += usize::from(r.quadrature[0] > 0.1 * r.albedo[0]);
            zt.push(z);
        }
        let g = Grid::hemisphere_isotropic(9, 24);
        let full = Table::from_brdf(&m, g).expect("table");
        let n = g.len();
        let t = Table::new(Channels::Single, g, full.values[..n].to_vec(), None).expect("table");
        let e = measure::energy(&t, 1.0, 1);
        for (k, (ti, _)) in e.incident.iter().enumerate() {
            if *ti > 75.0 {
                continue;
            }
            let (v, q) = (e.albedo[0][k], e.albedo_quadrature_sigma[0][k]);
            let z = (v - truth(&m, *ti)).abs() / q.max(ROUNDING * v);
            if z > 2.5 {
                println!("sum {name} θi {ti}: |z| {z:.2}");
            }
            large_s += usize::from(q > 0.1 * v);
            zs.push(z);
        }
    }
    summary("triangulated, plan directions", &mut zt, large_t);
    summary(
        "DeYoung's sum, 10° × 15° midpoints, θi ≤ 75°",
        &mut zs,
        large_s,
    );
}
