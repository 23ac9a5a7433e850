//! The simulator's sample can be any BRDF: a model file, a measured table, or a
//! microgeometry surface traced by `gonio-micro` — all prepared by the simulator
//! itself, and the text a run file keeps for each reads back to the same sample.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use gonio_brdf::{Brdf, Model};
use gonio_core::{Dir, SphericalDeg};
use gonio_process::{Grid, GridStep, Table};
use gonio_sim::{SampleKind, SimConfig};

const BLUE_PAINT: &str = include_str!("../../../config/models/blue-paint-550nm.toml");

/// The embedded simulator config with `sample` as its `[sample]` table, written to
/// `dir` (relative sample paths resolve against it).
fn config_with(dir: &Path, sample: &str) -> SimConfig {
    let text = gonio_sim::config::DEFAULT_SIM.replace(
        "[sample]                       # the embedded blue paint when no model is given\n# model = \"models/blue-paint-550nm.toml\"\n",
        sample,
    );
    assert_ne!(
        text,
        gonio_sim::config::DEFAULT_SIM,
        "the [sample] table was replaced"
    );
    let p = dir.join("sim.toml");
    std::fs::write(&p, &text).expect("write");
    SimConfig::load(&p).expect("valid sim config")
}

fn eval(b: &dyn Brdf, ti: f64, pi: f64, to: f64, po: f64) -> f64 {
    let mut v = vec![0.0; b.channels().len()];
    b.eval(
        Dir::from(SphericalDeg::new(ti, pi)),
        Dir::from(SphericalDeg::new(to, po)),
        &mut v,
    );
    v[0]
}

/// A small rough Lambertian-faceted surface: quick to trace.
const SURFACE: &str = r#"
channels = ["value"]
[surface]
kind = "gaussian"
size = [64, 64]
spacing = 1.0
rms_height = 0.5
correlation_length = 4.0
seed = 3
material = "white"
[materials.white]
kind = "lambert"
albedo = [0.8]
"#;

#[test]
fn a_table_sample_is_the_table() {
    let dir = tempfile::tempdir().expect("temp dir");
    let paint = Model::from_toml(BLUE_PAINT, None).expect("paint");
    let table = Table::from_brdf(&paint, Grid::hemisphere(9, 36)).expect("table");
    let text = gonio_process::file::write_table(&table);
    std::fs::write(dir.path().join("paint.csv"), &text).expect("write");
    let mut cfg = config_with(dir.path(), "[sample]\ntable = \"paint.csv\"\n");
    assert_eq!(cfg.sample_kind(), SampleKind::Table);
    assert_eq!(cfg.sample_model_text().expect("text"), text);
    let (sample, channel) = cfg.load_sample().expect("loads");
    assert_eq!(channel, 0);
    // At a node the table holds the model's value; between nodes it interpolates.
    for (ti, pi, to, po) in [(25.0, 0.0, 45.0, 180.0), (65.0, 90.0, 15.0, 270.0)] {
        let want = eval(&paint, ti, pi, to, po);
        let got = eval(sample.as_ref(), ti, pi, to, po);
        assert!((got - want).abs() <= 1e-12 * want, "{got} vs {want}");
    }
    // What a run file keeps reads back to the same sample.
    cfg.prepare_sample().expect("prepares");
    let mut resumed = config_with(dir.path(), "[sample]\ntable = \"elsewhere.csv\"\n");
    resumed.sample_text = cfg.sample_text.clone();
    let (again, _) = resumed.load_sample().expect("from the kept text");
    assert_eq!(
        eval(again.as_ref(), 30.0, 10.0, 50.0, 170.0),
        eval(sample.as_ref(), 30.0, 10.0, 50.0, 170.0)
    );

    // An isotropic table with its sidecar: the kept text carries the grid (and its
    // isotropy), so a resumed run evaluates it as isotropic at any φi.
    let iso = Table::from_brdf(
        &paint,
        GridStep::new(10.0, 10.0).expect("grid").isotropic_grid(),
    )
    .expect("table");
    std::fs::write(
        dir.path().join("iso.csv"),
        gonio_process::file::write_table(&iso),
    )
    .expect("write");
    std::fs::write(
        gonio_process::file::sidecar_path(&dir.path().join("iso.csv")),
        gonio_process::file::Meta::for_table(&iso).to_json(),
    )
    .expect("write");
    let mut cfg = config_with(dir.path(), "[sample]\ntable = \"iso.csv\"\n");
    let kept = cfg.sample_model_text().expect("text");
    assert!(
        kept.starts_with("# grid: isotropic=true"),
        "{}",
        &kept[..60]
    );
    cfg.prepare_sample().expect("prepares");
    let mut resumed = config_with(dir.path(), "[sample]\ntable = \"elsewhere.csv\"\n");
    resumed.sample_text = Some(kept);
    let (again, _) = resumed.load_sample().expect("from the kept text");
    let (a, b) = (
        eval(again.as_ref(), 25.0, 0.0, 45.0, 180.0),
        eval(again.as_ref(), 25.0, 70.0, 45.0, 250.0),
    );
    assert!((a - b).abs() <= 1e-12 * a, "{a} vs {b}");
    assert!((a - eval(&paint, 25.0, 0.0, 45.0, 180.0)).abs() <= 1e-12 * a);
}

