//! `gonio reduce --json` and `gonio report` show the uncertainty budget, and the
//! report's labels say what they show.

use crate::common;

use common::{ISO_PLAN, acquire, gonio, ok, ok_json, s, scratch};

#[test]
fn reduce_json_gives_every_term_of_the_budget_and_keeps_the_old_fields() {
    let d = scratch("budget-json");
    let run = acquire(&d, ISO_PLAN);
    let v = ok_json(&["reduce", &s(&run), "--out", &s(&d.join("t.csv")), "--json"]);
    let ch = &v["reduction"]["channels"][0];
    for old in [
        "channel",
        "calibration",
        "dark_v",
        "incident_v",
        "incident_rel_sigma",
        "calibration_readings",
        "drift_readings",
        "drift_max",
        "samples",
    ] {
        assert!(!ch[old].is_null(), "{old} missing: {ch}");
    }
    assert!(
        ch.get("unit").is_none() && ch.get("incident_a").is_none(),
        "{ch}"
    );
    let budget = ch["budget"].as_array().expect("budget");
    let terms: Vec<&str> = budget
        .iter()
        .map(|t| t["term"].as_str().expect("term"))
        .collect();
    // The lock-in's terms, then the position term.
    assert_eq!(terms[..gonio_reduce::TERMS.len()], gonio_reduce::TERMS);
    assert_eq!(
        terms[gonio_reduce::TERMS.len()..],
        [gonio_reduce::POSITION_TERM]
    );
    for t in budget {
        let (med, max) = (t["rel_median"].as_f64(), t["rel_max"].as_f64());
        let (med, max) = (med.expect("median"), max.expect("max"));
        assert!(med >= 0.0 && max >= med, "{t}");
        assert!(!t["source"].as_str().expect("source").is_empty());
    }
    // The noise is there in every simulated run; the calibration is the incident beam's.
    assert!(budget[0]["rel_median"].as_f64().expect("noise") > 0.0);
    assert!(budget[3]["rel_median"].as_f64().expect("calibration") > 0.0);
    assert_eq!(budget[5]["rel_max"].as_f64(), Some(0.0), "no standard used");
}

#[test]
fn the_report_shows_the_budget_and_labels_what_each_panel_shows() {
    let d = scratch("budget-report");
    let run = acquire(&d, ISO_PLAN);
    ok(&["report", &s(&run), "--out", &s(&d.join("rep"))]);
    let html = std::fs::read_to_string(d.join("rep/report.html")).expect("html");
    for want in [
        "Uncertainty budget",
        "<td class=\"k\">dark</td>",
        "created (UTC)",
        "Hemisphere: measured data and fitted model",
        "Rendered sphere: measured data and fitted model",
    ] {
        assert!(html.contains(want), "missing {want:?}");
    }
    // A key's own name with its unit is not a label for a date.
    assert!(
        !html.contains("created s<"),
        "the 'created s' label is back"
    );
}

/// The standard's own uncertainty enters the budget when the standard calibrates,
/// and adds in quadrature to every sample's σ; a value outside [0, 1] is refused.
#[test]
fn the_standard_s_uncertainty_is_a_term_of_the_budget() {
    let d = scratch("budget-standard");
    let plan = format!(
        "{ISO_PLAN}standard = {{ model = \"{}\", at = [[0, 0, 45, 180]] }}\n",
        common::config("models/white-reference.toml")
    );
    let run = acquire(&d, &plan);
    let reduce = |sigma: &str, out: &str| {
        ok_json(&[
            "reduce",
            &s(&run),
            "--out",
            &s(&d.join(out)),
            "--calibration",
            "standard",
            "--standard-sigma",
            sigma,
            "--json",
        ])
    };
    let v = reduce("0.005", "a.csv");
    let term = &v["reduction"]["channels"][0]["budget"][5];
    assert_eq!(term["term"], "standard");
    assert_eq!(term["rel_median"].as_f64(), Some(0.005), "{term}");
    let sigma_col = |out: &str| -> Vec<f64> {
        let text = std::fs::read_to_string(d.join(out)).expect("table");
        text.lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("theta") && !l.is_empty())
            .filter_map(|l| l.split(',').next_back()?.trim().parse().ok())
            .collect()
    };
    reduce("0", "b.csv");
    let (with, without) = (sigma_col("a.csv"), sigma_col("b.csv"));
    assert!(!with.is_empty() && with.len() == without.len());
    assert!(
        with.iter().zip(&without).all(|(a, b)| a > b),
        "σ grows with the term"
    );
    for bad in ["-0.1", "2", "nan"] {
        let o = gonio(&[
            "reduce",
            &s(&run),
            "--out",
            &s(&d.join("c.csv")),
            "--standard-sigma",
            bad,
        ]);
        assert_eq!(o.status.code(), Some(2), "{bad}");
    }
}
