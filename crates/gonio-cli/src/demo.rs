//! `gonio demo`: what Gonio does today, on an embedded default — the blue paint of
//! Lafortune et al. 1997, Table 1, at 550 nm.

use std::io::Write;

use gonio_brdf::albedo::{DEFAULT_TOLERANCE, integrate};
use gonio_brdf::{Brdf, Lafortune, Model};
use gonio_core::{Dir, SphericalDeg};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::output;

/// The embedded default model.
const BLUE_PAINT: &str = include_str!("../../../config/models/blue-paint-550nm.toml");

const ALBEDO_THETAS: [f64; 12] = [
    0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 65.0, 70.0, 75.0, 80.0, 85.0,
];
/// The incidence angles of Fig. 13.
const CUT_THETAS: [f64; 3] = [0.0, 35.0, 65.0];

fn deg(t: f64, p: f64) -> Dir {
    Dir::from(SphericalDeg::new(t, p))
}

fn albedo1(b: &dyn Brdf, wi: Dir) -> f64 {
    let mut a = vec![0.0; b.channels().len()];
    b.albedo(wi, &mut a);
    a[0]
}

fn eval1(b: &dyn Brdf, wi: Dir, wo: Dir) -> f64 {
    let mut a = vec![0.0; b.channels().len()];
    b.eval(wi, wo, &mut a);
    a[0]
}

/// A point of the plane of incidence: negative θo on the source's side (φo = 0),
/// positive on the specular side (φo = 180°).
fn in_plane(theta_o: f64) -> Dir {
    if theta_o < 0.0 {
        deg(-theta_o, 0.0)
    } else {
        deg(theta_o, 180.0)
    }
}

struct AlbedoRow {
    theta: f64,
    total: f64,
    diffuse: f64,
    lobes: Vec<f64>,
    cubature: f64,
}

