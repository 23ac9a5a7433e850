//! Spectral plans: wavelengths as a list or a range, their errors, the two loop
//! orders of the schedule, and the planner's choice between them from the estimated
//! times.

use crate::common;

use gonio_core::Channels;
use gonio_core::goniometer::OPERATOR_BAND_CHANGE_S;
use gonio_core::spectral_timing::WavelengthTiming;
use gonio_plan::schedule::{Loop, Step, StepKind};
use gonio_plan::{Inner, Mechanics, Plan, Prepared};

const IN_PLANE: &str = "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [30]\n";

fn reading_s() -> f64 {
    common::instrument().0.reading_seconds()
}

fn prepare_on(mech: &Mechanics, plan: &Plan) -> Prepared {
    gonio_plan::prepare(mech, reading_s(), plan).expect("prepares")
}

/// The channel of a step, as a number of nm.
fn nm(s: &Step) -> f64 {
    let name = s.channel.as_deref().expect("a band");
    match Channels::from_names(&[name]).expect("a wavelength") {
        Channels::Wavelengths(w) => w[0],
        other => panic!("{other:?}"),
    }
}

#[test]
fn wavelengths_as_a_list_or_a_range_name_the_channels() {
    let p = Plan::from_toml(
        &format!("wavelengths = [450, 550, 650.5]\n{IN_PLANE}"),
        None,
    )
    .expect("a list");
    assert_eq!(
        p.channel_names().expect("names"),
        Some(vec!["450nm".into(), "550nm".into(), "650.5nm".into()])
    );
    assert_eq!(p.band_wavelengths(), Some(vec![450.0, 550.0, 650.5]));
    assert_eq!(p.spectral.inner, Inner::Auto);

    // 400 to 700 by 10: exactly 31, both ends included.
    let p = Plan::from_toml(
        &format!("wavelengths = {{ from = 400, to = 700, step = 10 }}\n{IN_PLANE}"),
        None,
    )
    .expect("a range");
    let w = p.band_wavelengths().expect("wavelengths");
    assert_eq!(w.len(), 31);
    assert_eq!((w[0], w[30]), (400.0, 700.0));
    assert!(
        w.iter()
            .enumerate()
            .all(|(k, x)| *x == 400.0 + 10.0 * k as f64)
    );

    // By 0.1 nm: 400 + k·0.1 is not a short decimal in binary (400 + 3 × 0.1 is
    // 400.30000000000001), but the rounded values are, and their names read back to
    // the same numbers.
    let p = Plan::from_toml(
        &format!("wavelengths = {{ from = 400, to = 401, step = 0.1 }}\n{IN_PLANE}"),
        None,
    )
    .expect("a fine range");
    let w = p.band_wavelengths().expect("wavelengths");
    assert_eq!(w.len(), 11);
    let names = p.channel_names().expect("names").expect("bands");
    assert_eq!(names[3], "400.3nm");
    assert_eq!(names[10], "401nm");
    match Channels::from_names(&names).expect("names read back") {
        Channels::Wavelengths(back) => assert_eq!(&back[..], &w[..]),
        other => panic!("{other:?}"),
    }
    // One wavelength.
    let p = Plan::from_toml(&format!("wavelengths = 550\n{IN_PLANE}"), None).expect("one");
    assert_eq!(
        p.channel_names().expect("names"),
        Some(vec!["550nm".into()])
    );
    // Channels that all name wavelengths have them too; others have none.
    let p = Plan::from_toml(
        &format!("channels = [\"450nm\", \"550nm\"]\n{IN_PLANE}"),
        None,
    )
    .expect("channels");
    assert_eq!(p.band_wavelengths(), Some(vec![450.0, 550.0]));
    let p = Plan::from_toml(
        &format!("channels = [\"R\", \"G\", \"B\"]\n{IN_PLANE}"),
        None,
    )
    .expect("channels");
    assert_eq!(p.band_wavelengths(), None);
    // The inner loop, read.
    let p = Plan::from_toml(
        &format!("wavelengths = [450, 550]\n{IN_PLANE}[spectral]\ninner = \"wavelength\"\n"),
        None,
    )
    .expect("spectral");
    assert_eq!(p.spectral.inner, Inner::Wavelength);
}

