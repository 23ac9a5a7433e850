//! What a user types into a config, plan, surface, model, directions or table file
//! reaches them as one line naming the file, the line, the field and what is
//! accepted, with exit status 2; and a byte order mark (Windows editors, spreadsheets'
//! "CSV UTF-8") in front of any of them changes nothing.

use crate::common;

use std::path::{Path, PathBuf};

use common::{config, gonio, ok, s, scratch, stderr};

/// Runs `gonio` and returns its one-line reason, asserting exit status 2.
fn refused(args: &[&str]) -> String {
    let o = gonio(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    err.trim_end().to_string()
}

/// `text` written to `dir/name`.
fn put(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

/// The shipped file `rel` with a byte order mark in front, written to `dir`.
fn with_bom(dir: &Path, rel: &str) -> PathBuf {
    let text = std::fs::read_to_string(config(rel)).expect("shipped file");
    let name = Path::new(rel).file_name().expect("a file name");
    put(dir, &name.to_string_lossy(), &format!("\u{feff}{text}"))
}

const PLAN: &str = "name = \"scan\"\n[points]\nkind = \"in-plane\"\ntheta_i = [0, 30]\n";

#[test]
fn a_plan_angle_of_no_accepted_form_names_the_field_and_the_forms() {
    let d = scratch("untagged");
    let inst = config("instrument-sim.toml");
    let p = put(&d, "p.toml", &format!("{PLAN}theta_o = \"all\"\n"));
    assert_eq!(
        refused(&["plan", "check", &s(&p), "--instrument", &inst]),
        format!(
            "gonio: {}:5:11: field `points.theta_o`: invalid type: string \"all\", expected a \
             list of angles like [0, 30, 60], one angle like 45, or a range like \
             {{ from = 0, to = 60, step = 30 }}",
            s(&p)
        )
    );
    let p = put(
        &d,
        "r.toml",
        &format!("{PLAN}theta_o = {{ from = -80, to = 80 }}\n"),
    );
    assert_eq!(
        refused(&["plan", "check", &s(&p), "--instrument", &inst]),
        format!(
            "gonio: {}:5:11: field `points.theta_o`: a range needs from, to and step (missing \
             step): {{ from = 0, to = 60, step = 30 }}",
            s(&p)
        )
    );
}

#[test]
fn a_kind_tagged_table_names_the_field_and_the_kinds() {
    let d = scratch("tagged");
    let inst = config("instrument-sim.toml");
    let p = put(
        &d,
        "k.toml",
        &format!("{}theta_o = [30]\n", PLAN.replace("in-plane", "spiral")),
    );
    assert_eq!(
        refused(&["plan", "check", &s(&p), "--instrument", &inst]),
        format!(
            "gonio: {}:3:8: field `points.kind`: unknown kind \"spiral\", expected one of \
             \"grid\", \"isotropic\", \"in-plane\", \"list\" or \"adaptive\"",
            s(&p)
        )
    );
    let p = put(
        &d,
        "t.toml",
        &format!("{PLAN}theta_o = [30]\nphi_i = \"north\"\n"),
    );
    assert_eq!(
        refused(&["plan", "check", &s(&p), "--instrument", &inst]),
        format!(
            "gonio: {}:6:9: field `points.phi_i`: invalid type: string \"north\", expected f64",
            s(&p)
        )
    );
    // A surface file: the same for [surface] and [materials.NAME].
    let surface =
        std::fs::read_to_string(config("micro-brushed-aluminium.toml")).expect("shipped surface");
    let bad = surface.replacen("radius = ", "radius = \"wide\" # ", 1);
    assert_ne!(bad, surface);
    let p = put(&d, "s.toml", &bad);
    let line = bad
        .lines()
        .position(|l| l.starts_with("radius"))
        .expect("a radius line")
        + 1;
    assert_eq!(
        refused(&["micro", &s(&p), "--out", &s(&d.join("t.csv"))]),
        format!(
            "gonio: {}:{line}:10: field `surface.radius`: invalid type: string \"wide\", \
             expected f64",
            s(&p)
        )
    );
    assert!(!d.join("t.csv").exists());
}

#[test]
fn a_csv_with_a_wrong_header_names_the_columns_expected() {
    let d = scratch("header");
    let columns = "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg, then one column a channel \
                   (f_r_per_sr; f_r_R_per_sr,f_r_G_per_sr,f_r_B_per_sr; or wavelengths like \
                   f_r_550nm_per_sr), then optionally sigma_<channel>_per_sr for each channel \
                   and flags (or the older theta_i,phi_i,theta_o,phi_o, channel names and \
                   sigma_<channel>)";
    let p = put(
        &d,
        "t.csv",
        "# measured\ntheta,phi,theta_o,phi_o,value\n0,0,0,0,1\n",
    );
    assert_eq!(
        refused(&["check", &s(&p)]),
        format!(
            "gonio: {}:2: not a CSV header Gonio reads: expected the columns {columns}; found \
             \"theta,phi,theta_o,phi_o,value\"",
            s(&p)
        )
    );
    let p = put(&d, "c.csv", "theta_i,phi_i,theta_o,phi_o,red\n0,0,0,0,1\n");
    let err = refused(&["check", &s(&p)]);
    assert!(
        err.starts_with(&format!("gonio: {}:1: channels: ", s(&p)))
            && err.ends_with(&format!("(expected the columns {columns})")),
        "{err}"
    );
    // The directions file of `gonio model eval`.
    let p = put(&d, "d.csv", "ti,pi,to,po\n0,0,30,180\n");
    assert_eq!(
        refused(&[
            "model",
            "eval",
            &config("models/blue-paint-550nm.toml"),
            &s(&p)
        ]),
        format!(
            "gonio: {}:1: header must start with theta_i,phi_i,theta_o,phi_o (or \
             theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg); got \"ti,pi,to,po\"",
            s(&p)
        )
    );
}

#[test]
fn a_byte_order_mark_changes_nothing() {
    let d = scratch("bom");
    let model = config("models/blue-paint-550nm.toml");
    let dirs = config("dirs-example.csv");
    let plain = ok(&["model", "eval", &model, &dirs]).stdout;
    let bom_model = with_bom(&d, "models/blue-paint-550nm.toml");
    let bom_dirs = with_bom(&d, "dirs-example.csv");
    assert_eq!(ok(&["model", "eval", &s(&bom_model), &dirs]).stdout, plain);
    assert_eq!(ok(&["model", "eval", &model, &s(&bom_dirs)]).stdout, plain);
    // A model and a table as the INPUT of `check`, recognised from content.
    let check = |p: &str| ok(&["check", p, "--grid", "30,90", "--json"]).stdout;
    assert_eq!(check(&s(&bom_model)), check(&model));
    let table = d.join("paint.csv");
    std::fs::write(
        &table,
        ok(&["model", "eval", &model, &dirs]).stdout, // any CSV with the header
    )
    .expect("write");
    let text = std::fs::read_to_string(&table).expect("read");
    let bom_table = put(&d, "bom.csv", &format!("\u{feff}{text}"));
    let out = |p: &Path| {
        let o = gonio(&["check", &s(p), "--grid", "30,90", "--json"]);
        (
            o.status.code(),
            stderr(&o).replace(&s(p), "INPUT"),
            o.stdout,
        )
    };
    assert_eq!(out(&bom_table), out(&table));
    // Configs and plans.
    let inst = with_bom(&d, "instrument-sim.toml");
    ok(&["instrument", "check", &s(&inst)]);
    let plan = with_bom(&d, "plan-in-plane.toml");
    // Everything but the files' names, which differ.
    let json = |i: &str, p: &str| {
        let mut v = common::ok_json(&["plan", "check", p, "--instrument", i, "--json"]);
        let o = v.as_object_mut().expect("an object");
        assert_eq!(
            o.remove("plan").and_then(|x| x.as_str().map(str::to_owned)),
            Some(p.to_owned())
        );
        assert_eq!(
            o.remove("instrument")
                .and_then(|x| x.as_str().map(str::to_owned)),
            Some(i.to_owned())
        );
        v
    };
    assert_eq!(
        json(&s(&inst), &s(&plan)),
        json(
            &config("instrument-sim.toml"),
            &config("plan-in-plane.toml")
        )
    );
}