pub fn run(json: bool) -> CliResult<()> {
    let model = Model::from_toml(BLUE_PAINT, None)
        .map_err(|e| CliError::Runtime(format!("embedded demo model: {e}")))?;
    let Model::Lafortune(paint) = &model else {
        return Err(CliError::Runtime(
            "embedded demo model is not a Lafortune model".into(),
        ));
    };
    let ch = paint.channels().clone();
    // Each term on its own, to show what each lobe contributes.
    let lobes: Vec<Lafortune> = paint
        .lobes()
        .iter()
        .map(|l| Lafortune::new(ch.clone(), vec![l.clone()]))
        .collect::<Result<_, _>>()
        .map_err(|e| CliError::Runtime(format!("embedded demo model: {e}")))?;
    let rows: Vec<AlbedoRow> = ALBEDO_THETAS
        .iter()
        .map(|t| {
            let wi = deg(*t, 0.0);
            AlbedoRow {
                theta: *t,
                total: albedo1(paint, wi),
                diffuse: paint.diffuse().map_or(0.0, |d| albedo1(d, wi)),
                lobes: lobes.iter().map(|l| albedo1(l, wi)).collect(),
                // Independent check: generic cubature instead of the exact lobe integral.
                cubature: integrate(paint, wi, DEFAULT_TOLERANCE).values[0],
            }
        })
        .collect();
    let max_dev = rows
        .iter()
        .map(|r| (r.total - r.cubature).abs())
        .fold(0.0, f64::max);
    let cut_thetas_o: Vec<f64> = (-8..=8).map(|k| 10.0 * k as f64).collect();
    let cuts: Vec<Vec<f64>> = CUT_THETAS
        .iter()
        .map(|ti| {
            cut_thetas_o
                .iter()
                .map(|to| eval1(paint, deg(*ti, 0.0), in_plane(*to)))
                .collect()
        })
        .collect();
    // Reciprocity over a grid of pairs: exact by construction (Eq. 3 with M = Mᵀ).
    let mut recip: f64 = 0.0;
    for ti in (0..90).step_by(5) {
        for pi in (0..360).step_by(30) {
            for to in (0..90).step_by(5) {
                for po in (0..360).step_by(30) {
                    let (a, b) = (deg(ti as f64, pi as f64), deg(to as f64, po as f64));
                    let (x, y) = (eval1(paint, a, b), eval1(paint, b, a));
                    recip = recip.max((x - y).abs() / x.max(y));
                }
            }
        }
    }
    let measured = simulated_cut()?;
    if json {
        return output::json(&json!({
            "simulated_measurement": {
                "theta_i": SIM_THETA_I,
                "points": measured.points.iter().map(|p| json!({
                    "theta_o": p.theta_o, "model": p.model, "measured": p.measured,
                    "sigma": p.sigma,
                })).collect::<Vec<_>>(),
                "physical_seconds": measured.physical_s,
            },
            "model": "Lafortune et al. 1997, Table 1: blue paint",
            "channels": ch.names(),
            "albedo": rows.iter().map(|r| json!({
                "theta_i": r.theta, "total": r.total, "diffuse": r.diffuse,
                "lobes": r.lobes, "cubature": r.cubature,
            })).collect::<Vec<_>>(),
            "albedo_max_method_difference": max_dev,
            "in_plane": CUT_THETAS.iter().zip(&cuts).map(|(ti, c)| json!({
                "theta_i": ti,
                "theta_o": cut_thetas_o,
                "brdf": c,
            })).collect::<Vec<_>>(),
            "reciprocity_max_relative_difference": recip,
        }));
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(
            w,
            "Gonio demo: the blue paint of Lafortune et al. 1997, Table 1 (550 nm)"
        )?;
        writeln!(
            w,
            "model: Lambertian rho_d = 0.13 pi + three generalized cosine lobes (Eq. 8)"
        )?;
        writeln!(
            w,
            "  lobe I   Cx = Cy = 0.86, Cz = 0.77,  n = 18.6  (retro-reflective)"
        )?;
        writeln!(
            w,
            "  lobe II  Cx = Cy = -0.41, Cz = 0.018, n = 2.58 (broad forward)"
        )?;
        writeln!(
            w,
            "  lobe III Cx = Cy = -1.03, Cz = 0.70,  n = 63.8 (off-specular forward)"
        )?;
        writeln!(w)?;
        writeln!(
            w,
            "Directional albedo rho(theta_i) = integral of f_r cos(theta_o) over the hemisphere"
        )?;
        writeln!(
            w,
            "{:>7} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "theta_i", "total", "diffuse", "lobe I", "lobe II", "lobe III"
        )?;
        for r in &rows {
            write!(w, "{:>7} {:>9.5} {:>9.5}", r.theta, r.total, r.diffuse)?;
            for l in &r.lobes {
                write!(w, " {l:>9.5}")?;
            }
            writeln!(w)?;
        }
        writeln!(
            w,
            "exact lobe integrals and generic 2-D cubature agree to {max_dev:.1e} at every angle"
        )?;
        writeln!(w)?;
        writeln!(
            w,
            "BRDF in the plane of incidence (1/sr), the cuts of Fig. 13; theta_o < 0 is the"
        )?;
        writeln!(w, "source side, theta_o > 0 the specular side")?;
        write!(w, "{:>7}", "theta_o")?;
        for ti in CUT_THETAS {
            write!(w, "  {:>12}", format!("theta_i={ti}"))?;
        }
        writeln!(w)?;
        for (k, to) in cut_thetas_o.iter().enumerate() {
            write!(w, "{to:>7}")?;
            for c in &cuts {
                write!(w, "  {:>12.5}", c[k])?;
            }
            writeln!(w)?;
        }
        writeln!(w)?;
        writeln!(
            w,
            "reciprocity: max |f(wi,wo) - f(wo,wi)| / f over {} grid pairs = {recip:e}",
            18 * 12 * 18 * 12
        )?;
        writeln!(w)?;
        writeln!(
            w,
            "Measured on the simulated goniometer: the real SMC100 and SR830 drivers against"
        )?;
        writeln!(
            w,
            "gonio-sim (coplanar arms, this paint, seed 1), theta_i = {SIM_THETA_I}, in the plane"
        )?;
        writeln!(
            w,
            "{:>7} {:>11} {:>11} {:>10} {:>7}",
            "theta_o", "model", "measured", "sigma", "dev/s"
        )?;
        for p in &measured.points {
            writeln!(
                w,
                "{:>7} {:>11.6} {:>11.6} {:>10.2e} {:>7.2}",
                p.theta_o,
                p.model,
                p.measured,
                p.sigma,
                (p.measured - p.model) / p.sigma
            )?;
        }
        writeln!(
            w,
            "{} points: {:.1} s of instrument time (homing, moves, settling, sampling)",
            measured.points.len(),
            measured.physical_s
        )?;
        writeln!(w)?;
        writeln!(
            w,
            "Gonio today: BRDF models (gonio model eval | albedo), the SMC100 / SR830 drivers"
        )?;
        writeln!(
            w,
            "(gonio instrument check) and the simulated goniometer (gonio sim). Acquisition"
        )?;
        writeln!(w, "plans and run files, processing and fitting come next.")?;
        w.flush()
    })())
}

