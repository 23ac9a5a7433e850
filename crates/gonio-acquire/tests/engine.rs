//! The run engine on the simulator: a complete run, calibrations, and what is stored.

mod common;

use gonio_acquire::engine::Outcome;
use gonio_brdf::{Brdf, Model};
use gonio_core::radiometry::Aperture;
use gonio_plan::StepKind;
use gonio_run::{RunStore, flags};

const PLAN: &str = r#"
name = "in-plane test"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = { from = -60, to = 60, step = 20 }
[drift]
every = 3
[calibration]
dark = true
incident = { transmittance = 1e-3 }
"#;

#[test]
fn a_complete_run_measures_the_blue_paint() {
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, prepared) = common::create(&out, &plan, PLAN, 7);
    // θo = −20 lies 10° from the source: measurable; none are shadowed at 8°.
    assert_eq!(prepared.checked.accepted.len(), 7);
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let (report, store) = common::run_session(engine);
    assert_eq!(report.outcome, Outcome::Complete);
    let steps = store.steps().expect("steps");
    assert_eq!(report.total, steps.len());
    assert_eq!(report.measured, steps.len());
    assert!(steps.iter().all(|s| s.state == "done"));
    let readings = store.readings().expect("readings");
    assert_eq!(readings.len(), steps.len());

    // The calibrations: dark is noise only; the incident beam through its 1e-3 filter
    // gives R_v P T = 1e4 · 1e-3 · 1e-3 = 10 mV at the detector, 4.5 mV after the
    // lock-in's chop gain of 0.45.
    let by_kind = |k: StepKind| {
        steps
            .iter()
            .filter(|s| s.step.kind == k)
            .map(|s| readings.iter().find(|r| r.step_id == s.id).expect("read"))
            .collect::<Vec<_>>()
    };
    let dark = by_kind(StepKind::Dark);
    let incident = by_kind(StepKind::Incident);
    assert_eq!((dark.len(), incident.len()), (1, 1));
    assert!(dark[0].r_mean < 1e-6, "dark {}", dark[0].r_mean);
    assert!(
        (incident[0].r_mean - 4.5e-3).abs() < 1e-5,
        "incident {}",
        incident[0].r_mean
    );
    // The incident reading is taken with the arms opposite each other.
    assert_eq!(incident[0].commanded, Some([-90.0, 90.0, 0.0, 0.0]));

    // Every sample reading, reduced with the calibrations, gives the model's BRDF.
    let model = Model::from_toml(
        &std::fs::read_to_string(common::root().join("config/models/blue-paint-550nm.toml"))
            .expect("model"),
        None,
    )
    .expect("model parses");
    let omega = Aperture {
        radius_m: 0.005,
        distance_m: 0.3,
    }
    .solid_angle_sr();
    let s_in = (incident[0].r_mean - dark[0].r_mean) / 1e-3;
    let mut f = [0.0];
    for s in steps.iter().filter(|s| s.step.kind == StepKind::Sample) {
        let r = readings.iter().find(|r| r.step_id == s.id).expect("read");
        assert_eq!(r.flags, 0);
        let pair = s.step.pair.expect("pair").to_dirs();
        model.eval(pair.wi, pair.wo, &mut f);
        let measured = (r.r_mean - dark[0].r_mean) / s_in / (omega * pair.wo.z);
        assert!(
            (measured - f[0]).abs() < 2e-3 * f[0] + 3.0 * r.r_std / s_in / (omega * pair.wo.z),
            "step {}: measured {measured}, model {}",
            s.id,
            f[0]
        );
        // Read back where commanded (stepper quantisation is far below 0.01°).
        let cmd = r.commanded.expect("moved");
        for (p, c) in r.position.iter().zip(cmd) {
            assert!((p - c).abs() < 0.01);
        }
    }
    // Drift references: one before, after every third pair, and after the last.
    assert_eq!(by_kind(StepKind::Reference).len(), 1 + 2 + 1);
    drop(store);
    // The file reopens intact and reports itself complete.
    let store = RunStore::open(&out).expect("reopens");
    assert_eq!(
        store.meta_value("status").expect("meta").as_deref(),
        Some("complete")
    );
    let _ = flags::SHADOWED;
}

