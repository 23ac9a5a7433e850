//! `gonio export`, `plot` and `report` as processes.

mod common;

use std::path::Path;

use common::{ISO_PLAN, acquire, gonio, ok, root, s, scratch};
use serde_json::Value;

#[test]
fn the_report_of_a_run_is_one_self_contained_page() {
    let d = scratch("report");
    let run = acquire(&d, ISO_PLAN);
    let o = ok(&["report", &s(&run), "--out", &s(&d.join("rep")), "--json"]);
    let v: Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["figures"], 5, "{v}");
    let html = std::fs::read_to_string(d.join("rep/report.html")).expect("html");
    for want in [
        "isotropic grid",
        "Calibration and reduction",
        "P<sub>r</sub> reciprocity",
        "Lobe fit (Lafortune et al. 1997)",
        "Cook-Torrance (GGX)",
        "<svg",
        "Rendered sphere",
        "[points]",
    ] {
        assert!(html.contains(want), "missing {want:?}");
    }
    // Self-contained: nothing is fetched (the SVG namespace is a name, not a fetch).
    let fetched = html
        .replace("http://www.w3.org/2000/svg", "")
        .replace("http://www.w3.org/1999/xlink", "");
    for bad in ["http://", "https://", "<script", "<link", "<img src=\"http"] {
        assert!(!fetched.contains(bad), "found {bad:?}");
    }
}

#[test]
fn export_round_trips_and_plots_are_written() {
    let d = scratch("export");
    let model = root().join("config/models/blue-paint-550nm.toml");
    // A table of the model, then ASTM and back: the same numbers.
    let table = d.join("t.csv");
    ok(&[
        "correct",
        &s(&model),
        "--grid",
        "30,90",
        "--reciprocity",
        "1",
        "--out",
        &s(&table),
    ]);
    let astm = d.join("t.astm");
    ok(&["export", &s(&table), "--format", "astm", "--out", &s(&astm)]);
    let back = d.join("back.csv");
    ok(&["export", &s(&astm), "--format", "csv", "--out", &s(&back)]);
    let nums = |p: &Path| -> Vec<f64> {
        std::fs::read_to_string(p)
            .expect("read")
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("theta"))
            .flat_map(|l| {
                l.split(',')
                    .map(|x| x.parse::<f64>().expect("number"))
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (a, b) = (nums(&table), nums(&back));
    assert_eq!(a.len(), b.len());
    let mut pa: Vec<f64> = a.clone();
    let mut pb: Vec<f64> = b.clone();
    pa.sort_by(f64::total_cmp);
    pb.sort_by(f64::total_cmp);
    assert_eq!(pa, pb);
    // A MERL file is exactly 34,992,012 bytes (needs three channels: an RGB model).
    let rgb = root().join("config/models/conventions-example.toml");
    let merl = d.join("m.binary");
    let o = ok(&[
        "export",
        &s(&rgb),
        "--format",
        "merl",
        "--out",
        &s(&merl),
        "--json",
    ]);
    let v: Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["bytes"], 34_992_012);
    assert_eq!(std::fs::metadata(&merl).expect("merl").len(), 34_992_012);
    // Every plot kind, as PNG.
    for kind in ["polar", "hemisphere", "albedo", "separability", "sphere"] {
        let png = d.join(format!("{kind}.png"));
        ok(&[
            "plot",
            &s(&model),
            "--fit",
            &s(&model),
            "--kind",
            kind,
            "--out",
            &s(&png),
        ]);
        let bytes = std::fs::read(&png).expect("png");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{kind}");
        assert!(bytes.len() > 5_000, "{kind}: {} bytes", bytes.len());
    }
    let o = gonio(&[
        "plot",
        &s(&model),
        "--kind",
        "pie",
        "--out",
        &s(&d.join("x.png")),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let o = gonio(&[
        "plot",
        &s(&model),
        "--kind",
        "polar",
        "--out",
        &s(&d.join("x.gif")),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let o = gonio(&[
        "export",
        &s(&model),
        "--format",
        "tiff",
        "--out",
        &s(&d.join("x")),
    ]);
    assert_eq!(o.status.code(), Some(2));
}
