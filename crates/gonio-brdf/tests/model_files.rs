//! Model files: every kind round-trips, the shipped configs load, and bad files get
//! errors that name the file, the line and the field.

mod common;

use std::path::Path;

use gonio_brdf::{Model, ModelErrorKind};

#[test]
fn every_kind_round_trips_exactly() {
    for (name, m) in common::zoo() {
        let text = m.to_toml();
        let back = Model::from_toml(&text, None).unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
        assert_eq!(back, m, "{name}:\n{text}");
        assert_eq!(back.to_toml(), text, "{name}: writing is not stable");
    }
}

#[test]
fn shipped_model_configs_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("config/models exists") {
        let path = entry.expect("readable").path();
        if path.extension().is_some_and(|e| e == "toml") {
            let m = Model::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let back = Model::from_toml(&m.to_toml(), None).expect("written file reads back");
            assert_eq!(back, m, "{}", path.display());
            n += 1;
        }
    }
    assert!(n >= 8, "expected an example of every kind, found {n}");
}

/// The first line of the error, as the CLI prints it.
fn err(text: &str) -> gonio_brdf::ModelError {
    Model::from_toml(text, Some(Path::new("paint.toml"))).expect_err("must be refused")
}

#[test]
fn wrong_length_names_field_and_line() {
    let e = err(r#"kind = "lafortune"
channels = ["R", "G", "B"]

[[lobes]]
cx = [-1.0, -1.0, -1.0]
cz = [0.9, 0.9]
n = [10, 10, 10]
"#);
    assert_eq!(e.kind, ModelErrorKind::Invalid);
    assert_eq!(e.line, Some(6));
    assert_eq!(e.field.as_deref(), Some("lobes[0].cz"));
    assert_eq!(
        e.to_string(),
        "paint.toml:6:6: field `lobes[0].cz`: expected 3 values (one per channel R,G,B), got 2"
    );
}

#[test]
fn unknown_keys_are_errors() {
    let e = err(r#"kind = "lambert"
channels = ["value"]
rho = [0.5]
roughness = [0.1]
"#);
    assert_eq!(e.kind, ModelErrorKind::Syntax);
    assert_eq!(e.line, Some(4));
    assert!(e.message.contains("unknown field `roughness`"), "{e}");

    let e = err(r#"kind = "lafortune"
channels = ["value"]
[[lobes]]
cx = [1.0]
cz = [1.0]
n = [2]
exponent = [3]
"#);
    assert_eq!(e.line, Some(7), "{e}");
    assert!(e.message.contains("unknown field `exponent`"), "{e}");
}

#[test]
fn out_of_range_values_name_the_channel() {
    let e = err(r#"kind = "cook-torrance"
channels = ["R", "G", "B"]
distribution = "ggx"
f0 = [0.9, 1.2, 0.5]
alpha = [0.2, 0.2, 0.2]
"#);
    assert_eq!(e.field.as_deref(), Some("f0"));
    assert_eq!(e.line, Some(4));
    assert!(
        e.message.contains("1.2 for channel G must be in [0, 1]"),
        "{e}"
    );

    let e = err(r#"kind = "phong"
channels = ["value"]
rho_s = [0.2]
n = [20]
[diffuse]
rho = [0.3]
n = [-1]
"#);
    assert_eq!(e.field.as_deref(), Some("diffuse.n"));
    assert_eq!(e.line, Some(7));
}

#[test]
fn structural_mistakes() {
    let e = err("channels = [\"value\"]\nrho = [0.5]\n");
    assert_eq!(e.field.as_deref(), Some("kind"));
    assert!(e.message.contains("missing `kind`"));

    let e = err("kind = \"gaussian\"\nchannels = [\"value\"]\n");
    assert_eq!(e.line, Some(1));
    assert!(e.message.contains("unknown kind \"gaussian\""), "{e}");

    let e = err("kind = \"lambert\"\nchannels = [\"R\", \"B\", \"G\"]\nrho = [0.1, 0.2, 0.3]\n");
    assert_eq!(e.field.as_deref(), Some("channels"));
    assert_eq!(e.line, Some(2));

    let e = err(r#"kind = "ward"
channels = ["value"]
rho_s = [0.1]
alpha = [0.1]
alpha_x = [0.1]
alpha_y = [0.2]
"#);
    assert_eq!(e.field.as_deref(), Some("alpha"));
    assert_eq!(e.line, Some(4));

    let e = err("kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.1]\nalpha = [1e-5]\n");
    assert_eq!(e.field.as_deref(), Some("alpha_x"));
    assert!(e.message.contains("must be ≥ 1e-4"), "{e}");

    let e = err(r#"kind = "lafortune"
channels = ["value"]
[[lobes]]
m = [[[-0.8, 0.0, 0.1], [0.0, -0.8, 0.0], [0.1, 0.0, 0.9]]]
n = [10]
[mirror]
rm = [0.5]
"#);
    assert_eq!(e.field.as_deref(), Some("mirror"));
    assert_eq!(e.line, Some(6));
    assert!(e.message.contains("lobes[0]"), "{e}");

    let e = err("kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.1]\nalpha_x = [0.1]\n");
    assert_eq!(e.field.as_deref(), Some("alpha_y"));
    assert_eq!(e.line, Some(4));

    let e = err(r#"kind = "lafortune"
channels = ["value"]
[[lobes]]
m = [[[1.0, 0.5, 0.0], [0.4, 1.0, 0.0], [0.0, 0.0, 1.0]]]
n = [3]
"#);
    assert_eq!(e.field.as_deref(), Some("lobes[0].m"));
    assert!(e.message.contains("not symmetric"), "{e}");

    let e = err(r#"kind = "lafortune"
channels = ["value"]
[[lobes]]
cx = [1.0]
n = [3]
"#);
    assert_eq!(e.field.as_deref(), Some("lobes[0]"));

    let e = err("kind = \"lambert\"\nchannels = [\"value\"]\nrho = [0.5\n");
    assert_eq!(e.kind, ModelErrorKind::Syntax);
    assert!(e.line.is_some());

    let e = err("kind = \"oren-nayar\"\nchannels = [\"value\"]\nrho = [0.5]\nsigma_deg = [95]\n");
    assert_eq!(e.field.as_deref(), Some("sigma_deg"));
    assert!(e.message.contains("[0, 90) degrees"), "{e}");

    let e = err("kind = \"lambert\"\nchannels = [\"value\"]\nrho = [\"half\"]\n");
    assert_eq!(e.kind, ModelErrorKind::Syntax);
    assert_eq!(e.line, Some(3));
}

#[test]
fn values_of_the_wrong_type_name_their_field() {
    let e = err("kind = \"lambert\"\nchannels = [\"value\"]\nrho = [\"half\"]\n");
    assert_eq!(
        e.to_string(),
        "paint.toml:3:8: field `rho[0]`: invalid type: string \"half\", expected f64"
    );
    let e = err("kind = \"phong\"\nchannels = [\"value\"]\nrho_s = [0.2]\nn = [20]\nshading = 1\n");
    assert_eq!(
        e.to_string(),
        "paint.toml:5:11: field `shading`: invalid type: integer `1`, expected a boolean"
    );
    let e = err(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[[lobes]]\ncx = [1.0]\ncz = 1.0\nn = [2]\n",
    );
    assert_eq!(
        e.to_string(),
        "paint.toml:5:6: field `lobes[0].cz`: invalid type: floating point `1.0`, expected a sequence"
    );
}

/// Found by the `model_file` fuzz target: a Blinn-Phong exponent of 1e308 was
/// accepted with a NaN normalisation.
#[test]
fn an_exponent_whose_normalisation_overflows_is_refused() {
    let e = err(
        "kind = \"blinn-phong\"\nchannels = [\"R\", \"G\", \"B\"]\nrho_s = [0.1, 0.1, 0.1]\nn = [20, 1e308, 20]\n",
    );
    assert_eq!(
        e.to_string(),
        "paint.toml:4:5: field `n`: 1e308 for channel G is too large: its normalisation overflows"
    );
    // Large but representable exponents still read.
    let m = Model::from_toml(
        "kind = \"blinn-phong\"\nchannels = [\"value\"]\nrho_s = [0.1]\nn = [1e150]\n",
        None,
    )
    .expect("n = 1e150");
    assert_eq!(Model::from_toml(&m.to_toml(), None).expect("reads back"), m);
}

#[test]
fn a_byte_order_mark_is_ignored() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models");
    for name in [
        "blue-paint-550nm.toml",
        "lafortune-fig9.toml",
        "ward-brushed.toml",
    ] {
        let text = std::fs::read_to_string(dir.join(name)).expect("shipped model");
        assert_eq!(
            Model::from_toml(&format!("\u{feff}{text}"), None).expect(name),
            Model::from_toml(&text, None).expect(name),
        );
    }
    // Places on the first line do not count the mark as a column.
    let e = err("\u{feff}kind = \"gaussian\"\nchannels = [\"value\"]\n");
    assert_eq!((e.line, e.column), (Some(1), Some(8)));
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let e = Model::load(Path::new("/nonexistent/model.toml")).expect_err("no such file");
    assert_eq!(e.kind, ModelErrorKind::Io);
    assert!(
        e.to_string().starts_with("/nonexistent/model.toml: "),
        "{e}"
    );
}

#[test]
fn cy_defaults_to_cx() {
    let a = Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[[lobes]]\ncx = [-1.0]\ncz = [0.9]\nn = [5]\n",
        None,
    )
    .expect("valid");
    let b = Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[[lobes]]\ncx = [-1.0]\ncy = [-1.0]\ncz = [0.9]\nn = [5]\n",
        None,
    )
    .expect("valid");
    assert_eq!(a, b);
}
