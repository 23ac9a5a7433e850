//! The run engine on the simulator: a complete run, calibrations, and what is stored.

use crate::common;

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
dark_readings = 1
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

/// The run log's pause and continue entries, in order.
fn pause_log(store: &RunStore) -> Vec<String> {
    store
        .events()
        .expect("events")
        .into_iter()
        .map(|e| e.kind)
        .filter(|k| k == "pause" || k == "continue")
        .collect()
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
    // One thread: the watcher runs only where the engine awaits, so where a request
    // lands among the steps does not depend on how the machine schedules threads
    // (on two threads a loaded machine let the engine commit two steps past a
    // pause asked for at the third).
    let rt = tokio::runtime::Builder::new_current_thread()
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
    assert_eq!(pause_log(&store), ["pause", "continue"]);
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

#[test]
fn a_stop_requested_before_the_session_starts_is_honoured() {
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, _) = common::create(&out, &plan, PLAN, 7);
    let (engine, _sim) = common::engine(store, 7, |_| {});
    // As a live page's Stop may arrive between the server's start and the engine's.
    engine.stopper().stop();
    let (report, store) = common::run_session(engine);
    assert_eq!(report.outcome, Outcome::Interrupted);
    assert_eq!(report.measured, 0);
    assert!(store.readings().expect("readings").is_empty());
}

/// What the adaptive test's planner saw at each call: readings committed, steps done,
/// steps pending.
type Seen = std::sync::Arc<std::sync::Mutex<Vec<(usize, usize, usize)>>>;

