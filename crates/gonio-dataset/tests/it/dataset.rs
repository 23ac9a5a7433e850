//! Every kind of input is recognised from its content (whatever its name) and opened
//! into the data it holds; analytic inputs are evaluated on a grid exactly, measured
//! ones resampled, scattered samples refused without a grid.

use std::path::Path;

use gonio_brdf::{Brdf, Model};
use gonio_core::{Dir, SphericalDeg};
use gonio_dataset::{Dataset, DatasetError, Kind, OpenOptions, detect, open};
use gonio_io::formats::{MerlBrdf, write_astm, write_merl};
use gonio_process::separable::SeparableBrdf;
use gonio_process::sh::{ShBrdf, ShOptions};
use gonio_process::{Grid, GridStep, Samples, Table};

fn paint() -> (Model, String) {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/blue-paint-550nm.toml"),
    )
    .expect("model file");
    (Model::from_toml(&text, None).expect("model"), text)
}

fn eval(b: &dyn Brdf, wi: Dir, wo: Dir) -> f64 {
    let mut v = vec![0.0; b.channels().len()];
    b.eval(wi, wo, &mut v);
    v[0]
}

/// Writes `bytes` under a name that says nothing of the content.
fn put(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write");
    p
}

#[test]
fn every_kind_is_recognised_from_its_content() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (model, text) = paint();
    let table = Table::from_brdf(&model, Grid::hemisphere(3, 8)).expect("table");
    let samples = Samples::from_table(&table);
    let mut scattered = samples.clone();
    scattered.samples.truncate(10);
    let sep = SeparableBrdf::from_table(&table, 1, false).expect("separable");
    let sh = ShBrdf::from_table(
        &table,
        &ShOptions {
            l_max: 2,
            l_filter: None,
            quadrature: None,
        },
    )
    .expect("harmonics");
    // MERL holds RGB: a grey Lambertian table in R, G, B.
    let grey = Model::from_toml(
        "kind = \"lambert\"\nchannels = [\"R\", \"G\", \"B\"]\nrho = [0.5, 0.5, 0.5]\n",
        None,
    )
    .expect("grey");
    let rgb = Table::from_brdf(&grey, Grid::hemisphere(3, 8)).expect("RGB table");
    let merl = write_merl(&MerlBrdf::from_table(&rgb).expect("MERL"));
    let cases: Vec<(&str, Vec<u8>, Kind, &str)> = vec![
        ("a", text.clone().into_bytes(), Kind::Model, "model"),
        (
            "b",
            gonio_process::file::write_table(&table).into_bytes(),
            Kind::Csv,
            "table",
        ),
        (
            "c",
            gonio_process::file::write_samples(&scattered).into_bytes(),
            Kind::Csv,
            "samples",
        ),
        (
            "d",
            write_astm(&scattered).into_bytes(),
            Kind::Astm,
            "samples",
        ),
        (
            "e",
            sep.to_toml().into_bytes(),
            Kind::Separable,
            "separable representation",
        ),
        (
            "f",
            sh.to_toml().into_bytes(),
            Kind::Harmonics,
            "spherical harmonics",
        ),
        ("g", merl, Kind::Merl, "MERL table"),
    ];
    for (name, bytes, kind, what) in cases {
        assert_eq!(detect(&bytes), Some(kind), "{name}");
        let p = put(dir.path(), name, &bytes);
        let o = open(&p, &OpenOptions::default()).expect("opens");
        assert_eq!(o.kind, kind, "{name}");
        assert_eq!(o.data.describe(), what, "{name}");
        assert!(o.reduction.is_none());
    }
    // A run file is recognised by SQLite's header; anything else is no Gonio input.
    assert_eq!(detect(b"SQLite format 3\0rest of a page"), Some(Kind::Run));
    assert_eq!(detect(b"hello, world\n"), None);
    let e = open(
        &put(dir.path(), "h", b"hello, world\n"),
        &OpenOptions::default(),
    )
    .expect_err("not an input");
    assert!(e.is_bad_input());
    assert!(
        e.to_string()
            .starts_with(&dir.path().join("h").display().to_string())
    );
}

#[test]
fn a_table_reads_back_to_the_same_values() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (model, _) = paint();
    let table = Table::from_brdf(&model, Grid::hemisphere(9, 36)).expect("table");
    let p = put(
        dir.path(),
        "t.csv",
        gonio_process::file::write_table(&table).as_bytes(),
    );
    let o = open(&p, &OpenOptions::default()).expect("opens");
    let Dataset::Table(t) = &o.data else {
        panic!("{}", o.data.describe())
    };
    assert_eq!(t.values, table.values);
    assert_eq!(
        o.data.to_table(None, &p).expect("as is").values,
        table.values
    );
}

