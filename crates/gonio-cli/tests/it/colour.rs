//! `gonio colour` through the binary: the ColorChecker spectra against reference
//! values, white points against the CIE's, and bad files refused with file and line.

use crate::common;

use std::path::PathBuf;

use common::{gonio, ok_json, scratch, stderr};

fn testdata(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../gonio-core/src/colour/testdata")
        .join(name)
}

/// Data lines of a test file (comments and header left out), split at commas.
fn rows(name: &str) -> Vec<Vec<String>> {
    std::fs::read_to_string(testdata(name))
        .expect("the test data file reads")
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().expect("a number")
}

/// The 24 BabelColor spectra (10 nm, 380–730 nm) give, under every illuminant and
/// observer, the XYZ colour-science 0.4.7 computes the same way (Sprague to 1 nm,
/// end values beyond the ends), and so the same xy to far better than 1e-4.
#[test]
fn colorchecker_spectra_match_reference_values_for_every_illuminant_and_observer() {
    let file = testdata("colorchecker_babelcolor_avg.csv");
    let reference = rows("colorchecker_colour_science_xyz.csv");
    for obs in ["1931", "1964"] {
        for ill in ["D65", "D50", "A", "E"] {
            let v = ok_json(&[
                "colour",
                file.to_str().unwrap(),
                "--illuminant",
                ill,
                "--observer",
                obs,
                "--json",
            ]);
            assert_eq!(v["illuminant"], ill);
            assert_eq!(v["observer"], obs);
            let spectra = v["spectra"].as_array().unwrap();
            assert_eq!(spectra.len(), 24);
            for s in spectra {
                let name = s["name"].as_str().unwrap();
                let r = reference
                    .iter()
                    .find(|r| r[0] == obs && r[1] == ill && r[2] == name)
                    .unwrap();
                let e: Vec<f64> = r[3..].iter().map(|x| x.parse().unwrap()).collect();
                let got = [num(&s["X"]), num(&s["Y"]), num(&s["Z"])];
                for k in 0..3 {
                    assert!(
                        (got[k] - e[k]).abs() < 1e-9,
                        "{obs} {ill} {name}: {got:?} vs {e:?}"
                    );
                }
                let sum: f64 = e.iter().sum();
                assert!((num(&s["x"]) - e[0] / sum).abs() < 1e-9);
                assert!((num(&s["y"]) - e[1] / sum).abs() < 1e-9);
                let enc = s["srgb"].as_array().unwrap();
                let b8 = s["srgb8"].as_array().unwrap();
                for ch in 0..3 {
                    let e = num(&enc[ch]);
                    assert!((0.0..=1.0).contains(&e));
                    assert_eq!(b8[ch].as_u64().unwrap(), (255.0 * e).round() as u64);
                }
            }
        }
    }
}

/// BabelColor's own xyY (D50, 2°) are averages over 30 charts, so they agree with the
/// average spectra's colours to 8.1e-4 at worst (see the unit test in gonio-core).
#[test]
fn colorchecker_spectra_are_near_babelcolor_published_chromaticities() {
    let file = testdata("colorchecker_babelcolor_avg.csv");
    let published = rows("colorchecker_babelcolor_xyY_d50.csv");
    let v = ok_json(&[
        "colour",
        file.to_str().unwrap(),
        "--illuminant",
        "D50",
        "--json",
    ]);
    for s in v["spectra"].as_array().unwrap() {
        let p = published.iter().find(|p| p[0] == s["name"]).unwrap();
        let (x, y): (f64, f64) = (p[1].parse().unwrap(), p[2].parse().unwrap());
        assert!((num(&s["x"]) - x).abs() < 9e-4 && (num(&s["y"]) - y).abs() < 9e-4);
    }
}