/// The adaptive test's planner: batch 1 takes the schedule's first two sample pairs
/// again with a drift reference, batch 2 the next three sample pairs, then nothing.
/// It decides from the file alone (the batches it holds), as a planner must, and
/// writes into each decision the readings it was made from (their count and the sum
/// of their R).
fn planner(schedule: &[gonio_plan::Step], seen: Seen) -> gonio_acquire::Planner {
    let samples: Vec<gonio_plan::Step> = schedule
        .iter()
        .filter(|s| s.kind == StepKind::Sample)
        .cloned()
        .collect();
    let reference = schedule
        .iter()
        .find(|s| s.kind == StepKind::Reference)
        .cloned()
        .expect("a drift reference");
    Box::new(move |store: &RunStore| {
        let readings = store.readings().map_err(|e| e.to_string())?;
        let steps = store.steps().map_err(|e| e.to_string())?;
        let count = |state: &str| steps.iter().filter(|s| s.state == state).count();
        seen.lock()
            .expect("not poisoned")
            .push((readings.len(), count("done"), count("pending")));
        let sum_r: f64 = readings.iter().map(|r| r.r_mean).sum();
        let (method, steps) = match store.decisions().map_err(|e| e.to_string())?.len() {
            0 => (
                "again",
                vec![samples[0].clone(), samples[1].clone(), reference.clone()],
            ),
            1 => ("next", samples[2..5].to_vec()),
            _ => return Ok(None),
        };
        Ok(Some(gonio_run::Batch {
            decision: gonio_run::Decision {
                method: method.into(),
                points: steps.iter().filter(|s| s.kind == StepKind::Sample).count() as u32,
                detail: format!(r#"{{"readings":{},"sum_r":{sum_r:e}}}"#, readings.len()),
            },
            steps,
        }))
    })
}

/// What a session's listener returns: every event it heard.
type Heard = std::pin::Pin<Box<dyn std::future::Future<Output = Vec<gonio_acquire::Event>> + Send>>;

/// Every event of a session, until it finishes; `stop_at` raises the stopper on the
/// first event it accepts.
fn listen(
    stop_at: impl Fn(&gonio_acquire::Event) -> bool + Send + 'static,
) -> impl FnOnce(
    tokio::sync::broadcast::Receiver<gonio_acquire::Event>,
    gonio_acquire::Pauser,
    gonio_acquire::Stopper,
) -> Heard {
    move |mut rx, _, stopper| {
        Box::pin(async move {
            let mut heard = Vec::new();
            while let Ok(e) = rx.recv().await {
                if stop_at(&e) {
                    stopper.stop();
                }
                let end = matches!(e, gonio_acquire::Event::Finished { .. });
                heard.push(e);
                if end {
                    break;
                }
            }
            heard
        })
    }
}

#[test]
fn an_adaptive_run_measures_its_planners_batches_until_it_has_none() {
    use gonio_acquire::Event;
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, prepared) = common::create(&out, &plan, PLAN, 7);
    let n = prepared.schedule.steps.len();
    let seen = Seen::default();
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let engine = engine.with_planner(planner(&prepared.schedule.steps, seen.clone()));
    let (report, store, heard) = run_watched(engine, listen(|_| false));
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!((report.total, report.measured), (n + 6, n + 6));
    let steps = store.steps().expect("steps");
    assert_eq!(steps.len(), n + 6);
    assert!(steps.iter().all(|s| s.state == "done"));
    // The batches' steps are the planner's, after the schedule's.
    let sched = &prepared.schedule.steps;
    let samples: Vec<&gonio_plan::Step> = sched
        .iter()
        .filter(|s| s.kind == StepKind::Sample)
        .collect();
    assert_eq!(steps[n].step, *samples[0]);
    assert_eq!(steps[n + 1].step, *samples[1]);
    assert_eq!(steps[n + 2].step.kind, StepKind::Reference);
    assert_eq!(steps[n + 5].step, *samples[4]);
    // The planner saw every reading before it and nothing pending, each time; the
    // third call ended the run.
    assert_eq!(
        *seen.lock().expect("not poisoned"),
        [(n, n, 0), (n + 3, n + 3, 0), (n + 6, n + 6, 0)]
    );
    let readings = store.readings().expect("readings");
    let decided: Vec<_> = store
        .decisions()
        .expect("decisions")
        .into_iter()
        .map(|d| (d.id, d.first_step, d.steps, d.points, d.method, d.readings))
        .collect();
    assert_eq!(
        decided,
        [
            (1, n as i64, 3, 2, "again".to_string(), n as u64),
            (2, n as i64 + 3, 3, 3, "next".to_string(), n as u64 + 3),
        ]
    );
    let batches: Vec<(Option<i64>, String)> = store
        .events()
        .expect("events")
        .into_iter()
        .filter(|e| e.kind == "batch")
        .map(|e| (e.step_id, e.message))
        .collect();
    assert_eq!(
        batches,
        [
            (
                Some(n as i64),
                "batch 1: 2 points, 3 steps (again)".to_string()
            ),
            (
                Some(n as i64 + 3),
                "batch 2: 3 points, 3 steps (next)".to_string()
            ),
        ]
    );
    // Listeners hear each batch with the run's new size, and every step's
    // measurement against the size at the time.
    let told: Vec<&Event> = heard
        .iter()
        .filter(|e| matches!(e, Event::Batch { .. }))
        .collect();
    assert_eq!(
        told,
        [
            &Event::Batch {
                batch: 1,
                points: 2,
                steps: 3,
                total: n + 3
            },
            &Event::Batch {
                batch: 2,
                points: 3,
                steps: 3,
                total: n + 6
            },
        ]
    );
    let measured: Vec<(usize, usize)> = heard
        .iter()
        .filter_map(|e| match e {
            Event::Measured { done, total, .. } => Some((*done, *total)),
            _ => None,
        })
        .collect();
    let want: Vec<(usize, usize)> = (1..=n + 6)
        .map(|d| {
            (
                d,
                match d {
                    d if d <= n => n,
                    d if d <= n + 3 => n + 3,
                    _ => n + 6,
                },
            )
        })
        .collect();
    assert_eq!(measured, want);
    // A pair measured again reads the same BRDF: within its noise.
    for (again, first) in [(n, samples[0]), (n + 1, samples[1])] {
        let first_id = steps
            .iter()
            .position(|s| s.step == *first)
            .expect("in the schedule") as i64;
        let (a, b) = (&readings[again], &readings[first_id as usize]);
        assert_eq!(a.step_id, again as i64);
        assert!(
            (a.r_mean - b.r_mean).abs() < 4.0 * (a.r_std + b.r_std) + 1e-3 * b.r_mean,
            "step {again}: {} against {} at step {first_id}",
            a.r_mean,
            b.r_mean
        );
    }
    drop(store);
    let store = RunStore::open(&out).expect("reopens intact");
    assert!(store.integrity(true).expect("checks").is_intact());
    assert_eq!(
        store.meta_value("status").expect("meta").as_deref(),
        Some("complete")
    );
}