#[test]
fn analytic_inputs_are_evaluated_on_the_grid_asked_for() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (model, text) = paint();
    let p = put(dir.path(), "m.toml", text.as_bytes());
    let o = open(&p, &OpenOptions::default()).expect("opens");
    let step = GridStep::new(15.0, 30.0).expect("grid");
    let t = o.data.to_table(Some(step), &p).expect("tabulated");
    assert_eq!(t.grid.len(), step.grid().len());
    // At every node exactly the model: evaluated there, not resampled.
    let exact = Table::from_brdf(&model, step.grid()).expect("direct");
    assert_eq!(t.values, exact.values);
    // Without a grid, 10° × 10°.
    let d = o.data.to_table(None, &p).expect("default grid");
    assert_eq!(d.grid.len(), Grid::hemisphere(9, 36).len());
    // The model evaluates anywhere.
    let (wi, wo) = (
        Dir::from(SphericalDeg::new(33.0, 12.0)),
        Dir::from(SphericalDeg::new(51.0, 201.0)),
    );
    assert_eq!(
        eval(o.data.brdf().expect("a BRDF"), wi, wo),
        eval(&model, wi, wo)
    );
}

#[test]
fn scattered_samples_need_a_grid_to_become_a_table() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A smooth BRDF, so that the kernel's estimate is close where samples are dense.
    let model = Model::from_toml(
        "kind = \"oren-nayar\"\nchannels = [\"value\"]\nrho = [0.8]\nsigma_deg = [20]\n",
        None,
    )
    .expect("model");
    let table = Table::from_brdf(&model, Grid::hemisphere(9, 36)).expect("table");
    let mut s = Samples::from_table(&table);
    // Every other sample: no longer a complete grid.
    s.samples = s.samples.into_iter().step_by(2).collect();
    let n = s.samples.len();
    let p = put(
        dir.path(),
        "s.csv",
        gonio_process::file::write_samples(&s).as_bytes(),
    );
    let o = open(&p, &OpenOptions::default()).expect("opens");
    assert!(matches!(o.data, Dataset::Samples(_)));
    assert!(o.data.brdf().is_none());
    let e = o.data.to_table(None, &p).expect_err("no grid given");
    assert!(matches!(e, DatasetError::NotOnGrid { samples, .. } if samples == n));
    assert!(e.is_bad_input());
    assert!(e.to_string().contains("pass --grid DTHETA,DPHI"), "{e}");
    // With a grid, resampled by the kernel: close to the model, not equal to it.
    let t = o
        .data
        .to_table(Some(GridStep::new(10.0, 10.0).expect("grid")), &p)
        .expect("resampled");
    let mut rel: Vec<f64> = t
        .values
        .iter()
        .zip(&table.values)
        .map(|(a, b)| ((a - b) / b).abs())
        .collect();
    rel.sort_by(f64::total_cmp);
    let median = rel[rel.len() / 2];
    assert!(
        median > 0.0 && median < 0.02,
        "median relative difference {median}"
    );
}

#[test]
fn a_missing_input_is_bad_input_naming_the_file() {
    let e = open(Path::new("/no/such/input.csv"), &OpenOptions::default()).expect_err("missing");
    assert!(e.is_bad_input());
    assert!(e.to_string().starts_with("/no/such/input.csv: "), "{e}");
}

/// A directory, a device or a FIFO named as an input is refused from its metadata,
/// as bad input, without being read (a FIFO is never opened): no command can block
/// on one, and /dev/zero is not read for ever.
#[cfg(unix)]
#[test]
fn an_input_that_is_not_a_regular_file_is_refused_unread() {
    let dir = tempfile::tempdir().expect("temp dir");
    let fifo = dir.path().join("pipe.csv");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    let mut cases = vec![
        (dir.path().to_path_buf(), "a directory"),
        (Path::new("/dev/zero").to_path_buf(), "a character device"),
    ];
    if made {
        cases.push((fifo, "a FIFO (named pipe)"));
    }
    for (p, what) in cases {
        let e = open(&p, &OpenOptions::default()).expect_err("not a regular file");
        assert!(e.is_bad_input(), "{e}");
        assert_eq!(
            e.to_string(),
            format!(
                "{}: {what}, not a regular file (Gonio reads its inputs from regular files only)",
                p.display()
            )
        );
    }
}

#[test]
fn a_table_moved_into_its_tabulated_form_is_the_one_tabulate_copies() {
    let (model, _) = paint();
    let p = Path::new("t.csv");
    let half = Grid::isotropic(
        gonio_process::Axis::polar_midpoints(3),
        gonio_process::Axis::from_deg(15.0, 30.0, 6),
        gonio_process::Axis::polar_midpoints(3),
    );
    assert!(gonio_process::hemisphere::half_turn(&half));
    let step = GridStep::new(30.0, 60.0).expect("step");
    for (g, step) in [
        (Grid::hemisphere(3, 8), None),
        (Grid::hemisphere_isotropic(3, 8), None),
        (half, None),
        (Grid::hemisphere(3, 8), Some(step)),
    ] {
        let d = Dataset::Table(Table::from_brdf(&model, g).expect("table"));
        let copied = d.tabulate(step, p).expect("tabulated");
        let moved = d.into_tabulated(step, p).expect("moved");
        assert_eq!(moved.table, copied.table);
        assert_eq!(moved.symmetry, copied.symmetry);
        assert_eq!(format!("{moved:?}"), format!("{copied:?}"));
    }
}
