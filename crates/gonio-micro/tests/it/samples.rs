//! The issue's examples and the crate's contracts: DeYoung's sawtooth (Fig. 2.4),
//! brushed-metal cylinders (anisotropic, P_i > 0), the spherical-harmonic estimate
//! (exactly reciprocal, correctly normalised), facet models from gonio-brdf files,
//! determinism over thread counts, and surface files that name their faults.
#![allow(clippy::needless_range_loop)] // index arithmetic over grid nodes reads best

use std::path::Path;

use gonio_brdf::{Brdf, Model};
use gonio_core::{Dir, SphericalDeg};
use gonio_micro::{MicroError, Sample, SimOptions, Simulation};
use gonio_process::{Axis, Grid, Table, measure};

fn sim_from(text: &str, path: Option<&Path>) -> Simulation {
    let s = Sample::from_toml(text, path).expect("surface file");
    Simulation::new(s, SimOptions::default()).expect("simulation")
}

const SAWTOOTH: &str = r#"
channels = ["R", "G", "B"]
[surface]
kind = "sawtooth"
period = 1.0
angles_deg = [45.0, 45.0]
faces = ["red", "blue"]     # the face facing +x is red, the one facing -x blue
[materials.red]
kind = "lambert"
albedo = [0.8, 0.1, 0.1]
[materials.blue]
kind = "lambert"
albedo = [0.1, 0.1, 0.8]
"#;

/// DeYoung Fig. 2.4: light at θi = 30° from one side of the grooves comes back mostly
/// red, from the other side mostly blue. Measured (2^19 rays a side, 10° × 10° cells):
/// retro-reflected R/B = 4.90 from φi = 0° and B/R = 4.93 from φi = 180°.
#[test]
fn sawtooth_retro_reflects_red_from_one_side_and_blue_from_the_other() {
    let sim = sim_from(SAWTOOTH, None);
    let grid = Grid::full(
        Axis::full_turn(2),
        Axis::single(30f64.to_radians()),
        Axis::full_turn(36),
        Axis::from_deg(0.0, 10.0, 9),
    );
    let r = sim.to_table(&grid, 1 << 19, 1).expect("table");
    assert_eq!(r.stats.leaked, 0);
    let t = &r.table;
    let n = grid.len();
    // Retro-reflection: θo = 30° (node 3), φo = φi (node 0 or 18).
    let at = |a: usize, c: usize, ch: usize| t.values[ch * n + grid.index(a, 0, c, 3)];
    let (r0, b0) = (at(0, 0, 0), at(0, 0, 2));
    let (r1, b1) = (at(1, 18, 0), at(1, 18, 2));
    println!(
        "from +x: R {r0:.4} B {b0:.4} (R/B {:.2}); from −x: R {r1:.4} B {b1:.4} (B/R {:.2})",
        r0 / b0,
        b1 / r1
    );
    assert!(r0 / b0 > 3.0, "from +x: R {r0} B {b0}");
    assert!(b1 / r1 > 3.0, "from −x: R {r1} B {b1}");
    // The two sides are mirror images: the ratios agree to Monte Carlo error.
    let s = t.sigma.as_ref().expect("errors");
    let i0 = grid.index(0, 0, 0, 3);
    let i1 = grid.index(1, 0, 18, 3);
    // Relative errors of the two ratios, combined.
    let e = ((s[i0] / r0).powi(2)
        + (s[2 * n + i0] / b0).powi(2)
        + (s[i1] / r1).powi(2)
        + (s[2 * n + i1] / b1).powi(2))
    .sqrt();
    println!("relative error of the ratio of ratios: {e:.3}");
    assert!(((r0 / b0) / (b1 / r1) - 1.0).abs() < 4.0 * e);
}

const CYLINDERS: &str = r#"
channels = ["value"]
[surface]
kind = "cylinders"
radius = 1.0
spacing = 1.8
cells_per_period = 64
material = "aluminium"
[materials.aluminium]
kind = "conductor"
n = [0.96]
k = [6.69]
"#;