/// The readings as the instrument gave them (every column but the clocks and the
/// session), by step.
fn measured(store: &RunStore) -> Vec<String> {
    store
        .readings()
        .expect("readings")
        .into_iter()
        .map(|r| {
            format!(
                "{} {:?} {:?} {:?} {} {} {} {} {} {} {} {} {} {} {}",
                r.step_id,
                r.commanded,
                r.position,
                r.read_pair,
                r.sensitivity,
                r.time_constant,
                r.r_mean,
                r.r_std,
                r.x_mean,
                r.y_mean,
                r.n,
                r.autorange_steps,
                r.lias,
                r.flags,
                r.retries
            )
        })
        .collect()
}

/// The decisions but for when and by which session they were made, and the digest
/// (which covers the readings' clocks).
fn decided(store: &RunStore) -> Vec<(i64, i64, u32, u32, String, u64, String)> {
    store
        .decisions()
        .expect("decisions")
        .into_iter()
        .map(|d| {
            (
                d.id,
                d.first_step,
                d.steps,
                d.points,
                d.method,
                d.readings,
                d.detail,
            )
        })
        .collect()
}

#[test]
fn an_adaptive_run_stopped_and_resumed_ends_as_an_uninterrupted_one() {
    use gonio_acquire::Event;
    let dir = common::scratch();
    let plan = common::plan(PLAN);
    // Uninterrupted.
    let whole = dir.path().join("whole.gonio");
    let (store, prepared) = common::create(&whole, &plan, PLAN, 11);
    let n = prepared.schedule.steps.len();
    let sched = prepared.schedule.steps.clone();
    let (engine, _sim) = common::engine(store, 11, |_| {});
    let engine = engine.with_planner(planner(&sched, Seen::default()));
    let (report, whole) = common::run_session(engine);
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!(report.total, n + 6);

    // Killed before the planner's first batch was committed: the file is as if the
    // schedule had been measured by a run without a planner.
    let out = dir.path().join("stopped.gonio");
    let (store, _) = common::create(&out, &plan, PLAN, 11);
    let (engine, _sim) = common::engine(store, 11, |_| {});
    let (report, store) = common::run_session(engine);
    assert_eq!((report.outcome, report.measured), (Outcome::Complete, n));
    // Stopped just after the first batch was committed: the resume asks the planner
    // at once (nothing is pending), and the stop comes before the batch's first step.
    let (engine, _sim) = common::engine(store, 11, |_| {});
    let stopper = engine.stopper();
    let mut inner = planner(&sched, Seen::default());
    let engine = engine.with_planner(Box::new(move |store: &RunStore| {
        let batch = inner(store);
        stopper.stop();
        batch
    }));
    let (report, store) = common::run_session(engine);
    assert_eq!((report.outcome, report.measured), (Outcome::Interrupted, 0));
    assert_eq!(store.decisions().expect("decisions").len(), 1);
    assert_eq!(store.readings().expect("readings").len(), n);
    // Stopped after the first batch's first reading (the stop may race the engine by
    // one step).
    let (engine, _sim) = common::engine(store, 11, |_| {});
    let engine = engine.with_planner(planner(&sched, Seen::default()));
    let (report, store, _) = run_watched(
        engine,
        listen(move |e| matches!(e, Event::Measured { step_id, .. } if *step_id == n as i64)),
    );
    assert_eq!(report.outcome, Outcome::Interrupted);
    let after_stops = store.readings().expect("readings").len();
    assert!((n + 1..=n + 2).contains(&after_stops), "{after_stops}");
    let (engine, _sim) = common::engine(store, 11, |_| {});
    let engine = engine.with_planner(planner(&sched, Seen::default()));
    let (report, store) = common::run_session(engine);
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!(report.measured, n + 6 - after_stops);
    assert_eq!(store.sessions().expect("sessions").len(), 4);

    assert_eq!(measured(&store), measured(&whole));
    assert_eq!(decided(&store), decided(&whole));
    assert_eq!(decided(&store).len(), 2);
    assert!(store.integrity(true).expect("checks").is_intact());
}

