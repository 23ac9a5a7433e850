//! `gonio report` of an adaptive run shows where its points went: the budget and what
//! each stage took, a row per decision, and the sample directions by batch, a panel
//! per incidence; a grid run's report shows none of it.

use crate::common;

use common::{ISO_PLAN, acquire, ok, s, scratch};
use gonio_io::plot::batch_colour;
use gonio_run::RunStore;
use serde_json::Value;

/// The repository's adaptive plan with a budget small enough for a test.
const ADAPTIVE_PLAN: &str = r#"
name = "adaptive report"
[points]
kind = "adaptive"
phi_i = 0
theta_i = [30, 60]
budget = { points = 120 }
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

/// The part of `html` from `start` to the next `<h2>` (or the end).
fn section<'a>(html: &'a str, start: &str) -> &'a str {
    let i = html.find(start).unwrap_or_else(|| panic!("no {start:?}"));
    let rest = &html[i + start.len()..];
    &html[i..i + start.len() + rest.find("<h2>").unwrap_or(rest.len())]
}

/// Filled circles of an SVG in an 8-bit colour.
fn circles(svg: &str, [r, g, b]: [u8; 3]) -> usize {
    let fill = format!("fill=\"#{r:02X}{g:02X}{b:02X}\"");
    svg.split("<circle")
        .skip(1)
        .filter(|t| t.split("/>").next().is_some_and(|t| t.contains(&fill)))
        .count()
}

#[test]
fn the_report_of_an_adaptive_run_shows_where_the_points_went() {
    let d = scratch("adaptive-report");
    let run = acquire(&d, ADAPTIVE_PLAN);
    let store = RunStore::open_read_only(&run).expect("the run file");
    let decisions = store.decisions().expect("decisions");
    let points = gonio_reduce::adaptive::points_by_batch(&store).expect("points by batch");
    drop(store);
    assert!(decisions.len() >= 2, "{} decisions", decisions.len());
    let details: Vec<Value> = decisions
        .iter()
        .map(|d| serde_json::from_str(&d.detail).expect("detail is JSON"))
        .collect();
    let budget = details[0]["budget_points"].as_u64().expect("budget_points");
    assert_eq!(budget, 120);
    let coarse = points.iter().filter(|p| p.0 == 0).count();
    let chosen: u32 = decisions.iter().map(|d| d.points).sum();
    assert_eq!(coarse + chosen as usize, points.len());
    assert!(points.len() <= 120);

    let rep = d.join("rep");
    let o = ok(&["report", &s(&run), "--out", &s(&rep), "--json"]);
    let v: Value = serde_json::from_slice(&o.stdout).expect("json");
    let html = std::fs::read_to_string(rep.join("report.html")).expect("html");
    assert_eq!(
        v["figures"].as_u64(),
        Some(html.matches("<figure>").count() as u64),
        "{v}"
    );
    let sec = section(&html, "<h2>Adaptive sampling</h2>");

    // The sentence: the budget and each stage's points.
    let stages: Vec<String> = decisions
        .iter()
        .map(|d| format!("batch {} took {}", d.id, d.points))
        .collect();
    let sentence = format!(
        "<p>The budget was {budget} points: the coarse pass took {coarse} points, {}; {} \
         points in all, {chosen} of them chosen during the run.</p>",
        stages.join(", "),
        points.len()
    );
    assert!(sec.contains(&sentence), "{sentence}\n{sec}");

    // The table: a row per decision, with its points, steps, method and readings.
    let rows: Vec<&str> = sec.lines().filter(|l| l.starts_with("<tr><td>")).collect();
    assert_eq!(rows.len(), decisions.len(), "{sec}");
    for ((row, dec), det) in rows.iter().zip(&decisions).zip(&details) {
        let start = format!(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"k\">{}</td><td>{}</td><td>",
            dec.id, dec.points, dec.steps, dec.method, dec.readings
        );
        assert!(row.starts_with(&start), "{row}\nwant {start}");
        // The estimated time, as the decision recorded it (under 2 min here: seconds).
        let est = det["estimate_s"].as_f64().expect("estimate_s");
        assert!(est > 0.0 && est < 120.0, "{est}");
        assert!(row.ends_with(&format!("<td>{est:.0} s</td></tr>")), "{row}");
    }
    // Each later decision saw more readings than the one before.
    for w in decisions.windows(2) {
        assert!(w[1].readings > w[0].readings);
    }

    // The figure: a panel per incidence, captioned with its points; a filled circle a
    // point in its batch's colour (and one more grey: the coarse pass's legend mark).
    let fig_at = sec
        .find("<figure><h3>Where the points went</h3><svg")
        .expect("the figure, inline SVG");
    let fig = &sec[fig_at..sec.find("</figure>").expect("figure ends")];
    assert!(
        fig.contains("radius ∝ θo"),
        "the caption says the projection"
    );
    assert!(!fig.contains("not yet measured"), "the run is complete");
    for ti in [30.0, 60.0] {
        let n = points
            .iter()
            .filter(|p| p.1.incident.theta_deg == ti && p.1.incident.phi_deg == 0.0)
            .count();
        assert!(n > 0);
        let caption = format!("θi = {ti}°, φi = 0°: {n} points");
        assert!(fig.contains(&caption), "{caption}");
    }
    let batches = decisions.len();
    for b in 0..=batches {
        let want = points.iter().filter(|p| p.0 == b).count() + usize::from(b == 0);
        assert_eq!(circles(fig, batch_colour(b, batches)), want, "batch {b}");
        if b > 0 {
            assert_eq!(want, decisions[b - 1].points as usize, "batch {b}");
        }
    }

    // The same run gives the same page, byte for byte.
    let again = d.join("again");
    ok(&["report", &s(&run), "--out", &s(&again)]);
    assert!(std::fs::read_to_string(again.join("report.html")).expect("html") == html);
}

#[test]
fn a_grid_runs_report_has_no_adaptive_part() {
    let d = scratch("grid-report");
    let run = acquire(&d, ISO_PLAN);
    let store = RunStore::open_read_only(&run).expect("the run file");
    assert!(store.decisions().expect("decisions").is_empty());
    drop(store);
    let rep = d.join("rep");
    let o = ok(&["report", &s(&run), "--out", &s(&rep), "--json"]);
    let v: Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["figures"], 5, "{v}");
    let html = std::fs::read_to_string(rep.join("report.html")).expect("html");
    assert_eq!(html.matches("<figure>").count(), 5);
    for absent in [
        "Adaptive sampling",
        "Where the points went",
        "decided from",
        "coarse pass",
        "The budget was",
    ] {
        assert!(!html.contains(absent), "{absent:?}");
    }
}