fn gaussian_aluminium() -> &'static str {
    r#"
channels = ["value"]
[surface]
kind = "gaussian"
size = [128, 128]
rms_height = 0.6
correlation_length = 4.0
seed = 2
material = "aluminium"
[materials.aluminium]
kind = "conductor"
n = [0.96]
k = [6.69]
"#
}

/// Brushed metal: the cylinders' BRDF is anisotropic, P_i (DeYoung Eq. 4.10) far
/// above that of an isotropic Gaussian surface of the same metal on the same grid and
/// rays (which only sees Monte Carlo noise and the finite patch). Measured with
/// 16 384 rays per node on a 6 × 12 hemisphere grid: P_i = 0.4856 (cylinders) and
/// 0.0284 (Gaussian).
#[test]
fn brushed_metal_is_anisotropic() {
    let grid = Grid::hemisphere(6, 12);
    let rays = 1 << 14;
    let cyl = sim_from(CYLINDERS, None)
        .to_table(&grid, rays, 9)
        .expect("table");
    let gau = sim_from(gaussian_aluminium(), None)
        .to_table(&grid, rays, 9)
        .expect("table");
    let p_cyl = measure::isotropy(&cyl.table).expect("P_i")[0];
    let p_gau = measure::isotropy(&gau.table).expect("P_i")[0];
    println!("P_i: cylinders {p_cyl:.4}, gaussian {p_gau:.4}");
    assert!(p_cyl > 0.1, "{p_cyl}");
    assert!(p_cyl > 10.0 * p_gau, "{p_cyl} vs {p_gau}");
    // Turning the brushing direction by 90° turns the BRDF: f(φi, φo) of the turned
    // sample is f(φi − 90°, φo − 90°) of the original, node for node (the 12 azimuth
    // nodes include the 90° turn), to Monte Carlo error.
    let turned = CYLINDERS.replace(
        "cells_per_period = 64",
        "cells_per_period = 64\norientation_deg = 90.0",
    );
    let rot = sim_from(&turned, None)
        .to_table(&grid, rays, 9)
        .expect("table");
    let (g, n) = (grid, grid.len());
    let (mut se, mut ss, mut sv) = (0.0, 0.0, 0.0);
    let s1 = cyl.table.sigma.as_ref().expect("errors");
    let s2 = rot.table.sigma.as_ref().expect("errors");
    for i in 0..n {
        let [a, b, c, d] = g.unindex(i);
        let j = g.index((a + 9) % 12, b, (c + 9) % 12, d);
        se += (rot.table.values[i] - cyl.table.values[j]).powi(2);
        ss += s1[j].powi(2) + s2[i].powi(2);
        sv += cyl.table.values[j].powi(2);
    }
    println!(
        "turned: relative RMS {:.4}, noise {:.4}",
        (se / sv).sqrt(),
        (ss / sv).sqrt()
    );
    assert!(se < 1.5 * ss, "{se} vs noise {ss}");
}

/// The Westin et al. estimate is exactly reciprocal: M is symmetric to the bit and
/// f(a, b) = f(b, a) to the bit for any pair.
#[test]
fn sh_estimate_is_bit_reciprocal() {
    let sim = sim_from(CYLINDERS, None);
    let est = sim.estimate_sh(8, Some(6), 1 << 16, 4).expect("sh");
    let k = est.sh.basis.len();
    let m = &est.sh.matrices[0];
    for j in 0..k {
        for l in 0..k {
            assert_eq!(m[j * k + l].to_bits(), m[l * k + j].to_bits());
        }
    }
    let mut worst_anisotropy = 0.0f64;
    for i in 0..400 {
        let a = Dir::from(SphericalDeg::new(
            (i * 37 % 89) as f64,
            (i * 53 % 360) as f64,
        ));
        let b = Dir::from(SphericalDeg::new(
            (i * 17 % 89) as f64,
            (i * 101 % 360) as f64,
        ));
        let (mut x, mut y) = ([0.0], [0.0]);
        est.sh.eval(a, b, &mut x);
        est.sh.eval(b, a, &mut y);
        assert_eq!(x[0].to_bits(), y[0].to_bits(), "{a:?} {b:?}");
        // And the estimate is anisotropic: turning both directions changes it.
        let mut z = [0.0];
        est.sh.eval(
            a.rotate_about_normal(1.0),
            b.rotate_about_normal(1.0),
            &mut z,
        );
        worst_anisotropy = worst_anisotropy.max((z[0] - x[0]).abs());
    }
    assert!(worst_anisotropy > 0.05, "{worst_anisotropy}");
    assert_eq!(est.stats.leaked, 0);
}

