//! Model files: every kind round-trips, the shipped configs load, and bad files get
//! errors that name the file, the line and the field.

use crate::common;

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

    // An isotropic `alpha` is named as the file gives it.
    let e = err("kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.1]\nalpha = [1e-5]\n");
    assert_eq!(e.field.as_deref(), Some("alpha"));
    assert!(e.message.contains("must be in [1e-4, 10]"), "{e}");

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
/// accepted with a NaN normalisation. Exponents now have a range (docs/models.md).
#[test]
fn an_exponent_whose_normalisation_overflows_is_refused() {
    let e = err(
        "kind = \"blinn-phong\"\nchannels = [\"R\", \"G\", \"B\"]\nrho_s = [0.1, 0.1, 0.1]\nn = [20, 1e308, 20]\n",
    );
    assert_eq!(
        e.to_string(),
        "paint.toml:4:5: field `n`: 1e308 for channel G must be in [0, 1e6]"
    );
    // The largest exponent allowed reads, and reads back.
    let m = Model::from_toml(
        "kind = \"blinn-phong\"\nchannels = [\"value\"]\nrho_s = [0.1]\nn = [1e6]\n",
        None,
    )
    .expect("n = 1e6");
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

/// Every numeric parameter has a finite range, and an absurd or non-finite value is
/// refused with the field, its place and the range (docs/models.md, "Limits").
#[test]
fn absurd_and_non_finite_parameters_name_the_field_and_the_limit() {
    let cases: &[(&str, usize, &str, &str)] = &[
        (
            "kind = \"blinn-phong\"\nchannels = [\"value\"]\nrho_s = [0.04]\nn = [1e308]\n",
            4,
            "n",
            "1e308 for channel value must be in [0, 1e6]",
        ),
        (
            "kind = \"cook-torrance\"\nchannels = [\"value\"]\ndistribution = \"ggx\"\n\
             f0 = [0.5]\nalpha = [1e300]\n",
            5,
            "alpha",
            "1e300 for channel value must be in [1e-4, 10]",
        ),
        (
            "kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.1]\nalpha_x = [0.1]\n\
             alpha_y = [nan]\n",
            5,
            "alpha_y",
            "NaN for channel value must be in [1e-4, 10]",
        ),
        (
            "kind = \"lambert\"\nchannels = [\"value\"]\nrho = [inf]\n",
            3,
            "rho",
            "inf for channel value must be in [0, 100]",
        ),
        (
            "kind = \"minnaert\"\nchannels = [\"value\"]\nrho = [0.5]\nn = [1e7]\n",
            4,
            "n",
            "1e7 for channel value must be in [0, 1e6]",
        ),
        (
            "kind = \"phong\"\nchannels = [\"value\"]\nrho_s = [1e3]\nn = [10]\n",
            3,
            "rho_s",
            "1000 for channel value must be in [0, 100]",
        ),
        (
            "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.5]\nn = [-nan]\n",
            5,
            "diffuse.n",
            "NaN for channel value must be in [0, 1e6]",
        ),
        (
            // |C| = 2 with n = 100: a peak of 2^100 ≈ 1.3e30 1/sr.
            "kind = \"lafortune\"\nchannels = [\"value\"]\n[[lobes]]\ncx = [-2.0]\n\
             cz = [1.0]\nn = [100]\n",
            6,
            "lobes[0].n",
            "100 for channel value makes the lobe peak at 2^100 = 1.2676506002282294e30 1/sr, \
             more than 1e12",
        ),
    ];
    for (text, line, field, message) in cases {
        let e = err(text);
        assert_eq!(e.kind, ModelErrorKind::Invalid, "{e}");
        assert_eq!(
            e.to_string(),
            format!(
                "paint.toml:{line}:{}: field `{field}`: {message}",
                e.column.unwrap_or(0)
            ),
            "{text}"
        );
        assert_eq!(e.line, Some(*line), "{e}");
    }
    // A lobe that peaks within the cap loads: |C| = 1.05, n = 500 peaks at 4e10.
    Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[[lobes]]\ncx = [-1.05]\ncz = [1.0]\nn = [500]\n",
        None,
    )
    .expect("a sharp lobe within the cap");
}

#[test]
fn a_general_lobe_matrix_is_bounded_by_its_largest_eigenvalue() {
    use gonio_brdf::Sym3;
    // Eigenvalues 2, −4 and 1 (the first two in a rotated frame): the largest magnitude is 4.
    let m =
        Sym3::from_rows([[-1.0, 3.0, 0.0], [3.0, -1.0, 0.0], [0.0, 0.0, 1.0]]).expect("symmetric");
    assert!(
        (m.largest_magnitude() - 4.0).abs() < 1e-12,
        "{}",
        m.largest_magnitude()
    );
    let m =
        Sym3::from_rows([[2.0, 1.0, 1.0], [1.0, 2.0, 1.0], [1.0, 1.0, 2.0]]).expect("symmetric");
    assert!(
        (m.largest_magnitude() - 4.0).abs() < 1e-12,
        "{}",
        m.largest_magnitude()
    );
    assert_eq!(Sym3::diagonal(0.5, -0.9, 0.7).largest_magnitude(), 0.9);
}

#[cfg(unix)]
#[test]
fn a_device_or_a_directory_named_as_a_model_is_refused_unread() {
    let e = Model::load(Path::new("/dev/zero")).expect_err("a device");
    assert_eq!(e.kind, ModelErrorKind::Io);
    assert_eq!(
        e.to_string(),
        "/dev/zero: a character device, not a regular file (Gonio reads its inputs from regular files only)"
    );
    let e = Model::load(Path::new(env!("CARGO_MANIFEST_DIR"))).expect_err("a directory");
    assert!(
        e.to_string().contains("a directory, not a regular file"),
        "{e}"
    );
}
