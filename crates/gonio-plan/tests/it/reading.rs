//! The `[reading]` table (reading time): parsing with its defaults, each field's range
//! refused with its field, line and limit, and plans without it unchanged.

use gonio_plan::Plan;
use gonio_plan::plan::ReadingConfig;

const IN_PLANE: &str = "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [30]\n";

fn with_reading(body: &str) -> String {
    format!("{IN_PLANE}[reading]\n{body}")
}

#[test]
fn a_full_reading_table_parses_to_its_values() {
    let p = Plan::from_toml(
        &with_reading(
            "sigma_relative = 1e-4\nsigma_absolute = 2e-9\nmax_s = 12.5\nmin_samples = 7\n",
        ),
        None,
    )
    .expect("parses");
    assert_eq!(
        p.reading,
        Some(ReadingConfig {
            sigma_relative: 1e-4,
            sigma_absolute: Some(2e-9),
            max_s: 12.5,
            min_samples: 7,
        })
    );
}

#[test]
fn the_optional_fields_take_their_documented_defaults() {
    let p = Plan::from_toml(&with_reading("sigma_relative = 0.01\n"), None).expect("parses");
    assert_eq!(
        p.reading,
        Some(ReadingConfig {
            sigma_relative: 0.01,
            sigma_absolute: None,
            max_s: 30.0,
            min_samples: 2,
        })
    );
    // The ends of each range are accepted.
    let p = Plan::from_toml(
        &with_reading(
            "sigma_relative = 1e-7\nsigma_absolute = 1\nmax_s = 3600\nmin_samples = 10000\n",
        ),
        None,
    )
    .expect("upper ends");
    let r = p.reading.expect("table");
    assert_eq!(
        (r.sigma_relative, r.sigma_absolute, r.max_s, r.min_samples),
        (1e-7, Some(1.0), 3600.0, 10000)
    );
    let p = Plan::from_toml(
        &with_reading("sigma_relative = 0.1\nmin_samples = 1\n"),
        None,
    )
    .expect("other ends");
    let r = p.reading.expect("table");
    assert_eq!((r.sigma_relative, r.min_samples), (0.1, 1));
}

#[test]
fn a_plan_without_the_table_has_none_and_the_shipped_plans_still_load() {
    let p = Plan::from_toml(IN_PLANE, None).expect("parses");
    assert_eq!(p.reading, None);
    // Run files store the plan text and parse it again on resume: every plan the
    // repository ships must still load; only the targeted one has a reading table.
    let config = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
    let mut n = 0;
    for e in std::fs::read_dir(&config).expect("config dir") {
        let path = e.expect("entry").path();
        let name = path.file_name().and_then(|s| s.to_str()).unwrap_or("");
        if name.starts_with("plan-") && name.ends_with(".toml") {
            let (plan, _) = Plan::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let targeted = name == "plan-hemisphere-targeted.toml";
            assert_eq!(plan.reading.is_some(), targeted, "{name}");
            if targeted {
                let r = plan.reading.expect("table");
                assert_eq!(
                    (r.sigma_relative, r.sigma_absolute, r.max_s, r.min_samples),
                    (1e-4, None, 30.0, 2)
                );
            }
            n += 1;
        }
    }
    assert!(n >= 4, "found {n} plans in {}", config.display());
}

#[test]
fn each_field_outside_its_range_is_refused_with_field_line_and_limit() {
    // (table body, line of the fault, field, message)
    let cases: &[(&str, usize, &str, &str)] = &[
        (
            "sigma_relative = 1e-8\n",
            6,
            "reading.sigma_relative",
            "must be at least 1e-7, got 1e-8",
        ),
        (
            "sigma_relative = 0.2\n",
            6,
            "reading.sigma_relative",
            "must be at most 0.1, got 0.2",
        ),
        (
            "sigma_relative = nan\n",
            6,
            "reading.sigma_relative",
            "must be finite, got NaN",
        ),
        (
            "sigma_relative = -1e-4\n",
            6,
            "reading.sigma_relative",
            "must be at least 1e-7, got -1e-4",
        ),
        (
            "sigma_relative = 1e-4\nsigma_absolute = 0\n",
            7,
            "reading.sigma_absolute",
            "must be positive, got 0",
        ),
        (
            "sigma_relative = 1e-4\nsigma_absolute = 2\n",
            7,
            "reading.sigma_absolute",
            "must be at most 1, got 2",
        ),
        (
            "sigma_relative = 1e-4\nsigma_absolute = inf\n",
            7,
            "reading.sigma_absolute",
            "must be finite, got inf",
        ),
        (
            "sigma_relative = 1e-4\nmax_s = 0\n",
            7,
            "reading.max_s",
            "must be positive, got 0",
        ),
        (
            "sigma_relative = 1e-4\nmax_s = 3601\n",
            7,
            "reading.max_s",
            "must be at most 3600 s, got 3601",
        ),
        (
            "sigma_relative = 1e-4\nmax_s = nan\n",
            7,
            "reading.max_s",
            "must be finite, got NaN",
        ),
        (
            "sigma_relative = 1e-4\nmin_samples = 0\n",
            7,
            "reading.min_samples",
            "must be at least 1, got 0",
        ),
        (
            "sigma_relative = 1e-4\nmin_samples = 10001\n",
            7,
            "reading.min_samples",
            "must be at most 10000, got 10001",
        ),
    ];
    for (body, line, field, message) in cases {
        let e = Plan::from_toml(&with_reading(body), None).expect_err(body);
        assert_eq!(e.field.as_deref(), Some(*field), "{body}: {e}");
        assert_eq!(e.line, Some(*line), "{body}: {e}");
        assert!(e.to_string().contains(message), "{body}: {e}");
    }
}

#[test]
fn the_table_is_read_strictly() {
    // sigma_relative is required in the table.
    let e = Plan::from_toml(&with_reading("max_s = 10\n"), None).expect_err("no target");
    assert!(e.to_string().contains("sigma_relative"), "{e}");
    // An unknown key is refused on its line.
    let e = Plan::from_toml(&with_reading("sigma_relative = 1e-4\nsigma = 3\n"), None)
        .expect_err("unknown key");
    assert_eq!(e.line, Some(7), "{e}");
    assert!(e.to_string().contains("sigma"), "{e}");
    // A negative count is not a u32.
    let e = Plan::from_toml(
        &with_reading("sigma_relative = 1e-4\nmin_samples = -3\n"),
        None,
    )
    .expect_err("negative");
    assert_eq!(e.line, Some(7), "{e}");
}