#[test]
fn a_microgeometry_sample_is_traced_by_the_simulator() {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("surface.toml"), SURFACE).expect("write");
    let mut cfg = config_with(
        dir.path(),
        "[sample.micro]\nsurface = \"surface.toml\"\ngrid = [15, 30]\nrays = 4000\nseed = 5\n",
    );
    assert_eq!(cfg.sample_kind(), SampleKind::Micro);
    cfg.prepare_sample().expect("traces");
    let kept = cfg.sample_text.clone().expect("the table's text");
    // The same table gonio-micro traces on its own with the same seed, to the byte.
    let sample = gonio_micro::Sample::load(&dir.path().join("surface.toml")).expect("surface");
    let sim = gonio_micro::Simulation::new(sample, gonio_micro::SimOptions::default())
        .expect("simulation");
    let grid = GridStep::new(15.0, 30.0).expect("grid").isotropic_grid();
    let direct = sim.to_table(&grid, 4000, 5).expect("traces");
    assert_eq!(
        kept,
        gonio_process::file::write_table_self_contained(&direct.table)
    );
    // A rough white Lambertian surface reflects about diffusely: f ≈ albedo/π near
    // normal incidence and exitance (within the Monte Carlo error and the masking).
    let (b, _) = cfg.load_sample().expect("prepared");
    let f = eval(b.as_ref(), 7.5, 0.0, 37.5, 180.0);
    assert!((f - 0.8 / std::f64::consts::PI).abs() < 0.05, "f = {f}");
    // Reading back the kept text does not trace again (the surface is gone).
    std::fs::remove_file(dir.path().join("surface.toml")).expect("remove");
    let mut resumed = cfg.clone();
    resumed.prepared = None;
    let (again, _) = resumed.load_sample().expect("from the kept table");
    assert_eq!(
        eval(again.as_ref(), 22.5, 0.0, 52.5, 90.0),
        eval(b.as_ref(), 22.5, 0.0, 52.5, 90.0)
    );
}

#[test]
fn the_standalone_simulator_serves_a_microgeometry_sample() {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("surface.toml"), SURFACE).expect("write");
    config_with(
        dir.path(),
        "[sample.micro]\nsurface = \"surface.toml\"\ngrid = [15, 30]\nrays = 2000\n",
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_gonio-sim"))
        .arg("--config")
        .arg(dir.path().join("sim.toml"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("announces");
    let v: serde_json::Value = serde_json::from_str(&line).expect("one JSON line");
    assert!(v["motion"].as_str().is_some_and(|p| Path::new(p).exists()));
    // Served until a stop signal.
    let sent = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success());
    assert!(child.wait().expect("exits").success());
}

/// A rough gold surface whose refractive index is given per wavelength: the traced
/// table carries the wavelengths, and near the specular direction the colour comes
/// from Fresnel's equations alone, so the ratio of two wavelengths' values is their
/// normal-incidence reflectances' (the facets near the mirror direction sit near
/// normal incidence; multiple scattering, weak at this roughness, is the rest).
#[test]
fn a_microgeometry_sample_with_a_spectral_refractive_index_is_spectral() {
    let dir = tempfile::tempdir().expect("temp dir");
    let gold = r#"
channels = ["450nm", "550nm", "650nm"]
[surface]
kind = "gaussian"
size = [128, 128]
spacing = 1.0
rms_height = 0.3
correlation_length = 5.0
seed = 9
material = "gold"
[materials.gold]
kind = "conductor"
n = [1.38, 0.433, 0.166]
k = [1.86, 2.46, 3.15]
"#;
    std::fs::write(dir.path().join("surface.toml"), gold).expect("write");
    let mut cfg = config_with(
        dir.path(),
        "[sample.micro]\nsurface = \"surface.toml\"\ngrid = [10, 30]\nrays = 20000\nseed = 2\n",
    );
    cfg.prepare_sample().expect("traces");
    let (b, _) = cfg.load_sample().expect("prepared");
    assert_eq!(b.channels().names(), ["450nm", "550nm", "650nm"]);
    let mut v = vec![0.0; 3];
    b.eval(
        Dir::from(SphericalDeg::new(5.0, 0.0)),
        Dir::from(SphericalDeg::new(5.0, 180.0)),
        &mut v,
    );
    let fresnel = |n: f64, k: f64| ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
    let want = fresnel(0.166, 3.15) / fresnel(1.38, 1.86);
    let got = v[2] / v[0];
    println!("650/450: {got} vs Fresnel {want}; {v:?}");
    assert!(
        (got / want - 1.0).abs() < 0.05,
        "650/450: {got} vs Fresnel {want}"
    );
    assert!(v[0] < v[1] && v[1] < v[2], "gold reflects red best: {v:?}");
}
