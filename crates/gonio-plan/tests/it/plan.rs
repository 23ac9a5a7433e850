//! Plans: parsing with located errors, expansion of each kind, and the check of
//! every pair against the instrument (each rejection reason), and schedules.

use crate::common;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_plan::plan::{self, Mechanics, Plan, Rejection};
use gonio_plan::schedule::StepKind;

fn pair(ti: f64, pi: f64, to: f64, po: f64) -> PairDeg {
    PairDeg {
        incident: SphericalDeg::new(ti, pi),
        outgoing: SphericalDeg::new(to, po),
    }
}

fn mech() -> Mechanics {
    common::mechanics()
}

fn reason(m: &Mechanics, p: PairDeg) -> Result<[f64; 4], Rejection> {
    m.accept(p.to_dirs())
}

#[test]
fn a_measurable_pair_maps_to_stages_that_reproduce_it() {
    let m = mech();
    let p = pair(35.0, 0.0, 50.0, 180.0);
    let s = reason(&m, p).expect("measurable");
    // In-plane: the sample turned so the arms sweep its x–z plane, untilted.
    let back = m.layout.forward(s);
    let want = p.to_dirs();
    assert!(back.wi.angle_to(want.wi) < 1e-12 && back.wo.angle_to(want.wo) < 1e-12);
    assert!(s[3].abs() < 1e-9, "tilt {}", s[3]);
}

#[test]
fn each_rejection_reason() {
    let m = mech();
    // At the horizon: cos 90° is exactly 0 in the sample frame.
    assert!(matches!(
        reason(&m, pair(90.0, 0.0, 30.0, 180.0)),
        Err(Rejection::BelowHorizon { which }) if which == "wi"
    ));
    // The detector 5° from the source: inside the 8° the arm blocks.
    match reason(&m, pair(30.0, 0.0, 25.0, 0.0)) {
        Err(Rejection::Shadowed {
            separation_deg,
            min_deg,
        }) => {
            assert!((separation_deg - 5.0).abs() < 1e-9);
            assert_eq!(min_deg, 8.0);
        }
        other => panic!("{other:?}"),
    }
    // At 85°, a 5 mm beam draws a 57.4 mm footprint on the 50 mm sample.
    match reason(&m, pair(85.0, 0.0, 30.0, 180.0)) {
        Err(Rejection::Overfilled {
            footprint_m,
            sample_m,
        }) => {
            assert!((footprint_m - 0.005 / 85f64.to_radians().cos()).abs() < 1e-12);
            assert_eq!(sample_m, 0.05);
        }
        other => panic!("{other:?}"),
    }
    // Out of the plane of incidence the sample must tilt: wi = (45°, 0), wo = (45°, 90°)
    // span a plane whose normal k = wi × wo makes atan(1/√2) = 35.26° with the
    // horizontal, within [−5°, 85°]; with the tilt stage limited to 30° the pair is out
    // of reach.
    let ok = reason(&m, pair(45.0, 0.0, 45.0, 90.0)).expect("reachable");
    assert!(
        (ok[3].abs() - (0.5f64.sqrt()).atan().to_degrees()).abs() < 1e-9,
        "{ok:?}"
    );
    let mut narrow = m.clone();
    narrow.limits[3] = (-5.0, 30.0);
    match reason(&narrow, pair(45.0, 0.0, 45.0, 90.0)) {
        Err(Rejection::OutOfLimits {
            axis,
            position,
            min,
            max,
        }) => {
            assert_eq!(axis, "sample_tilt");
            assert!(position.abs() > 30.0);
            assert_eq!((min, max), (-5.0, 30.0));
        }
        other => panic!("{other:?}"),
    }
    // Duplicates: at normal incidence φi means nothing.
    let checked = plan::check(&m, &[pair(0.0, 0.0, 30.0, 0.0), pair(0.0, 90.0, 30.0, 0.0)]);
    assert_eq!(checked.accepted.len(), 1);
    assert_eq!(checked.rejected[0].reason, Rejection::Duplicate { of: 0 });
}

