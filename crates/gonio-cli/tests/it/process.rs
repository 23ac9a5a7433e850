//! `gonio reduce`, `check`, `correct` and `harmonics` as processes: a simulated run
//! reduced to a table and measured; DeYoung's transforms applied in the order given;
//! bad input refused with exit status 2 and the file, line and field named.

use crate::common;

use common::{ISO_PLAN, acquire, gonio, ok_json, s, scratch};

const PHONG: &str = r#"
kind = "phong"
channels = ["value"]
rho_s = [0.6]
n = [20]
shading = true
[diffuse]
rho = [0.3]
"#;

/// An isotropic grid the simulated arms can reach everywhere (no retro pair).

#[test]
fn a_simulated_run_reduces_to_a_reciprocal_isotropic_table() {
    let d = scratch("iso");
    let run = acquire(&d, ISO_PLAN);
    let table = d.join("table.csv");
    let r = ok_json(&["reduce", &s(&run), "--out", &s(&table), "--json"]);
    assert_eq!(r["samples"], 36);
    assert_eq!(r["wrote"], "a table of 36 nodes");
    let text = std::fs::read_to_string(&table).expect("table");
    assert!(
        text.starts_with("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_per_sr,sigma_per_sr\n")
    );
    // The grid is in the sidecar.
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("table.csv.json")).expect("sidecar"))
            .expect("JSON");
    assert_eq!(side["format"], "gonio-table");
    assert_eq!(side["isotropic"], true);
    let axis = |name: &str| {
        let a = &side["grid"][name];
        (
            a["start_deg"].as_f64(),
            a["step_deg"].as_f64(),
            a["n"].as_u64(),
        )
    };
    assert_eq!(axis("phi_i"), (Some(0.0), Some(360.0), Some(1)));
    assert_eq!(axis("theta_i"), (Some(20.0), Some(25.0), Some(3)));
    assert_eq!(axis("phi_o"), (Some(45.0), Some(90.0), Some(4)));
    // The simulated paint is reciprocal and the table is isotropic by construction:
    // P_r is at the readings' noise (σ ≈ 1e-5 here), P_i exactly 0.
    let c = ok_json(&["check", &s(&run), "--k", "1,2", "--json"]);
    let pr = c["reciprocity"][0].as_f64().expect("P_r");
    assert!(pr < 5e-5, "P_r {pr}");
    assert_eq!(c["isotropy"][0], 0.0);
    assert_eq!(c["energy"]["p_ec"][0], 0.0);
    assert!(c["paired"].as_bool().expect("paired"));
    // The same measures from the written table as from the run.
    let c2 = ok_json(&["check", &s(&table), "--k", "1,2", "--json"]);
    assert_eq!(c["reciprocity"], c2["reciprocity"]);
    assert_eq!(c["separability"], c2["separability"]);
}