#[test]
fn a_failing_planner_faults_the_session_and_loses_nothing() {
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, prepared) = common::create(&out, &plan, PLAN, 7);
    let n = prepared.schedule.steps.len();
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let engine = engine.with_planner(Box::new(|_: &RunStore| Err("no model converged".into())));
    let (report, store) = common::run_session(engine);
    assert_eq!(
        report.outcome,
        Outcome::Faulted("adaptive planner: no model converged".into())
    );
    assert_eq!((report.measured, report.finished, report.total), (n, n, n));
    let fault = store
        .events()
        .expect("events")
        .into_iter()
        .find(|e| e.kind == "fault")
        .expect("logged");
    assert_eq!(fault.message, "adaptive planner: no model converged");
    drop(store);
    let store = RunStore::open(&out).expect("intact");
    assert!(store.integrity(true).expect("checks").is_intact());
    assert_eq!(store.readings().expect("readings").len(), n);
    assert!(store.decisions().expect("decisions").is_empty());
    assert_eq!(
        store.meta_value("status").expect("meta").as_deref(),
        Some("faulted")
    );
    // A batch without steps is the planner's fault too, and is not appended.
    let mut store = store;
    store.lock().expect("locks");
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let engine = engine.with_planner(Box::new(|_: &RunStore| {
        Ok(Some(gonio_run::Batch {
            decision: gonio_run::Decision {
                method: "none".into(),
                points: 0,
                detail: "{}".into(),
            },
            steps: Vec::new(),
        }))
    }));
    let (report, store) = common::run_session(engine);
    assert!(
        matches!(&report.outcome, Outcome::Faulted(m)
            if m.starts_with("adaptive planner: ") && m.ends_with("cannot append the batch: it has no steps")),
        "{:?}",
        report.outcome
    );
    assert_eq!(report.measured, 0);
    // Resumable: a planner that works takes the run to its end.
    let (engine, _sim) = common::engine(store, 7, |_| {});
    let engine = engine.with_planner(planner(&prepared.schedule.steps, Seen::default()));
    let (report, store) = common::run_session(engine);
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!((report.measured, report.total), (6, n + 6));
    assert_eq!(store.decisions().expect("decisions").len(), 2);
    assert!(store.integrity(true).expect("checks").is_intact());
}

#[test]
fn a_paused_run_on_apt_lines_resumes_and_completes() {
    // The mixed instrument: the sample rotation and tilt on Thorlabs APT controllers,
    // which stop sending status messages after ~50 without the host's server-alive
    // (APT protocol manual, Issue 28, p. 130). A pause sends what is due each turn
    // and leaves the simulated clock alone (the same bytes however long it lasts);
    // the run then completes with no gap over a second on either line. (Ten minutes
    // idle on virtual time: simulator/tests/it/mixed.rs.)
    use gonio_acquire::Event;
    const MIXED_PLAN: &str = r#"
name = "mixed in-plane"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = { from = -60, to = 60, step = 10 }
"#;
    let dir = common::scratch();
    let out = dir.path().join("run.gonio");
    let plan = common::plan(MIXED_PLAN);
    let (store, _) = common::create_on(common::MIXED, &out, &plan, MIXED_PLAN, 5);
    let (engine, sim) = common::engine_on(common::MIXED, store, 5, |_| {});
    let clock = gonio_sim::lock(&sim).clock().clone();
    let paused_at = std::sync::Arc::new(std::sync::Mutex::new((0.0, 0.0)));
    let seen = paused_at.clone();
    let (report, store, heard) = run_watched(engine, move |mut rx, pauser, _| {
        Box::pin(async move {
            let mut heard = Vec::new();
            while let Ok(e) = rx.recv().await {
                match &e {
                    Event::Measured { done: 4, .. } => pauser.pause(),
                    Event::Paused => {
                        let t0 = clock.seconds();
                        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
                        *seen.lock().unwrap() = (t0, clock.seconds());
                        pauser.resume();
                    }
                    Event::Finished { .. } => break,
                    _ => {}
                }
                heard.push(e);
            }
            heard
        })
    });
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!(report.measured, report.total);
    assert!(heard.contains(&Event::Paused) && heard.contains(&Event::Resumed));
    // The simulated clock did not move while the person waited (but for one
    // keep-alive's 6 bytes on the wire, if one fell due as the pause began).
    let (t0, t1) = *paused_at.lock().unwrap();
    assert!(t1 - t0 < 1e-3, "{t0} → {t1}");
    assert_eq!(pause_log(&store), ["pause", "continue"]);
    let end = gonio_sim::lock(&sim).clock().seconds();
    let mut s = gonio_sim::lock(&sim);
    for n in 0..2 {
        let k = s.apt_mut(n).expect("an APT twin").keepalive().clone();
        assert_eq!((k.late, k.withheld), (0, 0), "line {n}: {k:?}");
        assert!(k.longest_gap_until(end) <= 1.0, "line {n}: {k:?}");
        // One every 0.5 s of the session.
        assert!(
            k.acks as f64 >= end / 0.5 - 2.0,
            "line {n}: {k:?} in {end} s"
        );
    }
}