/// The mirror-image set-up is used when the canonical one is out of limits.
#[test]
fn the_mirror_solution_rescues_a_pair() {
    let m = mech();
    let p = pair(30.0, 0.0, 60.0, 180.0);
    let s = reason(&m, p).expect("measurable");
    let mut lopsided = m.clone();
    // Forbid the canonical source angle's sign.
    let (lo, hi) = if s[0] > 0.0 {
        (-170.0, -1.0)
    } else {
        (1.0, 170.0)
    };
    lopsided.limits[0] = (lo, hi);
    lopsided.limits[1] = (-170.0, 170.0);
    let t = reason(&lopsided, p).expect("mirror set-up");
    assert!((t[0] + s[0]).abs() < 1e-9 && (t[1] + s[1]).abs() < 1e-9);
    let back = lopsided.layout.forward(t);
    assert!(back.wi.angle_to(p.to_dirs().wi) < 1e-12);
    assert!(back.wo.angle_to(p.to_dirs().wo) < 1e-12);
}

#[test]
fn plan_kinds_expand() {
    let grid = common::plan(
        "[points]\nkind = \"grid\"\ntheta_i = [0, 30]\nphi_i = 0\n\
         theta_o = { from = 10, to = 30, step = 10 }\nphi_o = [0, 180]\n",
    );
    assert_eq!(grid.pairs().expect("pairs").len(), 2 * 3 * 2);
    let iso = common::plan(
        "[points]\nkind = \"isotropic\"\nphi_i = 10\ntheta_i = [45]\ntheta_o = [30]\n\
         delta_phi = { from = 0, to = 180, step = 45 }\n",
    );
    let p = iso.pairs().expect("pairs");
    assert_eq!(p.len(), 5);
    assert_eq!(p[4].outgoing.phi_deg, 190.0);
    let inplane =
        common::plan("[points]\nkind = \"in-plane\"\ntheta_i = [30]\ntheta_o = [-40, 40]\n");
    let p = inplane.pairs().expect("pairs");
    assert_eq!(
        (p[0].outgoing.theta_deg, p[0].outgoing.phi_deg),
        (40.0, 0.0)
    );
    assert_eq!(
        (p[1].outgoing.theta_deg, p[1].outgoing.phi_deg),
        (40.0, 180.0)
    );
    // A range whose end is off the grid stops short of it.
    let r = common::plan(
        "[points]\nkind = \"in-plane\"\ntheta_i = { from = 0, to = 50, step = 20 }\ntheta_o = [30]\n",
    );
    let t: Vec<f64> = r
        .pairs()
        .expect("pairs")
        .iter()
        .map(|p| p.incident.theta_deg)
        .collect();
    assert_eq!(t, vec![0.0, 20.0, 40.0]);
    // The list kind reads the CSV relative to the plan.
    let list = Plan::load(&common::root().join("config/plan-list.toml"))
        .expect("example")
        .0;
    assert_eq!(list.pairs().expect("csv").len(), 6);
}

#[test]
fn plan_errors_name_file_line_and_field() {
    let path = common::root().join("config/bad-plan.toml");
    let e = Plan::from_toml("[points]\nkind = \"grid\"\ntheta_i = [0]\n", Some(&path))
        .expect_err("missing angles");
    assert!(e.to_string().contains("missing field `phi_i`"), "{e}");
    let e = Plan::from_toml(
        "repeats = 1\n[points]\nkind = \"in-plane\"\ntheta_i = [0, 95]\ntheta_o = [30]\n",
        Some(&path),
    )
    .expect_err("θ > 90");
    assert_eq!(
        e.to_string(),
        format!(
            "{}:4:11: field `points.theta_i`: 95 is outside [0, 90]",
            path.display()
        )
    );
    let e = Plan::from_toml(
        "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = { from = 0, to = 10, step = 0 }\n",
        None,
    )
    .expect_err("step 0");
    assert!(e.to_string().starts_with("<plan>:4:"), "{e}");
    assert!(e.to_string().contains("step 0 must be positive"), "{e}");
    let e = Plan::from_toml(
        "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [30]\n[drift]\nevery = 0\n",
        None,
    )
    .expect_err("every 0");
    assert_eq!(e.field.as_deref(), Some("drift.every"));
    assert_eq!(e.line, Some(6));
    let e = Plan::from_toml(
        "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [30]\nspeed = 3\n",
        None,
    )
    .expect_err("unknown key");
    assert_eq!(e.line, Some(5));
    // A bad row of a directions file names that file and line.
    let scratch = common::scratch();
    let dir = scratch.path();
    std::fs::write(
        dir.join("d.csv"),
        "theta_i,phi_i,theta_o,phi_o\n0,0,30,0\n0,0,x,0\n",
    )
    .expect("write");
    let list = Plan::from_toml(
        "[points]\nkind = \"list\"\nfile = \"d.csv\"\n",
        Some(&dir.join("p.toml")),
    )
    .expect("parses");
    let e = list.pairs().expect_err("bad row");
    assert!(
        e.to_string()
            .starts_with(&format!("{}:3", dir.join("d.csv").display())),
        "{e}"
    );
}