/// The estimator's normalisation: a flat Lambertian facet of albedo ρ has f = ρ/π,
/// which is M_00 Y_00² with M_00 = 4ρ and every other coefficient 0. Measured with
/// 2^18 rays: M_00 = 2.4026 ± 0.0030 for ρ = 0.6 (2.4073 ± 0.0095 with the 1/cos θo
/// weight of Westin et al., whose variance is infinite).
#[test]
fn sh_estimate_of_a_lambertian_plane() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    std::fs::write(dir.join("flat.csv"), "0 0 0\n0 0 0\n").expect("write");
    let text = r#"
channels = ["value"]
[surface]
kind = "height-map"
file = "flat.csv"
spacing = 1.0
material = "white"
[materials.white]
kind = "lambert"
albedo = [0.6]
"#;
    let path = dir.join("flat.toml");
    std::fs::write(&path, text).expect("write");
    let sim =
        Simulation::new(Sample::load(&path).expect("load"), SimOptions::default()).expect("sim");
    let est = sim.estimate_sh(4, None, 1 << 18, 8).expect("sh");
    let k = est.sh.basis.len();
    let (m, s) = (&est.sh.matrices[0], &est.sigma[0]);
    println!("M_00 = {} ± {}", m[0], s[0]);
    assert!(
        (m[0] - 2.4).abs() < 4.0 * s[0] && s[0] < 0.01,
        "{} ± {}",
        m[0],
        s[0]
    );
    let mut beyond = 0;
    for j in 0..k {
        for l in j..k {
            if (j, l) != (0, 0) && m[j * k + l].abs() > 4.0 * s[j * k + l] {
                beyond += 1;
            }
        }
    }
    // 119 other coefficients at 4σ: at most a couple by chance.
    assert!(beyond <= 2, "{beyond} coefficients beyond 4σ");
    let (mut f, wi) = ([0.0], Dir::from(SphericalDeg::new(40.0, 10.0)));
    est.sh
        .eval(wi, Dir::from(SphericalDeg::new(20.0, 200.0)), &mut f);
    assert!((f[0] - 0.6 / std::f64::consts::PI).abs() < 0.01, "{}", f[0]);
}

/// A gonio-brdf model at the microscale: on a flat surface the simulated albedo is the
/// model's own (computed by gonio-brdf to 1e-8) within Monte Carlo error.
#[test]
fn model_facets_reproduce_the_models_albedo_on_a_flat_surface() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let model_path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/cook-torrance-gold.toml");
    std::fs::write(dir.join("flat.csv"), "0,0\n0,0\n").expect("write");
    let text = format!(
        r#"
channels = ["R", "G", "B"]
[surface]
kind = "height-map"
file = "flat.csv"
spacing = 1.0
material = "gold"
[materials.gold]
kind = "model"
file = "{}"
"#,
        model_path.display()
    );
    let path = dir.join("gold.toml");
    std::fs::write(&path, text).expect("write");
    let sim =
        Simulation::new(Sample::load(&path).expect("load"), SimOptions::default()).expect("sim");
    let model = Model::load(&model_path).expect("model");
    let grid = Grid::isotropic(
        Axis::from_deg(20.0, 40.0, 2),
        Axis::full_turn(8),
        Axis::polar_midpoints(6),
    );
    let r = sim.to_table(&grid, 1 << 16, 5).expect("table");
    for al in &r.albedo {
        let mut exact = [0.0; 3];
        model.albedo(Dir::from_angles(al.theta_i, 0.0), &mut exact);
        for ch in 0..3 {
            let z = (al.albedo[ch] - exact[ch]) / al.sigma[ch];
            println!(
                "θi {:.0} ch {ch}: {} vs {} (z = {z:.2})",
                al.theta_i.to_degrees(),
                al.albedo[ch],
                exact[ch]
            );
            assert!(
                z.abs() < 4.0,
                "θi {} ch {ch}: {} vs {}",
                al.theta_i,
                al.albedo[ch],
                exact[ch]
            );
        }
    }
}