#[test]
fn check_measures_the_phong_shading_model_and_correct_fixes_it_in_order() {
    let d = scratch("phong");
    let model = d.join("phong.toml");
    std::fs::write(&model, PHONG).expect("model");
    let c = ok_json(&[
        "check",
        &s(&model),
        "--grid",
        "10,10",
        "--k",
        "1,5",
        "--json",
    ]);
    assert!(c["reciprocity"][0].as_f64().expect("P_r") > 0.1);
    assert!(c["energy"]["p_ec"][0].as_f64().expect("P_ec") > 0.01);
    // The worst incident direction for energy is the grazing one.
    assert_eq!(c["energy"]["worst"][0][0], 85.0);
    assert_eq!(c["nodes"], 9 * 36 * 9 * 36);

    // Energy then reciprocity: the reciprocity average can raise an albedo again, so
    // the last property asked for is the one that holds exactly.
    let out = d.join("fixed.csv");
    let r = ok_json(&[
        "correct",
        &s(&model),
        "--energy",
        "1",
        "--reciprocity",
        "1",
        "--out",
        &s(&out),
        "--json",
    ]);
    assert_eq!(r["steps"][0]["Energy"][0], 1.0);
    assert_eq!(r["steps"][1]["Reciprocity"], 1.0);
    assert!(r["after"]["reciprocity"][0].as_f64().expect("P_r") < 1e-15);
    let r2 = ok_json(&[
        "correct",
        &s(&model),
        "--reciprocity",
        "1",
        "--energy",
        "1:global",
        "--out",
        &s(&out),
        // The first correction's table is replaced on purpose.
        "--force",
        "--json",
    ]);
    assert_eq!(r2["steps"][0]["Reciprocity"], 1.0);
    assert!(r2["after"]["energy"]["p_ec"][0].as_f64().expect("P_ec") < 1e-15);
    // A global scale keeps reciprocity.
    assert!(r2["after"]["reciprocity"][0].as_f64().expect("P_r") < 1e-15);
    let again = ok_json(&["check", &s(&out), "--json"]);
    assert_eq!(again["energy"]["p_ec"], r2["after"]["energy"]["p_ec"]);

    // Five separable components stored as factors: 5 (P + Q) / PQ of the table.
    let sep = d.join("sep5.toml");
    let sv = ok_json(&[
        "correct",
        &s(&out),
        "--separable",
        "5",
        "--out",
        &s(&sep),
        "--json",
    ]);
    let ratio = sv["storage_ratio"].as_f64().expect("ratio");
    assert!((ratio - 10.0 / 324.0).abs() < 1e-12, "{ratio}");
    let c5 = ok_json(&["check", &s(&sep), "--k", "5", "--json"]);
    assert!(
        c5["separability"][0]["p_s"][0][1]
            .as_f64()
            .expect("P_s^(5)")
            < 1e-12
    );

    // Spherical harmonics of the corrected table: reciprocal by construction.
    let sh = d.join("sh.toml");
    let h = ok_json(&[
        "harmonics",
        &s(&out),
        "--order",
        "6",
        "--out",
        &s(&sh),
        "--json",
    ]);
    assert_eq!(h["coefficients"], 28 * 29 / 2);
    let hc = ok_json(&["check", &s(&sh), "--json"]);
    assert!(hc["reciprocity"][0].as_f64().expect("P_r") < 1e-15);
}

#[test]
fn bad_input_exits_2_naming_the_file_line_and_field() {
    let d = scratch("bad");
    let cases: [(&str, &str, &str); 4] = [
        (
            "nan.csv",
            "theta_i,phi_i,theta_o,phi_o,value\n10,0,20,0,nan\n",
            "nan.csv:2: field `value`",
        ),
        (
            "grid.csv",
            "# grid: isotropic=false phi_i=0:90:4 theta_i=0:45:3\ntheta_i,phi_i,theta_o,phi_o,value\n0,0,0,0,1\n",
            "grid.csv:1: field `grid`",
        ),
        (
            "sep.toml",
            "kind = \"separable\"\nchannels = [\"value\"]\nk = 1\n",
            "sep.toml",
        ),
        ("empty.csv", "", "empty.csv"),
    ];
    for (name, text, want) in cases {
        let f = d.join(name);
        std::fs::write(&f, text).expect("write");
        let o = gonio(&["check", &s(&f)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(want), "{name}: {err}");
        assert_eq!(err.lines().count(), 1, "{name}: one line: {err}");
    }
    // Scattered samples over the hemisphere, on no grid of their own: resample them.
    let f = d.join("scattered.csv");
    std::fs::write(
        &f,
        "theta_i,phi_i,theta_o,phi_o,value\n10,0,20,0,0.1\n10,0,25,90,0.2\n\
         10,0,33,180,0.2\n10,0,41,270,0.2\n",
    )
    .expect("write");
    let o = gonio(&["check", &s(&f)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--grid"));
    // Two samples at two incidences cover no area: no grid can fix that, and it says so.
    std::fs::write(
        &f,
        "theta_i,phi_i,theta_o,phi_o,value\n10,0,20,0,0.1\n30,0,20,90,0.2\n",
    )
    .expect("write");
    let o = gonio(&["check", &s(&f)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cover no area"));
    // Bad δ and a bad grid.
    for args in [
        vec!["correct", "x.csv", "--isotropy", "1.5", "--out", "y.csv"],
        vec!["check", "x.csv", "--grid", "7,10"],
        vec!["correct", "x.csv", "--separable", "0", "--out", "y.csv"],
    ] {
        let o = gonio(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
    }
    // reduce wants a run file.
    let o = gonio(&["reduce", &s(&f), "--out", &s(&d.join("o.csv"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a run file"));
}