/// A perfect white (and a 5 nm file) gives the CIE's published white points, and
/// sRGB white once adapted.
#[test]
fn a_perfect_white_gives_the_published_white_points() {
    let dir = scratch("colour-white");
    let path = dir.join("white.csv");
    let mut text = String::from("# a perfect reflecting diffuser\nwavelength_nm,white,grey\n");
    for i in 0..=94 {
        text += &format!("{},1,0.18\n", 360 + 5 * i);
    }
    std::fs::write(&path, text).unwrap();
    let published = [
        ("D65", "1931", 0.31272, 0.32903),
        ("D65", "1964", 0.31382, 0.33100),
        ("A", "1931", 0.44757, 0.40745),
        ("D50", "1964", 0.34773, 0.35952),
    ];
    for (ill, obs, x, y) in published {
        let v = ok_json(&[
            "colour",
            path.to_str().unwrap(),
            "--illuminant",
            ill,
            "--observer",
            obs,
            "--json",
        ]);
        let s = &v["spectra"][0];
        assert!((num(&s["x"]) - x).abs() < 1e-4 && (num(&s["y"]) - y).abs() < 1e-4);
        assert!((num(&s["Y"]) - 1.0).abs() < 1e-12);
        assert_eq!(s["srgb8"], serde_json::json!([255, 255, 255]));
        // 18 % grey: sRGB code value 118 in every channel.
        assert_eq!(v["spectra"][1]["srgb8"], serde_json::json!([118, 118, 118]));
    }
    // Unadapted, a white under A is orange.
    let v = ok_json(&[
        "colour",
        path.to_str().unwrap(),
        "--illuminant",
        "A",
        "--adaptation",
        "none",
        "--json",
    ]);
    let l = v["spectra"][0]["srgb_linear"].as_array().unwrap();
    assert!(num(&l[0]) > num(&l[1]) && num(&l[1]) > num(&l[2]));
    // The text form names the conditions and each spectrum.
    let o = common::ok(&["colour", path.to_str().unwrap()]);
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(
        out.contains("illuminant D65, CIE 1931 2° observer"),
        "{out}"
    );
    assert!(
        out.lines()
            .any(|l| l.starts_with("white") && l.ends_with("#ffffff")),
        "{out}"
    );
}