/// Incidence angle of the simulated measurement.
const SIM_THETA_I: f64 = 35.0;

struct SimPoint {
    theta_o: f64,
    model: f64,
    measured: f64,
    sigma: f64,
}

struct SimCut {
    points: Vec<SimPoint>,
    physical_s: f64,
}

/// Measures the paint's in-plane BRDF at θi = 35° on the simulated goniometer, through
/// the real drivers, and turns each reading back into a BRDF with the simulator's
/// known optics (`R = g · R_v · P · f_r · cos θo · Ω`).
fn simulated_cut() -> CliResult<SimCut> {
    use gonio_core::DirPair;
    use gonio_core::kinematics::Layout;

    let runtime =
        |e: &dyn std::fmt::Display| CliError::Runtime(format!("simulated measurement: {e}"));
    let icfg =
        gonio_driver::InstrumentConfig::from_toml(INSTRUMENT_SIM, None).map_err(|e| runtime(&e))?;
    let scfg = gonio_sim::SimConfig::default_config().map_err(|e| runtime(&e))?;
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).map_err(|e| runtime(&e))?;
    g.start().map_err(|e| runtime(&e))?;
    g.home().map_err(|e| runtime(&e))?;
    let omega = gonio_sim::lock(&sim).optics().solid_angle_sr();
    let scale = scfg.lockin.chop_gain
        * scfg.optics.responsivity_v_per_w
        * scfg.optics.source_power_w
        * omega;
    let wi = deg(SIM_THETA_I, 0.0);
    let mut points = Vec::new();
    let mut hint = [0.0; 4];
    // θo < 0 on the source's side; −35° would put the detector in the beam.
    for to in [-70.0, -50.0, -20.0, 0.0, 20.0, 35.0, 50.0, 70.0] {
        let wo = in_plane(to);
        let pair = DirPair::new(wi, wo);
        let a = Layout::CoplanarArms
            .inverse(pair, Some(hint))
            .map_err(|e| runtime(&e))?;
        hint = a;
        let targets = [
            ("source", a[0]),
            ("detector", a[1]),
            ("sample_rot", a[2]),
            ("sample_tilt", a[3]),
        ];
        let (_, r) = g.measure_at(&targets).map_err(|e| runtime(&e))?;
        let cos_o = wo.z;
        let mut f = [0.0];
        gonio_sim::lock(&sim).optics().sample().eval(wi, wo, &mut f);
        // Neighbouring samples, one time constant apart, correlate (e^-1): the mean's
        // variance is about 2.2 σ²/n.
        let sigma = r.r_std * (2.2 / r.n as f64).sqrt() / (scale * cos_o);
        points.push(SimPoint {
            theta_o: to,
            model: f[0],
            measured: r.r_mean / (scale * cos_o),
            sigma,
        });
    }
    let physical_s = gonio_sim::lock(&sim).clock().seconds();
    Ok(SimCut { points, physical_s })
}

/// The simulator's instrument config, embedded.
const INSTRUMENT_SIM: &str = include_str!("../../../config/instrument-sim.toml");