#[test]
fn wavelength_errors_name_their_field_and_line() {
    // (text, line, field, message)
    let cases: &[(String, usize, &str, &str)] = &[
        (
            format!("channels = [\"550nm\"]\nwavelengths = [550]\n{IN_PLANE}"),
            2,
            "wavelengths",
            "`wavelengths` and `channels` both name the bands; give one of them",
        ),
        (
            format!("wavelengths = [450, 650, 550]\n{IN_PLANE}"),
            1,
            "wavelengths[2]",
            "550 nm does not follow 650 nm: wavelengths must be strictly increasing",
        ),
        (
            format!("wavelengths = [450, 450]\n{IN_PLANE}"),
            1,
            "wavelengths[1]",
            "450 nm does not follow 450 nm: wavelengths must be strictly increasing",
        ),
        (
            format!("wavelengths = [0, 450]\n{IN_PLANE}"),
            1,
            "wavelengths[0]",
            "must be at least 1 nm, got 0",
        ),
        (
            format!("wavelengths = []\n{IN_PLANE}"),
            1,
            "wavelengths",
            "name at least one wavelength",
        ),
        (
            format!("wavelengths = {{ from = 700, to = 400, step = 10 }}\n{IN_PLANE}"),
            1,
            "wavelengths",
            "range from 700 to 400 must have from ≤ to",
        ),
        (
            format!("wavelengths = {{ from = 400, to = 700, step = 0 }}\n{IN_PLANE}"),
            1,
            "wavelengths.step",
            "must be at least 0.001 nm, got 0",
        ),
        (
            format!("wavelengths = {{ from = 400, to = 1e9, step = 10 }}\n{IN_PLANE}"),
            1,
            "wavelengths.to",
            "must be at most 100000 nm, got 1e9",
        ),
        (
            // 30 001 wavelengths.
            format!("wavelengths = {{ from = 400, to = 700, step = 0.01 }}\n{IN_PLANE}"),
            1,
            "wavelengths.step",
            "400 to 700 by 0.01 nm is more than 10000 wavelengths",
        ),
        (
            format!("{IN_PLANE}[spectral]\ninner = \"sideways\"\n"),
            6,
            "spectral.inner",
            "unknown variant `sideways`, expected one of `auto`, `wavelength`, `geometry`",
        ),
        (
            // 811 801 pairs at 3 wavelengths: about 2.4 million readings.
            "wavelengths = [450, 550, 650]\n[points]\nkind = \"isotropic\"\n\
             theta_i = { from = 0, to = 90, step = 0.1 }\n\
             theta_o = { from = 0, to = 90, step = 0.1 }\ndelta_phi = [0]\n"
                .into(),
            1,
            "wavelengths",
            "811801 pairs and 0 standard pairs × 1 repeats × 3 channels is about 2435409 \
             readings, more than the 2000000 a plan may take",
        ),
    ];
    for (text, line, field, message) in cases {
        let e = Plan::from_toml(text, None).expect_err(text);
        assert_eq!(e.field.as_deref(), Some(*field), "{e}\n{text}");
        assert_eq!(e.line, Some(*line), "{e}\n{text}");
        assert_eq!(e.message, *message, "{text}");
    }
    // A value of none of the forms lists the forms, in nm.
    let e = Plan::from_toml(&format!("wavelengths = \"visible\"\n{IN_PLANE}"), None)
        .expect_err("a string");
    assert_eq!(
        e.to_string(),
        "<plan>:1:15: field `wavelengths`: invalid type: string \"visible\", expected a list \
         of wavelengths in nm like [450, 550, 650], one like 550, or a range like \
         { from = 400, to = 700, step = 10 }"
    );
    let e = Plan::from_toml(
        &format!("wavelengths = {{ from = 400, to = 700 }}\n{IN_PLANE}"),
        None,
    )
    .expect_err("no step");
    assert_eq!(
        e.message,
        "a range needs from, to and step (missing step): { from = 400, to = 700, step = 10 }"
    );
}

/// The plan of the schedule tests: 7 pairs at three wavelengths, two readings each,
/// a reference after every 3 pairs, dark and incident before and after.
fn three_band_plan(inner: &str) -> Plan {
    common::plan(&format!(
        r#"
wavelengths = [450, 550, 650]
repeats = 2
[spectral]
inner = "{inner}"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = {{ from = 10, to = 70, step = 10 }}
[drift]
every = 3
[calibration]
dark = true
dark_readings = 2          # one a repeat, as the structure below counts
incident = {{ transmittance = 0.01 }}
repeat_at_end = true
"#
    ))
}