/// Each bad file or flag exits 2 with the file, the line and the field.
#[test]
fn bad_inputs_exit_2_naming_file_and_line() {
    let dir = scratch("colour-bad");
    let cases: [(&str, String, &str); 6] = [
        (
            "spacing.csv",
            "wavelength_nm,a\n".to_string()
                + &(0..200)
                    .map(|i| format!("{},0.5\n", 380 + 2 * i))
                    .collect::<String>(),
            ":3: field `wavelength_nm`: the spacing must be uniform 1, 5 or 10 nm; found 2 nm between 380 and 382 nm",
        ),
        (
            "text.csv",
            "# comment\nwavelength_nm,a,b\n400,0.5,0.5\n410,0.5,zero\n".to_string(),
            ":4: field `b`: \"zero\" is not a finite number",
        ),
        (
            "nowl.csv",
            "lambda,a\n400,0.5\n".to_string(),
            ":1: no `wavelength_nm` column",
        ),
        (
            "short.csv",
            "wavelength_nm,a\n".to_string()
                + &(0..20)
                    .map(|i| format!("{},0.5\n", 450 + 10 * i))
                    .collect::<String>(),
            ": field `wavelength_nm`: the spectrum covers 450–640 nm; at least 400–700 nm is needed",
        ),
        (
            "fields.csv",
            "wavelength_nm,a\n400,0.5\n410\n".to_string(),
            ":3: 1 fields, the header has 2",
        ),
        (
            "uneven.csv",
            "wavelength_nm,a\n".to_string()
                + &(0..31)
                    .map(|i| format!("{},0.5\n", if i < 20 { 400 + 10 * i } else { 401 + 10 * i }))
                    .collect::<String>(),
            ":22: field `wavelength_nm`: the spacing must be uniform 1, 5 or 10 nm; found 11 nm between 590 and 601 nm",
        ),
    ];
    for (name, text, expect) in cases {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        let o = gonio(&["colour", p.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        let want = format!("gonio: {}{expect}", p.display());
        assert!(
            stderr(&o).starts_with(&want),
            "{name}: {} vs {want}",
            stderr(&o)
        );
        assert!(o.stdout.is_empty());
    }
    let good = testdata("colorchecker_babelcolor_avg.csv");
    let o = gonio(&["colour", good.to_str().unwrap(), "--illuminant", "F11"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--illuminant: unknown illuminant \"F11\""),
        "{}",
        stderr(&o)
    );
    let o = gonio(&["colour", good.to_str().unwrap(), "--observer", "2006"]);
    assert_eq!(o.status.code(), Some(2));
    let o = gonio(&["colour", dir.join("missing.csv").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
}

/// A spectral Lambertian model whose reflectance is a ColorChecker patch exports to a
/// MERL table whose every valid bin holds the patch's linear sRGB / π (the reference
/// XYZ through the IEC 61966-2-1 matrix: no adaptation under D65 with the 1931
/// observer).
#[test]
fn a_spectral_lambertian_exports_to_merl_as_its_srgb_over_pi() {
    let dir = scratch("colour-merl");
    let spectra = rows("colorchecker_babelcolor_avg.csv");
    let col = 7; // the header's 7th spectrum: "orange"
    let header = std::fs::read_to_string(testdata("colorchecker_babelcolor_avg.csv")).unwrap();
    let names: Vec<&str> = header
        .lines()
        .find(|l| !l.starts_with('#'))
        .unwrap()
        .split(',')
        .collect();
    assert_eq!(names[col], "orange");
    let channels: Vec<String> = spectra.iter().map(|r| format!("\"{}nm\"", r[0])).collect();
    let rho: Vec<&str> = spectra.iter().map(|r| r[col].as_str()).collect();
    let model = dir.join("orange.toml");
    std::fs::write(
        &model,
        format!(
            "kind = \"lambert\"\nchannels = [{}]\nrho = [{}]\n",
            channels.join(", "),
            rho.join(", ")
        ),
    )
    .unwrap();
    let out = dir.join("orange.binary");
    let v = ok_json(&[
        "export",
        model.to_str().unwrap(),
        "--format",
        "merl",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(v["colour"], "illuminant D65, CIE 1931 2° observer");
    let r = rows("colorchecker_colour_science_xyz.csv");
    let xyz: Vec<f64> = r
        .iter()
        .find(|r| r[0] == "1931" && r[1] == "D65" && r[2] == "orange")
        .unwrap()[3..]
        .iter()
        .map(|x| x.parse().unwrap())
        .collect();
    let iec = [
        [3.2406, -1.5372, -0.4986],
        [-0.9689, 1.8758, 0.0415],
        [0.0557, -0.2040, 1.0570],
    ];
    let expect: Vec<f64> = iec
        .iter()
        .map(|row| (row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2]) / std::f64::consts::PI)
        .collect();
    // An orange: R well above G above B.
    assert!(expect[0] > expect[1] && expect[1] > expect[2] && expect[2] > 0.0);
    let bytes = std::fs::read(&out).unwrap();
    let merl = gonio_io::formats::read_merl(&bytes, Some(&out)).unwrap();
    let mut valid = 0;
    for bin in gonio_io::formats::Bin::all() {
        if let Some(v) = merl.bin_values(bin) {
            for k in 0..3 {
                assert!(
                    (v[k] - expect[k]).abs() < 1e-9,
                    "{bin}: {v:?} vs {expect:?}"
                );
            }
            valid += 1;
        }
    }
    // The bins whose centre pair lies within the tabulated model (965 020 of 1 458 000).
    assert!(valid > 900_000, "{valid} valid bins");
    // A bad illuminant is bad input, and nothing is written.
    let o = gonio(&[
        "export",
        model.to_str().unwrap(),
        "--format",
        "merl",
        "--out",
        dir.join("x.binary").to_str().unwrap(),
        "--illuminant",
        "F2",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!dir.join("x.binary").exists());
}

/// `gonio plot --colour srgb` draws a spectral model's hemisphere; the flag is refused
/// where it has no meaning.
#[test]
fn plot_draws_a_spectral_hemisphere_in_true_colour() {
    let dir = scratch("colour-plot");
    let model = dir.join("grey.toml");
    let channels: Vec<String> = (0..31).map(|i| format!("\"{}nm\"", 400 + 10 * i)).collect();
    std::fs::write(
        &model,
        format!(
            "kind = \"lambert\"\nchannels = [{}]\nrho = [{}]\n",
            channels.join(", "),
            vec!["0.18"; 31].join(", ")
        ),
    )
    .unwrap();
    let png = dir.join("h.png");
    let m = model.to_str().unwrap();
    common::ok(&[
        "plot",
        m,
        "--kind",
        "hemisphere",
        "--colour",
        "srgb",
        "--illuminant",
        "A",
        "--out",
        png.to_str().unwrap(),
    ]);
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    for (args, msg) in [
        (
            vec!["--kind", "polar", "--colour", "srgb"],
            "--colour srgb: only for --kind hemisphere",
        ),
        (
            vec!["--kind", "hemisphere", "--colour", "hsv"],
            "--colour: srgb, got \"hsv\"",
        ),
        (
            vec![
                "--kind",
                "hemisphere",
                "--colour",
                "srgb",
                "--observer",
                "1900",
            ],
            "--observer: unknown observer \"1900\"",
        ),
    ] {
        let out = dir.join("bad.png");
        let mut a = vec!["plot", m, "--out", out.to_str().unwrap()];
        a.extend(args);
        let o = gonio(&a);
        assert_eq!(o.status.code(), Some(2), "{a:?}");
        assert!(stderr(&o).contains(msg), "{a:?}: {}", stderr(&o));
        assert!(!out.exists());
    }
}