/// Every number of a plan has a finite range and the plan's size a cap: each is
/// refused with its field, line and the limit (docs/acquisition.md, "Limits").
#[test]
fn plan_numbers_and_sizes_outside_their_limits_name_the_limit() {
    const IN_PLANE: &str = "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [30]\n";
    let cases: &[(String, usize, &str, &str)] = &[
        (
            format!("{IN_PLANE}[order]\nbudget_s = 1e20\n"),
            6,
            "order.budget_s",
            "must be at most 3600 s, got 1e20",
        ),
        (
            format!("{IN_PLANE}[order]\nbudget_s = nan\n"),
            6,
            "order.budget_s",
            "must be finite, got NaN",
        ),
        (
            IN_PLANE.replace("theta_i = [0]", "phi_i = nan\ntheta_i = [0]"),
            3,
            "points.phi_i",
            "must be finite, got NaN",
        ),
        (
            "[points]\nkind = \"grid\"\ntheta_i = [0]\nphi_i = [1e300]\ntheta_o = [30]\n\
             phi_o = [0]\n"
                .into(),
            4,
            "points.phi_i",
            "1e300 is outside [-360, 360]",
        ),
        (
            format!("{IN_PLANE}[calibration]\nincident = {{ stages = [0, 0, 0, 1e300] }}\n"),
            6,
            "calibration.incident.stages[3]",
            "must be at most 1e6 deg, got 1e300",
        ),
        (
            format!("{IN_PLANE}[drift]\nevery = 5\nat = [30, 1e300, 30, 0]\n"),
            7,
            "drift.at",
            "phi_i must be at most 360 deg, got 1e300",
        ),
        (
            // 8.1 × 10^11 pairs: 900 001 on each of two axes.
            "[points]\nkind = \"isotropic\"\ntheta_i = { from = 0, to = 90, step = 1e-4 }\n\
             theta_o = { from = 0, to = 90, step = 1e-4 }\ndelta_phi = [0]\n"
                .into(),
            1,
            "points",
            "expands to 810001800001 pairs, more than 1000000",
        ),
        (
            // 811 801 pairs, each read 10 000 times: 8 × 10^9 readings.
            "repeats = 10000\n[points]\nkind = \"isotropic\"\n\
             theta_i = { from = 0, to = 90, step = 0.1 }\n\
             theta_o = { from = 0, to = 90, step = 0.1 }\ndelta_phi = [0]\n"
                .into(),
            1,
            "repeats",
            "811801 pairs and 0 standard pairs × 10000 repeats × 1 channels is about \
             8118030000 readings, more than the 2000000 a plan may take",
        ),
    ];
    for (text, line, field, message) in cases {
        let e = Plan::from_toml(text, None).expect_err(text);
        assert_eq!(e.field.as_deref(), Some(*field), "{e}\n{text}");
        assert_eq!(e.line, Some(*line), "{e}\n{text}");
        assert_eq!(e.message, *message, "{text}");
    }
    // A directions file is counted when it is read.
    let scratch = common::scratch();
    let dir = scratch.path();
    let mut csv = String::from("theta_i,phi_i,theta_o,phi_o\n");
    for k in 0..1000 {
        csv.push_str(&format!("30,0,{},180\n", k % 90));
    }
    std::fs::write(dir.join("d.csv"), csv).expect("write");
    let list = Plan::from_toml(
        "repeats = 2001\n[points]\nkind = \"list\"\nfile = \"d.csv\"\n",
        Some(&dir.join("p.toml")),
    )
    .expect("parses");
    let e = list.pairs().expect_err("2 million readings");
    assert_eq!(e.field.as_deref(), Some("repeats"), "{e}");
    assert!(
        e.message.contains("more than the 2000000 a plan may take"),
        "{e}"
    );
    // A directions file that is not a regular file is refused without being read.
    let dev = Plan::from_toml(
        "[points]\nkind = \"list\"\nfile = \"/dev/zero\"\n",
        Some(&dir.join("p.toml")),
    )
    .expect("parses");
    let e = dev.pairs().expect_err("a device");
    assert_eq!(e.field.as_deref(), Some("points.file"), "{e}");
    assert!(
        e.message
            .contains("/dev/zero: a character device, not a regular file"),
        "{e}"
    );
}