fn table_bits(t: &Table) -> Vec<u64> {
    t.values
        .iter()
        .chain(t.sigma.as_deref().unwrap_or(&[]))
        .map(|v| v.to_bits())
        .collect()
}

/// The same seed gives the same bytes on one thread and on two.
#[test]
fn same_seed_same_bytes_on_any_thread_count() {
    let sim = sim_from(SAWTOOTH, None);
    let grid = Grid::isotropic(
        Axis::from_deg(0.0, 30.0, 3),
        Axis::full_turn(12),
        Axis::polar_midpoints(6),
    );
    let run = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let r = sim.to_table(&grid, 5000, seed).expect("table");
            let sh = sim.estimate_sh(4, Some(3), 5000, seed).expect("sh");
            let ex = sim
                .trace(Dir::from(SphericalDeg::new(30.0, 0.0)), 3000, seed)
                .expect("trace");
            let mut bits = table_bits(&r.table);
            for t in &r.per_order {
                bits.extend(table_bits(t));
            }
            bits.extend(sh.sh.matrices[0].iter().map(|v| v.to_bits()));
            bits.extend(ex.energy.iter().map(|v| v.to_bits()));
            bits.extend(ex.wo.iter().map(|d| d.x.to_bits()));
            bits
        })
    };
    let one = run(1, 42);
    assert_eq!(one, run(2, 42));
    assert_ne!(one, run(2, 43));
}

fn load_err(dir: &Path, name: &str, text: &str) -> MicroError {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    Sample::load(&p).expect_err("a bad file")
}

#[test]
fn bad_surface_files_name_file_and_field() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let base = CYLINDERS;
    let cases: Vec<(&str, String, &[&str])> = vec![
        (
            "neg-radius.toml",
            base.replace("radius = 1.0", "radius = -1.0"),
            &["neg-radius.toml:5:", "surface.radius"],
        ),
        (
            "no-material.toml",
            base.replace("material = \"aluminium\"", "material = \"steel\""),
            &["surface.material", "steel"],
        ),
        (
            "channels.toml",
            base.replace("k = [6.69]", "k = [6.69, 1.0]"),
            &[
                "channels.toml:",
                "materials.aluminium.k",
                "2 values for 1 channels",
            ],
        ),
        (
            "unknown-key.toml",
            base.replace("spacing = 1.8", "spacing = 1.8\nroughness = 3"),
            &["unknown-key.toml:7:1", "roughness"],
        ),
        (
            "kind.toml",
            base.replace("kind = \"cylinders\"", "kind = \"cylinder\""),
            &["kind.toml:", "cylinder"],
        ),
        (
            "gaussian.toml",
            gaussian_aluminium().replace("rms_height = 0.6", "rms_height = -0.6"),
            &["gaussian.toml:6:", "surface.rms_height"],
        ),
        (
            "chan.toml",
            base.replace("[\"value\"]", "[\"X\"]"),
            &["chan.toml:2:", "channels"],
        ),
    ];
    for (name, text, needles) in cases {
        let e = load_err(dir, name, &text).to_string();
        println!("{e}");
        for n in needles {
            assert!(e.contains(n), "{name}: {e:?} lacks {n:?}");
        }
    }
    // A height map with a bad number: the map's file and line.
    std::fs::write(dir.join("bumps.csv"), "0 1 2\n0 x 2\n").expect("write");
    let hm = r#"
