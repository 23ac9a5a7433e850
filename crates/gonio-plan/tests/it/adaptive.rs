//! Adaptive plans: what they read, what they refuse, and what they schedule.

use crate::common;

use gonio_plan::adaptive::{Budget, Method, lattice};
use gonio_plan::plan::Points;
use gonio_plan::{Plan, StepKind};

const CAL: &str = "[calibration]\ndark = true\nincident = { transmittance = 1e-3 }\n";

fn text(points: &str) -> String {
    format!("[points]\nkind = \"adaptive\"\n{points}{CAL}")
}

fn refused(t: &str) -> String {
    Plan::from_toml(t, None).expect_err("refused").to_string()
}

#[test]
fn an_adaptive_plan_reads_with_its_defaults() {
    let p = common::plan(&text("theta_i = [30, 60]\nbudget = { points = 600 }\n"));
    let Points::Adaptive(a) = &p.points else {
        panic!("not adaptive: {:?}", p.points)
    };
    assert_eq!(a.budget, Budget::Points(600));
    assert_eq!((a.coarse, a.batch, a.candidates), (0.3, 0.1, 32768));
    assert_eq!((a.method, a.seed, a.phi_i), (Method::Residual, 0, 0.0));
    // 600 × 0.3 / 2 = 90 lattice points and the mirror direction per incidence.
    let pairs = p.pairs().expect("pairs");
    assert_eq!(pairs.len(), 2 * 91);
    assert_eq!(
        (pairs[0].outgoing.theta_deg, pairs[0].outgoing.phi_deg),
        (30.0, 180.0)
    );
    let h = common::plan(&text(
        "theta_i = { from = 20, to = 60, step = 20 }\nbudget = { hours = 2.5 }\n\
         method = \"value\"\ncoarse = 0.5\nbatch = 0.05\ncandidates = 1000\nseed = 9\n",
    ));
    let Points::Adaptive(a) = &h.points else {
        panic!("not adaptive")
    };
    assert_eq!(a.budget, Budget::Hours(2.5));
    assert_eq!(
        (a.coarse, a.batch, a.candidates, a.method, a.seed),
        (0.5, 0.05, 1000, Method::Value, 9)
    );
    // A time budget needs the instrument to become points.
    let e = h.pairs().expect_err("hours").to_string();
    assert!(e.contains("expanded on an instrument"), "{e}");
}

#[test]
fn adaptive_plan_errors_name_the_field() {
    assert_eq!(
        refused(&text(
            "theta_i = [30]\nbudget = { points = 10, hours = 1 }\n"
        )),
        "<plan>:4:10: field `points.budget`: `budget` takes one of `points` and `hours`: \
         { points = 1200 } or { hours = 2.5 }"
    );
    assert_eq!(
        refused(&text("theta_i = [30]\nbudget = { points = 0 }\n")),
        "<plan>:4:21: field `points.budget.points`: 0 is not in 1..=1000000"
    );
    let e = refused(&text("theta_i = [30]\nbudget = { hours = -1 }\n"));
    assert!(e.contains("field `points.budget.hours`"), "{e}");
    let e = refused(&text(
        "theta_i = [30]\nbudget = { points = 9 }\ncoarse = 1.5\n",
    ));
    assert!(e.contains("field `points.coarse`"), "{e}");
    let e = refused(&text(
        "theta_i = [30]\nbudget = { points = 9 }\ncandidates = 10\n",
    ));
    assert!(
        e.contains("field `points.candidates`: 10 is not in 64..=262144"),
        "{e}"
    );
    let e = refused(&text("theta_i = [95]\nbudget = { points = 9 }\n"));
    assert!(
        e.contains("field `points.theta_i`: 95 is outside [0, 90]"),
        "{e}"
    );
    let e = refused(&text(
        "theta_i = [30]\nbudget = { points = 9 }\nmethod = \"magic\"\n",
    ));
    assert!(e.contains("unknown variant `magic`"), "{e}");
    let e = refused("[points]\nkind = \"adaptive\"\ntheta_i = [30]\nbudget = { points = 9 }\n");
    assert!(
        e.contains(
            "field `calibration`: an adaptive plan chooses its points from the reduced BRDF"
        ),
        "{e}"
    );
    let e = refused(&format!(
        "{}repeat_at_end = true\n",
        text("theta_i = [30]\nbudget = { points = 9 }\n")
    ));
    assert!(e.contains("field `calibration.repeat_at_end`"), "{e}");
}