/// An angle's value of none of its forms, and a fault inside the `[points]` table, are
/// named by their field and place, with what is accepted.
#[test]
fn points_errors_name_the_field_and_what_is_accepted() {
    let plan = |points: &str| {
        Plan::from_toml(&format!("name = \"p\"\n[points]\n{points}"), None)
            .expect_err(points)
            .to_string()
    };
    let forms = "a list of angles like [0, 30, 60], one angle like 45, or a range like \
                 { from = 0, to = 60, step = 30 }";
    assert_eq!(
        plan("kind = \"in-plane\"\ntheta_i = [0]\ntheta_o = \"all\"\n"),
        format!(
            "<plan>:5:11: field `points.theta_o`: invalid type: string \"all\", expected {forms}"
        )
    );
    assert_eq!(
        plan("kind = \"grid\"\ntheta_i = true\nphi_i = 0\ntheta_o = 0\nphi_o = 0\n"),
        format!(
            "<plan>:4:11: field `points.theta_i`: invalid type: boolean `true`, expected {forms}"
        )
    );
    assert_eq!(
        plan("kind = \"in-plane\"\ntheta_i = [0]\ntheta_o = { from = -80, to = 80 }\n"),
        "<plan>:5:11: field `points.theta_o`: a range needs from, to and step (missing step): \
         { from = 0, to = 60, step = 30 }"
    );
    assert_eq!(
        plan("kind = \"in-plane\"\ntheta_i = [0]\ntheta_o = { from = 0, to = 8, by = 1 }\n"),
        "<plan>:5:11: field `points.theta_o`: unknown key `by` in a range: a range is \
         { from = 0, to = 60, step = 30 }"
    );
    assert_eq!(
        plan("kind = \"in-plane\"\ntheta_i = [0, \"x\"]\ntheta_o = [30]\n"),
        "<plan>:4:11: field `points.theta_i`: invalid type: string \"x\", expected f64"
    );
    assert_eq!(
        plan("kind = \"in-plane\"\nphi_i = [0]\ntheta_i = [0]\ntheta_o = [30]\n"),
        "<plan>:4:9: field `points.phi_i`: invalid type: sequence, expected f64"
    );
    assert_eq!(
        plan("kind = \"spiral\"\n"),
        "<plan>:3:8: field `points.kind`: unknown kind \"spiral\", expected one of \"grid\", \
         \"isotropic\", \"in-plane\", \"list\" or \"adaptive\""
    );
    assert_eq!(
        plan("theta_i = [0]\n"),
        "<plan>:2:1: field `points`: missing field `kind` (\"grid\", \"isotropic\", \"in-plane\", \
         \"list\" or \"adaptive\")"
    );
    let e = Plan::from_toml("points = 5\n", None).expect_err("a number");
    assert_eq!(
        e.to_string(),
        "<plan>:1:10: field `points`: invalid type: integer `5`, expected a table with kind = \
         one of \"grid\", \"isotropic\", \"in-plane\", \"list\" or \"adaptive\""
    );
    // Every form still reads.
    let p = Plan::from_toml(
        "[points]\nkind = \"isotropic\"\nphi_i = 10\ntheta_i = 20\ntheta_o = [30, 40.5]\n\
         delta_phi = { from = 0, to = 180, step = 90 }\n",
        None,
    )
    .expect("valid");
    assert_eq!(
        p.points,
        plan::Points::Isotropic {
            phi_i: 10.0,
            theta_i: plan::Values::One(20.0),
            theta_o: plan::Values::List(vec![30.0, 40.5]),
            delta_phi: plan::Values::Range {
                from: 0.0,
                to: 180.0,
                step: 90.0
            },
        }
    );
}