/// Runs a session on a multi-threaded runtime while `during` reacts to its events.
fn run_watched(
    engine: gonio_acquire::Engine<gonio_sim::SimClock, gonio_sim::SimBench>,
    during: impl FnOnce(
        tokio::sync::broadcast::Receiver<gonio_acquire::Event>,
        gonio_acquire::Pauser,
        gonio_acquire::Stopper,
    ) -> std::pin::Pin<
        Box<dyn std::future::Future<Output = Vec<gonio_acquire::Event>> + Send>,
    >,
) -> (
    gonio_acquire::SessionReport,
    RunStore,
    Vec<gonio_acquire::Event>,
) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let watcher = during(engine.subscribe(), engine.pauser(), engine.stopper());
    rt.block_on(async move {
        let heard = tokio::spawn(watcher);
        let (report, store) = engine.run().await.expect("engine runs");
        (report, store, heard.await.expect("watcher"))
    })
}

#[test]
fn a_pause_holds_the_run_between_steps_until_resumed() {
    use gonio_acquire::Event;
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, _) = common::create(&out, &plan, PLAN, 7);
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let (report, store, heard) = run_watched(engine, |mut rx, pauser, _| {
        Box::pin(async move {
            let mut heard = Vec::new();
            while let Ok(e) = rx.recv().await {
                match &e {
                    // Paused after the third step's commit: nothing is measured
                    // while the pause lasts, however long.
                    Event::Measured { done: 3, .. } => pauser.pause(),
                    Event::Paused => {
                        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
                        pauser.resume();
                    }
                    Event::Finished { .. } => {
                        heard.push(e);
                        break;
                    }
                    _ => {}
                }
                heard.push(e);
            }
            heard
        })
    });
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!(report.measured, report.total);
    let order: Vec<String> = heard
        .iter()
        .filter_map(|e| match e {
            Event::Measured { done, .. } => Some(format!("m{done}")),
            Event::Paused => Some("paused".into()),
            Event::Resumed => Some("resumed".into()),
            _ => None,
        })
        .collect();
    let at = order.iter().position(|s| s == "paused").expect("paused");
    // Step 3's commit may race the request by one step, never more.
    assert!(
        order[..at] == ["m1", "m2", "m3"] || order[..at] == ["m1", "m2", "m3", "m4"],
        "{order:?}"
    );
    assert_eq!(order[at + 1], "resumed");
    let kinds: Vec<String> = store
        .events()
        .expect("events")
        .into_iter()
        .map(|e| e.kind)
        .filter(|k| k == "pause" || k == "continue")
        .collect();
    assert_eq!(kinds, ["pause", "continue"]);
}

#[test]
fn a_stop_during_a_pause_ends_the_session_interrupted_and_resumable() {
    use gonio_acquire::Event;
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, _) = common::create(&out, &plan, PLAN, 7);
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let (report, store, _) = run_watched(engine, |mut rx, pauser, stopper| {
        pauser.pause();
        Box::pin(async move {
            while let Ok(e) = rx.recv().await {
                if e == Event::Paused {
                    stopper.stop();
                }
                if matches!(e, Event::Finished { .. }) {
                    break;
                }
            }
            Vec::new()
        })
    });
    assert_eq!(report.outcome, Outcome::Interrupted);
    assert_eq!(report.measured, 0);
    assert!(store.readings().expect("readings").is_empty());
    let log = store.events().expect("events");
    let msg = log
        .iter()
        .find(|e| e.kind == "continue")
        .expect("pause end logged");
    assert_eq!(msg.message, "pause ended by a stop");
    // Resumable: the next session measures every step.
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let (report, _) = common::run_session(engine);
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!(report.measured, report.total);
}