channels = ["value"]
[surface]
kind = "height-map"
file = "bumps.csv"
spacing = 1.0
material = "m"
[materials.m]
kind = "mirror"
"#;
    let e = load_err(dir, "hm.toml", hm).to_string();
    assert!(e.contains("bumps.csv:2:") && e.contains("\"x\""), "{e}");
    // A spreadsheet's byte order mark before the first height is no height.
    std::fs::write(dir.join("bumps.csv"), "\u{feff}0,1,2\n0,1,2\n").expect("write");
    let s = Sample::load(&dir.join("hm.toml")).expect("BOM");
    assert_eq!((s.surface.nx(), s.surface.ny()), (3, 2));
    std::fs::write(dir.join("bumps.csv"), "0 1 2\n0 1\n").expect("write");
    let e = load_err(dir, "hm.toml", hm).to_string();
    assert!(e.contains("bumps.csv:2:"), "{e}");
    let e = load_err(dir, "hm2.toml", &hm.replace("bumps.csv", "missing.csv")).to_string();
    assert!(e.contains("missing.csv"), "{e}");
    // A model file that is not there: the surface file, the field, and the model path.
    let md = hm.replace(
        "kind = \"mirror\"",
        "kind = \"model\"\nfile = \"nowhere.toml\"",
    );
    std::fs::write(dir.join("bumps.csv"), "0 1\n1 0\n").expect("write");
    let e = load_err(dir, "md.toml", &md).to_string();
    assert!(
        e.contains("md.toml") && e.contains("materials.m.file") && e.contains("nowhere.toml"),
        "{e}"
    );
}

/// Every number of a surface file has a finite range, and the tracer's counts a cap:
/// each is refused with its field, line and the limit (docs/micro.md, "Limits").
#[test]
fn absurd_surface_numbers_and_counts_name_the_limit() {
    let g = gaussian_aluminium();
    let cases: Vec<(String, usize, &str, &str)> = vec![
        (
            g.replace("rms_height = 0.6", "rms_height = 1e8"),
            6,
            "surface.rms_height",
            "must be at most 200, got 1e8 (at most 50 × correlation_length: an RMS slope \
             2σ/l of at most 100)",
        ),
        (
            g.replace("rms_height = 0.6", "rms_height = nan"),
            6,
            "surface.rms_height",
            "must be finite, got NaN",
        ),
        (
            g.replace("correlation_length = 4.0", "correlation_length = 1e300"),
            7,
            "surface.correlation_length",
            "must be at most 1e9, got 1e300",
        ),
        (
            g.replace("size = [128, 128]", "size = [8192, 8192]")
                .replace("correlation_length = 4.0", "correlation_length = 400.0"),
            7,
            "surface.correlation_length",
            "a correlation of 400 cells on 8192 × 8192 cells takes 4.30e11 kernel products \
             to generate, more than 2^34; shorten it or the size",
        ),
        (
            g.replace("seed = 2", "seed = 2\norientation_deg = inf"),
            9,
            "surface.orientation_deg",
            "must be finite, got inf",
        ),
        (
            g.replace("k = [6.69]", "k = [1e300]"),
            13,
            "materials.aluminium.k",
            "value 0 (1e300) must be in [0, 100]",
        ),
    ];
    for (text, line, field, message) in cases {
        let e = match Sample::from_toml(&text, None) {
            Err(MicroError::File(e)) => e,
            other => panic!("{text}: {other:?}"),
        };
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert_eq!(e.line, Some(line), "{e}");
        assert_eq!(e.message, message, "{text}");
    }
    // A height map whose relief no tracer can follow: 1e8 over a unit spacing.
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    std::fs::write(dir.join("spike.csv"), "0 0 0\n0 1e8 0\n0 0 0\n").expect("write");
    let hm = "channels = [\"value\"]\n[surface]\nkind = \"height-map\"\nfile = \"spike.csv\"\n\
              spacing = 1.0\nmaterial = \"m\"\n[materials.m]\nkind = \"mirror\"\n";
    let e = load_err(dir, "hm.toml", hm).to_string();
    assert!(
        e.contains(
            "heights: the facets at node (0, 0) rise 1e8 per unit of spacing, more than 1e4"
        ),
        "{e}"
    );
    // A device named as the height map is refused unread.
    let e = load_err(dir, "dev.toml", &hm.replace("spike.csv", "/dev/zero")).to_string();
    assert!(
        e.contains("/dev/zero: a character device, not a regular file"),
        "{e}"
    );
    // The tracer's counts.
    let sim = sim_from(g, None);
    let grid = Grid::hemisphere(1, 1);
    let e = sim.to_table(&grid, usize::MAX, 1).expect_err("rays");
    assert_eq!(
        e.to_string(),
        format!("rays: must be at most 1000000000 rays, got {}", usize::MAX)
    );
    let e = sim.estimate_sh(2, None, usize::MAX, 1).expect_err("rays");
    assert!(
        e.to_string()
            .starts_with("rays: must be at most 1000000000 rays"),
        "{e}"
    );
    let s = Sample::from_toml(g, None).expect("surface");
    let opts = SimOptions {
        max_bounces: u32::MAX,
        ..SimOptions::default()
    };
    let e = Simulation::new(s, opts).expect_err("bounces");
    assert_eq!(
        e.to_string(),
        "max_bounces: must be at most 10000 bounces, got 4294967295"
    );
}