/// The schedule: calibrations first (and last), references every N pairs, repeats
/// together, channels as passes, every accepted pair exactly once a pass.
#[test]
fn schedule_structure() {
    let text = r#"
channels = ["550nm", "650nm"]
repeats = 2
[points]
kind = "in-plane"
theta_i = [30]
theta_o = { from = 10, to = 70, step = 10 }
[drift]
every = 3
[calibration]
dark = true
dark_readings = 2          # one a repeat, as the structure below counts
incident = { transmittance = 0.01 }
repeat_at_end = true
"#;
    let plan = common::plan(text);
    let p = common::prepare(&plan).expect("prepares");
    let steps = &p.schedule.steps;
    let accepted = p.checked.accepted.len();
    assert_eq!(accepted, 7);
    // A pass: (dark + incident) × 2 repeats, first reference, 7 pairs × 2, references
    // after pairs 3, 6 and the last, then the calibrations again.
    let per_pass = 4 + 1 + 14 + 3 + 4;
    assert_eq!(steps.len(), 2 * per_pass);
    for (k, pass) in steps.chunks(per_pass).enumerate() {
        let ch = if k == 0 { "550nm" } else { "650nm" };
        assert!(pass.iter().all(|s| s.channel.as_deref() == Some(ch)));
        let kinds: Vec<StepKind> = pass.iter().map(|s| s.kind).collect();
        assert_eq!(
            &kinds[..5],
            &[
                StepKind::Dark,
                StepKind::Dark,
                StepKind::Incident,
                StepKind::Incident,
                StepKind::Reference
            ]
        );
        let mut seen: Vec<usize> = pass
            .iter()
            .filter(|s| s.kind == StepKind::Sample && s.repeat == 0)
            .map(|s| s.plan_index.expect("index"))
            .collect();
        seen.sort_unstable();
        let mut want: Vec<usize> = p.checked.accepted.iter().map(|a| a.index).collect();
        want.sort_unstable();
        assert_eq!(seen, want);
        // Repeats follow each other at the same stages.
        for w in pass.windows(2) {
            if w[1].repeat == 1 {
                assert_eq!(w[0].stages, w[1].stages);
                assert_eq!(w[0].repeat, 0);
            }
        }
    }
    // The second pass runs the pairs backwards.
    let order = |pass: &[gonio_plan::schedule::Step]| -> Vec<usize> {
        pass.iter()
            .filter(|s| s.kind == StepKind::Sample && s.repeat == 0)
            .map(|s| s.plan_index.expect("index"))
            .collect()
    };
    let mut second = order(&steps[per_pass..]);
    second.reverse();
    assert_eq!(order(&steps[..per_pass]), second);
    // The estimate: optimised never slower than plan order.
    assert!(p.schedule.motion_s <= p.schedule.raster_motion_s + 1e-9);
}

#[test]
fn a_plan_with_nothing_measurable_is_refused() {
    let plan =
        common::plan("[points]\nkind = \"in-plane\"\ntheta_i = [30]\ntheta_o = [-30, -25]\n");
    let e = common::prepare(&plan).expect_err("all shadowed");
    assert!(
        e.to_string()
            .contains("no pair of the plan can be measured"),
        "{e}"
    );
}

/// The dark readings each time the calibrations are taken: four when the plan does
/// not say (its shared error half a reading's noise at the floor), as many as
/// `dark_readings` asks, never fewer than the plan's `repeats`; none without `dark`.
#[test]
fn dark_readings_default_to_four_and_follow_the_plan() {
    let text = |repeats: u32, dark: &str| {
        format!(
            r#"
name = "darks"
repeats = {repeats}
[points]
kind = "in-plane"
theta_i = [30]
theta_o = [30]
[calibration]
{dark}
incident = {{ transmittance = 0.01 }}
repeat_at_end = true
"#
        )
    };
    let darks = |repeats: u32, dark: &str| {
        let p = common::prepare(&common::plan(&text(repeats, dark))).expect("prepares");
        let s = &p.schedule.steps;
        s.iter().filter(|s| s.kind == StepKind::Dark).count()
    };
    // Taken twice: before the sample's points and after them.
    assert_eq!(darks(1, ""), 0);
    assert_eq!(darks(1, "dark = true"), 2 * 4);
    assert_eq!(
        gonio_plan::plan::DEFAULT_DARK_READINGS,
        4,
        "the documented default"
    );
    assert_eq!(darks(1, "dark = true\ndark_readings = 7"), 2 * 7);
    assert_eq!(darks(9, "dark = true\ndark_readings = 7"), 2 * 9);
    assert_eq!(darks(1, "dark = false\ndark_readings = 7"), 0);
    let err = Plan::from_toml(&text(1, "dark = true\ndark_readings = 0"), None)
        .expect_err("refused")
        .to_string();
    assert!(err.contains("calibration.dark_readings"), "{err}");
}