/// With the wavelength loop inside, every configuration is measured at every
/// wavelength before the stages move: the calibrations, the references and every
/// pair; the sweeps alternate up and down when that is cheaper (an operator's band
/// changes all cost the same, so it is).
#[test]
fn wavelength_inner_measures_every_configuration_at_every_wavelength() {
    let mech = common::mechanics();
    let p = prepare_on(&mech, &three_band_plan("wavelength"));
    let s = &p.schedule;
    assert_eq!(p.checked.accepted.len(), 7);
    // Per wavelength what a pass holds: (dark + incident) × 2 repeats × 2, 4
    // references, 7 pairs × 2: 26, so 78 in all, as with the geometry loop inside.
    assert_eq!(s.steps.len(), 78);
    let d = s.spectral.as_ref().expect("a decision");
    assert_eq!(
        (d.inner, d.requested, d.bands),
        (Loop::Wavelength, Inner::Wavelength, 3)
    );
    assert!(d.alternate);
    // The configurations in order, each a run of steps at one place: its kind and
    // readings per wavelength.
    use StepKind::*;
    let configs = [
        (Dark, 2),
        (Incident, 2),
        (Reference, 1),
        (Sample, 2),
        (Sample, 2),
        (Sample, 2),
        (Reference, 1),
        (Sample, 2),
        (Sample, 2),
        (Sample, 2),
        (Reference, 1),
        (Sample, 2),
        (Reference, 1),
        (Dark, 2),
        (Incident, 2),
    ];
    let mut at = 0;
    let mut samples = Vec::new();
    for (k, (kind, repeats)) in configs.iter().enumerate() {
        let run = &s.steps[at..at + 3 * repeats];
        at += run.len();
        assert!(run.iter().all(|x| x.kind == *kind), "config {k}: {run:?}");
        assert!(
            run.iter()
                .all(|x| x.stages == run[0].stages && x.plan_index == run[0].plan_index),
            "config {k} moves"
        );
        // Up on even sweeps, down on odd ones; the repeats follow each other.
        let mut want: Vec<f64> = [450.0, 550.0, 650.0]
            .iter()
            .flat_map(|w| std::iter::repeat_n(*w, *repeats))
            .collect();
        if k % 2 == 1 {
            want.reverse();
        }
        assert_eq!(run.iter().map(nm).collect::<Vec<_>>(), want, "config {k}");
        let reps: Vec<u32> = run.iter().map(|x| x.repeat).collect();
        let want_reps: Vec<u32> = (0..3).flat_map(|_| 0..*repeats as u32).collect();
        assert_eq!(reps, want_reps, "config {k}");
        if *kind == Sample {
            samples.push(run[0].plan_index.expect("index"));
        }
    }
    assert_eq!(at, s.steps.len());
    samples.sort_unstable();
    let mut want: Vec<usize> = p.checked.accepted.iter().map(|a| a.index).collect();
    want.sort_unstable();
    assert_eq!(samples, want);
    // The bands first appear in increasing wavelength (the reduction's channel order).
    let mut first: Vec<f64> = Vec::new();
    for x in &s.steps {
        if !first.contains(&nm(x)) {
            first.push(nm(x));
        }
    }
    assert_eq!(first, [450.0, 550.0, 650.0]);
    // The stages follow one pass over the geometry: their motion is exactly that of
    // the same plan in one unnamed band. (Its serial exchanges are not: every step
    // commands its move, also one that stays where it is.)
    let mut single = three_band_plan("wavelength");
    single.wavelengths = None;
    let bare = Mechanics {
        exchanges: None,
        ..mech.clone()
    };
    let one = prepare_on(&bare, &single);
    assert_eq!(one.schedule.steps.len(), 26);
    assert!(one.schedule.spectral.is_none());
    let three = prepare_on(&bare, &three_band_plan("wavelength")).schedule;
    assert_eq!(three.motion_s, one.schedule.motion_s);
    assert!(s.motion_s > three.motion_s);
    // Band changes: the first selection, then two per sweep of the 15 sweeps, each
    // an operator's minute.
    assert_eq!(d.wavelength_inner.band_changes, 31);
    assert!((s.band_s - 31.0 * OPERATOR_BAND_CHANGE_S).abs() < 1e-9);
}