#[test]
fn prepare_schedules_the_coarse_pass_and_states_the_budget() {
    let p = common::plan(&format!(
        "[drift]\nevery = 50\n{}",
        text("theta_i = [30, 60]\nbudget = { points = 600 }\n")
    ));
    let prepared = common::prepare(&p).expect("prepared");
    let a = prepared.adaptive.as_ref().expect("adaptive summary");
    assert_eq!(a.points, 600);
    assert_eq!(a.batch, 60);
    assert_eq!(a.coarse, prepared.checked.accepted.len());
    // The coarse pass is its 182 pairs less what the instrument refuses (the
    // retro-reflection cone the arms cannot reach).
    assert_eq!(prepared.pairs.len(), 182);
    assert!(a.coarse > 160 && a.coarse < 182, "{}", a.coarse);
    // Every candidate the instrument refuses is counted, and the pool is what is left.
    assert_eq!(a.pool + a.refused, 2 * 32768);
    assert!(a.refused > 0 && a.refused < 2 * 32768 / 10, "{}", a.refused);
    // The whole run: the coarse schedule and the points left at its time per point.
    let s = &prepared.schedule;
    assert!((a.point_s - s.duration_s() / a.coarse as f64).abs() < 1e-9);
    assert!((a.estimate_s - (s.duration_s() + (600 - a.coarse) as f64 * a.point_s)).abs() < 1e-6);
    let samples = s
        .steps
        .iter()
        .filter(|x| x.kind == StepKind::Sample)
        .count();
    assert_eq!(samples, a.coarse);

    // A budget in hours becomes the points its time allows.
    let h = common::plan(&text("theta_i = [30, 60]\nbudget = { hours = 1 }\n"));
    let ph = common::prepare(&h).expect("prepared");
    let ah = ph.adaptive.as_ref().expect("summary");
    assert!(ah.points > 50 && ah.points < 3600, "{}", ah.points);
    assert!(
        (ah.estimate_s - 3600.0).abs() < 0.2 * 3600.0,
        "{} s for a budget of an hour",
        ah.estimate_s
    );
}

#[test]
fn the_coarse_pass_never_passes_the_budget() {
    // The whole budget in the coarse pass: 49 lattice directions and the mirror at
    // each incidence, 100 points, not 102.
    let p = common::plan(&text(
        "theta_i = [30, 60]\nbudget = { points = 100 }\ncoarse = 1.0\n",
    ));
    let prepared = common::prepare(&p).expect("prepared");
    assert_eq!(prepared.pairs.len(), 100);
    assert!(prepared.adaptive.expect("summary").coarse <= 100);
    // Too small a budget for a coarse pass, and a coarse pass longer than the time.
    let e = common::prepare(&common::plan(&text(
        "theta_i = [30, 60]\nbudget = { points = 3 }\n",
    )))
    .expect_err("3 points for 2 incidences")
    .to_string();
    assert!(
        e.ends_with(
            ": field `points.budget`: a budget of 3 points cannot hold a coarse pass at 2 \
         incidences: it takes at least two points per incidence (a direction and the mirror)"
        ),
        "{e}"
    );
    let e = common::prepare(&common::plan(&text(
        "theta_i = [30, 60]\nbudget = { hours = 0.005 }\n",
    )))
    .expect_err("18 s")
    .to_string();
    assert!(
        e.contains(": field `points.budget`: the coarse pass alone is estimated at ")
            && e.ends_with(
                "more than the budget of 0.005 h (18 s): raise the budget or lower `coarse`"
            ),
        "{e}"
    );
}

#[test]
fn the_lattice_is_deterministic() {
    assert_eq!(lattice(100, 0.3), lattice(100, 0.3));
    assert_ne!(lattice(100, 0.3), lattice(100, 0.4));
}