/// A value of the wrong type inside `[surface]` or a `[materials.NAME]` table names
/// its field and line; an unknown kind lists the kinds there are.
#[test]
fn type_errors_in_kind_tables_name_the_field() {
    let err = |text: String| {
        Sample::from_toml(&text, Some(Path::new("s.toml")))
            .expect_err(&text)
            .to_string()
    };
    assert_eq!(
        err(CYLINDERS.replace("radius = 1.0", "radius = \"wide\"")),
        "s.toml:5:10: field `surface.radius`: invalid type: string \"wide\", expected f64"
    );
    assert_eq!(
        err(CYLINDERS.replace("cells_per_period = 64", "cells_per_period = -64")),
        "s.toml:7:20: field `surface.cells_per_period`: invalid value: integer `-64`, \
         expected usize"
    );
    assert_eq!(
        err(CYLINDERS.replace("n = [0.96]", "n = 0.96")),
        "s.toml:11:5: field `materials.aluminium.n`: invalid type: floating point `0.96`, \
         expected a sequence"
    );
    assert_eq!(
        err(CYLINDERS.replace("kind = \"cylinders\"", "kind = \"cylinder\"")),
        "s.toml:4:8: field `surface.kind`: unknown kind \"cylinder\", expected one of \
         \"gaussian\", \"sawtooth\", \"cylinders\" or \"height-map\""
    );
    assert_eq!(
        err(CYLINDERS.replace("kind = \"conductor\"", "kind = \"metal\"")),
        "s.toml:10:8: field `materials.aluminium.kind`: unknown kind \"metal\", expected \
         one of \"mirror\", \"conductor\", \"dielectric\", \"lambert\" or \"model\""
    );
    // The alias still reads, and so does the file with a byte order mark.
    let sawtooth = SAWTOOTH.replace("kind = \"sawtooth\"", "kind = \"v-grooves\"");
    assert_ne!(sawtooth, SAWTOOTH);
    assert_eq!(
        Sample::from_toml(&sawtooth, None).expect("alias"),
        Sample::from_toml(SAWTOOTH, None).expect("sawtooth")
    );
    assert_eq!(
        Sample::from_toml(&format!("\u{feff}{CYLINDERS}"), None).expect("BOM"),
        Sample::from_toml(CYLINDERS, None).expect("plain")
    );
}