/// Both orders take the same readings: per wavelength, the same kinds, pairs and
/// repeats; the geometry loop runs one pass per wavelength, in increasing order.
#[test]
fn both_orders_take_the_same_readings() {
    let mech = common::mechanics();
    let w = prepare_on(&mech, &three_band_plan("wavelength")).schedule;
    let g = prepare_on(&mech, &three_band_plan("geometry")).schedule;
    assert_eq!(g.spectral.as_ref().map(|d| d.inner), Some(Loop::Geometry));
    assert_eq!(w.steps.len(), g.steps.len());
    for (k, pass) in g.steps.chunks(26).enumerate() {
        let want = [450.0, 550.0, 650.0][k];
        assert!(pass.iter().all(|x| nm(x) == want), "pass {k}");
    }
    for band in [450.0, 550.0, 650.0] {
        let key = |v: &[Step]| {
            let mut k: Vec<(&str, Option<usize>, u32)> = v
                .iter()
                .filter(|x| nm(x) == band)
                .map(|x| (x.kind.as_str(), x.plan_index, x.repeat))
                .collect();
            k.sort_unstable();
            k
        };
        let (a, b) = (key(&w.steps), key(&g.steps));
        assert_eq!(a, b, "{band} nm");
        // Each wavelength: 4 darks, 4 incident readings, 4 references, 14 samples.
        let count = |kind: &str| a.iter().filter(|x| x.0 == kind).count();
        assert_eq!(
            [
                count("dark"),
                count("incident"),
                count("reference"),
                count("sample")
            ],
            [4, 4, 4, 14],
            "{band} nm"
        );
    }
    // The two estimates, whichever runs, are the same numbers.
    let (dw, dg) = (
        w.spectral.as_ref().expect("decision"),
        g.spectral.as_ref().expect("decision"),
    );
    assert_eq!(dw.wavelength_inner, dg.wavelength_inner);
    assert_eq!(dw.geometry_inner, dg.geometry_inner);
    assert_eq!(g.motion_s, dg.geometry_inner.motion_s);
    assert_eq!(g.band_s, dg.geometry_inner.band_s);
    assert_eq!(dg.geometry_inner.band_changes, 3);
    // The readings do not depend on the order.
    assert_eq!(dw.wavelength_inner.detector_s, dw.geometry_inner.detector_s);
    assert!((g.detector_s - 78.0 * reading_s()).abs() < 1e-9);
}

/// `auto` takes the shorter estimate. With a per-change selector of c seconds, each
/// order's total is a line in c: T(c) = motion + readings + n·c, with n its band
/// changes (31 with the wavelength loop inside, 3 with the geometry loop). The lines
/// cross at c* = (M_geometry − M_wavelength) / (31 − 3): just below c* the
/// wavelength loop is chosen, just above it the geometry loop, and the reason gives
/// both estimates.
#[test]
fn auto_flips_where_the_estimates_cross() {
    let base = common::mechanics();
    let plan = three_band_plan("auto");
    let at = |c: f64| {
        prepare_on(
            &base
                .clone()
                .with_wavelength(WavelengthTiming::per_change(c)),
            &plan,
        )
    };
    let probe = at(1.0);
    let d = probe.schedule.spectral.clone().expect("decision");
    let (w, g) = (d.wavelength_inner, d.geometry_inner);
    assert_eq!((w.band_changes, g.band_changes), (31, 3));
    assert!((w.band_s - 31.0).abs() < 1e-9 && (g.band_s - 3.0).abs() < 1e-9);
    for e in [w, g] {
        assert!((e.total_s - (e.motion_s + e.band_s + e.detector_s)).abs() < 1e-9);
    }
    // Three passes over the geometry move the stages more than one.
    assert!(g.motion_s > w.motion_s, "{g:?} {w:?}");
    let c_star = (g.motion_s - w.motion_s) / (31.0 - 3.0);
    for (c, want) in [
        (0.99 * c_star, Loop::Wavelength),
        (1.01 * c_star, Loop::Geometry),
    ] {
        let p = at(c);
        let d = p.schedule.spectral.expect("decision");
        assert_eq!(d.inner, want, "c = {c} s, c* = {c_star} s");
        assert_eq!(d.requested, Inner::Auto);
        // The motion does not depend on c; the band time is n·c.
        assert_eq!(d.wavelength_inner.motion_s, w.motion_s);
        assert!((d.wavelength_inner.band_s - 31.0 * c).abs() < 1e-9);
        assert!((d.geometry_inner.band_s - 3.0 * c).abs() < 1e-9);
        assert_eq!(
            p.schedule.band_s,
            match want {
                Loop::Wavelength => d.wavelength_inner.band_s,
                Loop::Geometry => d.geometry_inner.band_s,
            }
        );
        let (mine, other) = match want {
            Loop::Wavelength => ("wavelength", "geometry"),
            Loop::Geometry => ("geometry", "wavelength"),
        };
        assert!(
            d.reason.starts_with(&format!("{mine} inner: ")),
            "{}",
            d.reason
        );
        assert!(
            d.reason.contains(&format!(" than {other} inner: ")),
            "{}",
            d.reason
        );
        assert!(d.reason.contains(" 31 band changes of "), "{}", d.reason);
        assert!(d.reason.contains(" 3 band changes of "), "{}", d.reason);
        assert_eq!(p.schedule.steps.len(), 78);
    }
    // An operator changing bands (no timing): a minute a change keeps the geometry
    // loop inside.
    let p = prepare_on(&base, &plan);
    let d = p.schedule.spectral.expect("decision");
    assert_eq!(d.inner, Loop::Geometry);
    assert!((d.geometry_inner.band_s - 3.0 * OPERATOR_BAND_CHANGE_S).abs() < 1e-9);
}

