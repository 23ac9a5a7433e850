//! `gonio export`, `plot` and `report` as processes.

use crate::common;

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

/// The CSV `gonio export` writes loads with `pandas.read_csv(path)` and no arguments
/// (run when a Python with pandas is at $PYTHON or /tmp/scipyenv/bin/python), and a
/// table written in format 1 (`#` lines, unitless names) still reads and exports to
/// the same values.
#[test]
fn exported_csv_is_what_pandas_reads_and_format_1_still_reads() {
    let d = scratch("pandas");
    let model = root().join("config/models/phong-shading.toml");
    let table = d.join("table.csv");
    ok(&["export", &s(&model), "--format", "csv", "--out", &s(&table)]);
    assert!(d.join("table.csv.json").is_file(), "the sidecar");
    let astm = d.join("s.astm");
    std::fs::write(
        &astm,
        "NUM_POINTS 3\nVARS theta_i phi_i theta_s phi_s R G B\n\
         30 0 30 180 0.25 0.5 0.125\n30 0 40 180 0.2 0.4 0.1\n45 10 20 170 0.3 0.6 0.15\n",
    )
    .expect("astm");
    let samples = d.join("samples.csv");
    ok(&[
        "export",
        &s(&astm),
        "--format",
        "csv",
        "--out",
        &s(&samples),
    ]);
    assert_eq!(
        std::fs::read_to_string(&samples).expect("samples"),
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_R_per_sr,f_r_G_per_sr,f_r_B_per_sr\n\
         30,0,30,180,0.25,0.5,0.125\n30,0,40,180,0.2,0.4,0.1\n45,10,20,170,0.3,0.6,0.15\n"
    );

    // Format 1 of the same table, as Gonio wrote it before: same measures, and an
    // export to format 2 gives the same bytes.
    let new = std::fs::read_to_string(&table).expect("table");
    let side: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("table.csv.json")).expect("json"))
            .expect("sidecar");
    let axis = |n: &str| {
        let a = &side["grid"][n];
        format!("{}:{}:{}", a["start_deg"], a["step_deg"], a["n"]).replace(".0:", ":")
    };
    let old = format!(
        "# gonio-table: 1\n# grid: isotropic=false phi_i={} theta_i={} phi_o={} theta_o={}\n\
         theta_i,phi_i,theta_o,phi_o,value\n{}",
        axis("phi_i"),
        axis("theta_i"),
        axis("phi_o"),
        axis("theta_o"),
        new.split_once('\n').expect("header").1
    );
    let old_path = d.join("old.csv");
    std::fs::write(&old_path, old).expect("old");
    let m_new: Value =
        serde_json::from_slice(&ok(&["check", &s(&table), "--json"]).stdout).expect("json");
    let m_old: Value =
        serde_json::from_slice(&ok(&["check", &s(&old_path), "--json"]).stdout).expect("json");
    assert_eq!(m_new, m_old);
    let again = d.join("again.csv");
    ok(&[
        "export",
        &s(&old_path),
        "--format",
        "csv",
        "--out",
        &s(&again),
    ]);
    assert_eq!(std::fs::read_to_string(&again).expect("again"), new);

    let python = std::env::var("PYTHON").unwrap_or_else(|_| "/tmp/scipyenv/bin/python".into());
    let script = "import sys, pandas as pd\n\
        t = pd.read_csv(sys.argv[1]); s = pd.read_csv(sys.argv[2])\n\
        print(len(t), list(t.columns), repr(float(t['f_r_per_sr'].sum())))\n\
        print(len(s), list(s.columns), repr(float(s['f_r_G_per_sr'].iloc[2])))\n";
    let out = std::process::Command::new(&python)
        .args(["-c", script, &s(&table), &s(&samples)])
        .output();
    let out = match out {
        Ok(o) if o.status.success() => o,
        _ => {
            eprintln!("skipped the pandas check: no {python} with pandas");
            return;
        }
    };
    let text = String::from_utf8_lossy(&out.stdout);
    let mut lines = text.lines();
    let rows: Vec<&str> = new.lines().skip(1).collect();
    let sum: f64 = rows
        .iter()
        .map(|l| {
            l.rsplit(',')
                .next()
                .expect("value")
                .parse::<f64>()
                .expect("f64")
        })
        .sum();
    let t_line = lines.next().expect("table line");
    assert!(
        t_line.starts_with(&format!(
            "{} ['theta_i_deg', 'phi_i_deg', 'theta_o_deg', 'phi_o_deg', 'f_r_per_sr']",
            rows.len()
        )),
        "{t_line}"
    );
    let py_sum: f64 = t_line
        .rsplit(' ')
        .next()
        .expect("sum")
        .parse()
        .expect("f64");
    assert!((py_sum - sum).abs() <= 1e-12 * sum, "{py_sum} vs {sum}");
    assert_eq!(
        lines.next(),
        Some(
            "3 ['theta_i_deg', 'phi_i_deg', 'theta_o_deg', 'phi_o_deg', 'f_r_R_per_sr', \
             'f_r_G_per_sr', 'f_r_B_per_sr'] 0.6"
        )
    );
}