/// The example surface files in `config/` load and simulate.
#[test]
fn config_examples_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
    for name in [
        "micro-gaussian-gold.toml",
        "micro-sawtooth-deyoung.toml",
        "micro-brushed-aluminium.toml",
    ] {
        let s = Sample::load(&dir.join(name)).unwrap_or_else(|e| panic!("{e}"));
        let sim = Simulation::new(s, SimOptions::default()).expect("sim");
        let ex = sim
            .trace(Dir::from(SphericalDeg::new(30.0, 0.0)), 2048, 1)
            .expect("trace");
        let total: f64 = ex.energy.iter().sum::<f64>() / (3.0 * ex.rays as f64);
        assert!(total > 0.1 && total <= 1.0, "{name}: {total}");
        assert_eq!(ex.stats.leaked, 0, "{name}");
    }
}

/// A table traced in chunks (parts of whole segments, in another order, through
/// bytes as they cross processes) is bit for bit the table traced at once.
#[test]
fn a_table_merged_from_parts_is_the_table_traced_at_once() {
    use gonio_micro::{SEGMENT_RAYS, TablePart};
    let sim = sim_from(
        &std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/micro-sawtooth-deyoung.toml"),
        )
        .expect("shipped surface"),
        None,
    );
    let grid = gonio_process::GridStep::new(30.0, 90.0)
        .expect("steps")
        .isotropic_grid();
    // Three segments, the last short.
    let rays = 2 * SEGMENT_RAYS + 5000;
    let whole = sim.to_table(&grid, rays, 11).expect("table");
    let mut parts = Vec::new();
    for inc in (0..grid.n_in()).rev() {
        for segs in [2..3, 0..2] {
            let p = sim.table_part(&grid, rays, 11, inc, segs).expect("part");
            let back = TablePart::from_bytes(&p.to_bytes()).expect("reads back");
            assert_eq!(back, p);
            parts.push(back);
        }
    }
    let merged = sim
        .table_from_parts(&grid, rays, 11, &parts)
        .expect("merged");
    assert_eq!(table_bits(&merged.table), table_bits(&whole.table));
    assert_eq!(merged.stats, whole.stats);
    assert_eq!(merged.albedo, whole.albedo);
    assert_eq!(merged.stats.rays, (rays * grid.n_in()) as u64);

    // A missing or doubled segment is refused, as are damaged bytes.
    let e = sim
        .table_from_parts(&grid, rays, 11, &parts[1..])
        .expect_err("missing");
    assert!(e.to_string().contains("segment"), "{e}");
    let mut doubled = parts.clone();
    doubled.push(parts[0].clone());
    assert!(sim.table_from_parts(&grid, rays, 11, &doubled).is_err());
    // Parts of another seed, or of another ray count with as many segments.
    let e = sim
        .table_from_parts(&grid, rays, 12, &parts)
        .expect_err("another seed");
    assert!(e.to_string().contains("another simulation"), "{e}");
    assert!(sim.table_from_parts(&grid, rays + 1, 11, &parts).is_err());
    // A segment's counts that do not add up are refused as bytes.
    let mut bytes = parts[0].to_bytes();
    let exits_at = 8 + 7 * 8 + 8;
    bytes[exits_at..exits_at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(TablePart::from_bytes(&bytes).is_err());
    let bytes = parts[0].to_bytes();
    assert!(TablePart::from_bytes(&bytes[..bytes.len() - 8]).is_err());
    let mut huge = bytes.clone();
    // The segment count (after seed, rays, incident and first).
    huge[8 + 32..8 + 40].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(TablePart::from_bytes(&huge).is_err());
    assert!(
        sim.table_part(&grid, rays, 11, 0, 3..4).is_err(),
        "past the end"
    );
}