/// A monochromator whose drive takes up its backlash from below pays the overshoot
/// on every move down. For 16 wavelengths 400–700 nm by 20 at 100 nm/s, settling
/// 0.1 s, with b nm of backlash: a sweep up costs 15 × 0.3 = 4.5 s, a sweep down
/// 15 × (0.3 + 0.02 b) s, the move back from 700 to 400 nm 3.1 + 0.02 b s.
/// Alternating pays when down < up + 2·back, i.e. 0.26 b < 6.2, b < 23.85 nm.
#[test]
fn the_timing_decides_whether_sweeps_alternate() {
    let plan = common::plan(
        r#"
wavelengths = { from = 400, to = 700, step = 20 }
[spectral]
inner = "wavelength"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = [20, 40, 60]
"#,
    );
    let mono = |b: f64| {
        common::mechanics()
            .with_wavelength(WavelengthTiming::monochromator(100.0, 0.1).with_backlash(b))
    };
    for (b, alternate) in [(23.0, true), (25.0, false)] {
        let p = prepare_on(&mono(b), &plan);
        let d = p.schedule.spectral.as_ref().expect("decision");
        assert_eq!(d.alternate, alternate, "backlash {b} nm");
        let sweeps: Vec<Vec<f64>> = p
            .schedule
            .steps
            .chunks(16)
            .map(|c| c.iter().map(nm).collect())
            .collect();
        assert_eq!(sweeps.len(), 3);
        let up: Vec<f64> = (0..16).map(|k| 400.0 + 20.0 * k as f64).collect();
        let mut down = up.clone();
        down.reverse();
        assert_eq!(sweeps[0], up);
        assert_eq!(sweeps[1], if alternate { down } else { up.clone() });
        assert_eq!(sweeps[2], up);
        // The band time, analytically: from nowhere a settle (no filter, no
        // grating), then per sweep up 4.5 s, down 15 × (0.3 + 0.02 b), back
        // 3.1 + 0.02 b.
        let (sweep_up, sweep_down, back) = (4.5, 15.0 * (0.3 + 0.02 * b), 3.1 + 0.02 * b);
        let want = 0.1
            + if alternate {
                sweep_up + sweep_down + sweep_up
            } else {
                3.0 * sweep_up + 2.0 * back
            };
        assert!(
            (p.schedule.band_s - want).abs() < 1e-9,
            "{} vs {want}",
            p.schedule.band_s
        );
    }
}

/// The example spectral plan reads and prepares: 16 wavelengths, a dark and an
/// incident reading at each, before and after.
#[test]
fn the_example_spectral_plan_prepares() {
    let (plan, _) = Plan::load(&common::root().join("config/plan-spectral.toml")).expect("loads");
    let names = plan.channel_names().expect("names").expect("bands");
    assert_eq!(names.len(), 16);
    assert_eq!((names[0].as_str(), names[15].as_str()), ("400nm", "700nm"));
    let p = common::prepare(&plan).expect("prepares");
    let d = p.schedule.spectral.as_ref().expect("decision");
    assert_eq!(d.bands, 16);
    // The simulated instrument has no wavelength timing: an operator's minute per
    // change keeps the geometry loop inside.
    assert_eq!(d.inner, Loop::Geometry);
    for n in &names {
        let of = |k: StepKind| {
            p.schedule
                .steps
                .iter()
                .filter(|s| s.kind == k && s.channel.as_deref() == Some(n))
                .count()
        };
        // The plan's default dark readings, each time the calibrations are taken.
        assert_eq!(
            (of(StepKind::Dark), of(StepKind::Incident)),
            (2 * gonio_plan::plan::DEFAULT_DARK_READINGS as usize, 2),
            "{n}"
        );
        assert_eq!(of(StepKind::Sample), p.checked.accepted.len(), "{n}");
    }
}
