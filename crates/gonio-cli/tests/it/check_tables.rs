//! `gonio check` of a table another tool wrote (columns shuffled, units in the
//! header, no sidecar): the same measures as Gonio's own table, the same bytes on 1
//! and 2 rayon threads, and bad rows refused at their line (issue 40).

use std::path::Path;
use std::process::{Command, Output};

use crate::common;

use common::{ok, root, s, scratch};
use serde_json::Value;

/// `gonio ARGS` on `threads` rayon threads, asserting success.
fn on_threads(threads: usize, args: &[&str]) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_gonio"))
        .env("RAYON_NUM_THREADS", threads.to_string())
        .args(args)
        .output()
        .expect("the gonio binary runs");
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Gonio's table rewritten with its columns in another order and other names.
fn as_another_tool(text: &str) -> String {
    let mut out = String::from("# written by another tool\n");
    for (k, line) in text.lines().enumerate() {
        if k == 0 {
            out.push_str("f_r [1/sr],phi_o (deg),theta_i [deg],theta_o,phi_i_deg\n");
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        out.push_str(&[f[4], f[3], f[0], f[2], f[1]].join(","));
        out.push('\n');
    }
    out
}

#[test]
fn another_tools_table_checks_as_gonios_own_on_any_number_of_threads() {
    let d = scratch("check-tables");
    let table = d.join("table.csv");
    let model = root().join("config/models/phong-shading.toml");
    ok(&[
        "correct",
        &s(&model),
        "--grid",
        "15,7.5",
        "--reciprocity",
        "0",
        "--out",
        &s(&table),
    ]);
    let other = d.join("other.csv");
    std::fs::write(
        &other,
        as_another_tool(&std::fs::read_to_string(&table).expect("table")),
    )
    .expect("other");
    assert!(!Path::new(&format!("{}.json", s(&other))).exists());
    let args = |p: &Path, json: bool| {
        let mut a = vec!["check".to_string(), s(p), "--k".into(), "1,5,10".into()];
        if json {
            a.push("--json".into());
        }
        a
    };
    for json in [false, true] {
        let a = args(&other, json);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let (one, two) = (on_threads(1, &a), on_threads(2, &a));
        assert_eq!(
            String::from_utf8_lossy(&one.stdout),
            String::from_utf8_lossy(&two.stdout),
            "json {json}"
        );
    }
    // A is 288 × 288 (48 φ × 6 θ): the truncated SVD's path.
    let a = args(&other, true);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let theirs: Value = serde_json::from_slice(&on_threads(2, &a).stdout).expect("json");
    let a = args(&table, true);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let ours: Value = serde_json::from_slice(&on_threads(1, &a).stdout).expect("json");
    assert_eq!(theirs, ours);
    assert_eq!(ours["grid"]["theta_i"]["n"], 6);
    assert_eq!(ours["grid"]["phi_i"]["n"], 48);
    assert_eq!(ours["separability"][0]["p_s"][2][0], 10);

    // A bad value in the shuffled file: exit 2, the file, the line and the column.
    let mut text = std::fs::read_to_string(&other).expect("other");
    let at = text.match_indices('\n').nth(99).expect("line 100").0 + 1;
    text.insert_str(at, "nan");
    let bad = d.join("bad.csv");
    std::fs::write(&bad, text).expect("bad");
    let o = common::gonio(&["check", &s(&bad)]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!(
            "{}:101: field `f_r [1/sr]`: not a finite number",
            s(&bad)
        )),
        "{err}"
    );
}

/// An RGB table with σ, as `gonio micro` writes it (with its sidecar): its floors
/// draw noise (each draw's from its place in one stream, channel by channel), and
/// `gonio check` prints the same bytes on 1 and 2 rayon threads.
#[test]
fn an_rgb_table_with_sigma_checks_the_same_on_any_number_of_threads() {
    let d = scratch("check-tables-rgb");
    let table = d.join("micro.csv");
    let config = root().join("config/micro-gaussian-gold.toml");
    ok(&[
        "micro",
        &s(&config),
        "--grid",
        "15,30",
        "--rays",
        "200",
        "--out",
        &s(&table),
    ]);
    for json in [false, true] {
        let mut a = vec!["check", table.to_str().expect("path"), "--k", "1,2"];
        if json {
            a.push("--json");
        }
        let (one, two) = (on_threads(1, &a), on_threads(2, &a));
        assert_eq!(
            String::from_utf8_lossy(&one.stdout),
            String::from_utf8_lossy(&two.stdout),
            "json {json}"
        );
        if json {
            let v: Value = serde_json::from_slice(&one.stdout).expect("json");
            assert_eq!(v["channels"], serde_json::json!(["R", "G", "B"]));
            assert!(v["floor"]["draws"].as_u64().is_some_and(|k| k > 0), "{v}");
            assert_eq!(v["floor"]["reciprocity"].as_array().map(Vec::len), Some(3));
        }
    }
}