#[test]
fn a_run_exports_to_rgl_and_the_material_is_an_input_like_any_other() {
    let d = scratch("rgl");
    let run = acquire(&d, ISO_PLAN);
    let bsdf = d.join("run.bsdf");
    let v: Value = serde_json::from_slice(
        &ok(&[
            "export",
            &s(&run),
            "--format",
            "rgl",
            "--out",
            &s(&bsdf),
            "--json",
        ])
        .stdout,
    )
    .expect("json");
    assert_eq!(
        (v["format"].as_str(), v["from"].as_str()),
        (Some("rgl"), Some("table"))
    );
    // At the nodes the file holds the reduced table as interpolated; between them the
    // format's resolution.
    assert!(
        v["interpolation"]["at_nodes"].as_f64().expect("number") < 1e-4,
        "{v}"
    );
    assert!(
        v["interpolation"]["between"].as_f64().expect("number") < 0.15,
        "{v}"
    );
    let bytes = std::fs::read(&bsdf).expect("written");
    assert_eq!(&bytes[..12], b"tensor_file\0");
    // Written again: refused without --force (exit 2), the file untouched.
    let again = gonio(&["export", &s(&run), "--format", "rgl", "--out", &s(&bsdf)]);
    assert_eq!(again.status.code(), Some(2));
    assert_eq!(std::fs::read(&bsdf).expect("still there"), bytes);
    // Bad resolutions are refused before anything is written.
    let bad = gonio(&[
        "export",
        &s(&run),
        "--format",
        "rgl",
        "--rgl-slice",
        "1",
        "--out",
        &s(&d.join("bad.bsdf")),
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("slice: 1 nodes"));
    assert!(!d.join("bad.bsdf").exists());
    // The material is an input: checked, plotted, exported to CSV and back to itself
    // (fitted in crates/gonio-py/tests/test_rgl.py).
    let check: Value =
        serde_json::from_slice(&ok(&["check", &s(&bsdf), "--json"]).stdout).expect("json");
    let pr = check["reciprocity"]
        .as_array()
        .expect("reciprocity per channel");
    assert_eq!(pr.len(), 3);
    assert!(pr.iter().all(|p| p.as_f64().is_some_and(f64::is_finite)));
    ok(&[
        "plot",
        &s(&bsdf),
        "--kind",
        "albedo",
        "--out",
        &s(&d.join("albedo.svg")),
    ]);
    ok(&[
        "export",
        &s(&bsdf),
        "--format",
        "csv",
        "--out",
        &s(&d.join("t.csv")),
    ]);
    ok(&[
        "export",
        &s(&bsdf),
        "--format",
        "rgl",
        "--out",
        &s(&d.join("same.bsdf")),
    ]);
    assert_eq!(std::fs::read(d.join("same.bsdf")).expect("written"), bytes);
}
