//! The run engine against every fault the simulator can inject, mid-run: lost,
//! garbled and late replies, a command never answered, a controller that loses power,
//! a stage that stalls, detector overload and reference unlock, and a port that
//! closes and reopens. Each test asserts how the session ends, what the run file
//! holds (one reading per step, its flags and retries, the events), that the readings
//! still give the model's BRDF, and, where the session faults, that the stages are
//! stopped and a second session completes the run.
//!
//! Faults are injected deterministically: either at a physical time taken from a run
//! without faults (the same seed gives the same timeline up to the fault), or from the
//! bench's `at_step` hook, which the engine calls on the step's own thread after the
//! stages arrived and before the detector reads.

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use gonio_acquire::engine::{Engine, EngineConfig, Event, Outcome, SessionReport};
use gonio_brdf::{Brdf, Model};
use gonio_core::radiometry::Aperture;
use gonio_driver::Goniometer;
use gonio_driver::bench::{Bench, BenchError, Setup};
use gonio_plan::StepKind;
use gonio_run::{EventRecord, ReadingRecord, RunStore, StoredStep, flags};
use gonio_sim::SimBench;
use gonio_sim::faults::{PortOutage, PowerLoss, Stall, Window};
use gonio_sim::{Port, SharedSim, SimClock, SimInstrument, SimTransport, lock};

/// The plan of `tests/engine.rs`: dark, incident, then six in-plane sample points with
/// drift references (13 steps).
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

const SEED: u64 = 7;

/// Steps of [`PLAN`].
const STEPS: usize = 13;

/// Step 3 is the first sample point: the detector arm swings from −60° (step 2, a
/// drift reference) to +60°, the only stage that moves.
const SWING: i64 = 3;

/// Controller addresses (`config/sim-example.toml`).
const DETECTOR_ARM: u8 = 2;
const SAMPLE_ROT: u8 = 3;

// ---------------------------------------------------------------------------------
// The rig: an engine on a simulator, with faults injected from the bench hook.

/// Injects faults into the simulator when the engine reaches a step.
type Hook = Box<dyn FnOnce(&mut SimInstrument) + Send>;

/// The simulator's bench, plus hooks fired (once each) at given steps, after the
/// stages arrived and before the detector reads.
struct FaultBench {
    inner: SimBench,
    sim: SharedSim,
    hooks: Vec<(i64, Option<Hook>)>,
}

impl Bench for FaultBench {
    fn set_up(&mut self, setup: Setup) -> Result<(), BenchError> {
        self.inner.set_up(setup)
    }

    fn select_channel(&mut self, channel: &str) -> Result<(), BenchError> {
        self.inner.select_channel(channel)
    }

    fn at_step_since(
        &mut self,
        step_id: i64,
        previous: Option<[f64; 2]>,
        since: std::time::Duration,
    ) {
        self.inner.at_step_since(step_id, previous, since);
        for (at, hook) in &mut self.hooks {
            if *at == step_id
                && let Some(h) = hook.take()
            {
                h(&mut lock(&self.sim));
            }
        }
    }
}

/// A hook at `step`.
fn at(step: i64, f: impl FnOnce(&mut SimInstrument) + Send + 'static) -> (i64, Hook) {
    (step, Box::new(f))
}

type FaultEngine = Engine<SimClock, FaultBench>;

/// A new simulator (powered up, nothing homed) with the test seed.
fn fresh_sim(tweak: impl FnOnce(&mut gonio_sim::SimConfig)) -> SharedSim {
    let mut s = common::sim(SEED);
    tweak(&mut s);
    gonio_sim::instrument(&s).expect("sim")
}

/// An engine for `store` driving `sim` over new lines (as a new process would).
fn engine_on(store: RunStore, sim: &SharedSim, hooks: Vec<(i64, Hook)>) -> FaultEngine {
    let (inst, _) = common::instrument();
    let clock = lock(sim).clock().clone();
    let g = Goniometer::from_transports(
        &inst,
        SimTransport::new(sim.clone(), Port::Motion),
        SimTransport::new(sim.clone(), Port::Detector),
        clock.clone(),
        clock,
    )
    .expect("goniometer");
    let mech = inst.mechanics().expect("mechanics");
    let stored = gonio_acquire::stored(&store).expect("stored");
    let cfg = EngineConfig {
        incident_transmittance: stored.transmittance,
        ..EngineConfig::default()
    };
    let bench = FaultBench {
        inner: SimBench::new(sim.clone(), None),
        sim: sim.clone(),
        hooks: hooks.into_iter().map(|(s, h)| (s, Some(h))).collect(),
    };
    Engine::new(g, bench, store, mech, cfg)
}

/// What one session did: its report, the run file, and what listeners heard.
struct Session {
    report: SessionReport,
    store: RunStore,
    heard: Vec<Event>,
}

fn run_session(engine: FaultEngine) -> Session {
    let mut rx = engine.subscribe();
    let (report, store) = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
        .block_on(engine.run())
        .expect("engine runs");
    let mut heard = Vec::new();
    while let Ok(e) = rx.try_recv() {
        heard.push(e);
    }
    Session {
        report,
        store,
        heard,
    }
}

/// A new run file of [`PLAN`].
fn new_run(name: &str) -> (PathBuf, RunStore) {
    // Kept after the test (the file is reopened by path, as `gonio resume` does).
    let out = tempfile::Builder::new()
        .prefix(&format!("gonio-faults-{name}-"))
        .tempdir()
        .expect("temp dir")
        .keep()
        .join("run.gonio");
    let plan = common::plan(PLAN);
    let (store, prepared) = common::create(&out, &plan, PLAN, SEED);
    assert_eq!(prepared.checked.accepted.len(), 7);
    (out, store)
}

/// The run file reopened from disk, as `gonio resume` does.
fn reopen(path: &Path, store: RunStore) -> RunStore {
    drop(store);
    RunStore::open(path).expect("reopens")
}

/// The readings of a run without faults (same plan, same seed).
fn baseline() -> &'static [ReadingRecord] {
    static BASE: OnceLock<Vec<ReadingRecord>> = OnceLock::new();
    BASE.get_or_init(|| {
        let (_, store) = new_run("baseline");
        let sim = fresh_sim(|_| {});
        let s = run_session(engine_on(store, &sim, Vec::new()));
        assert_eq!(s.report.outcome, Outcome::Complete);
        // The session started at simulator time 0, so reading times are simulator
        // times (what fault windows are written in).
        let now = lock(&sim).clock().seconds();
        assert!((now - s.report.physical_s).abs() < 0.1, "{now}");
        let readings = s.store.readings().expect("readings");
        assert_eq!(readings.len(), STEPS);
        readings
    })
}

// ---------------------------------------------------------------------------------
// What every test checks.

/// Every step done, measured exactly once: one reading each, committed once.
fn assert_each_step_once(store: &RunStore) {
    let steps = store.steps().expect("steps");
    assert_eq!(steps.len(), STEPS);
    for s in &steps {
        assert_eq!(s.state, "done", "step {}", s.id);
        assert_eq!(s.attempts, 1, "step {} committed once", s.id);
    }
    let ids: Vec<i64> = store
        .readings()
        .expect("readings")
        .iter()
        .map(|r| r.step_id)
        .collect();
    let want: Vec<i64> = steps.iter().map(|s| s.id).collect();
    assert_eq!(ids, want, "one reading per step");
}

/// Every sample reading of the run, reduced with its dark and incident readings,
/// gives the model's BRDF (as in `tests/engine.rs`); every reading but those of
/// `flagged` is clean, and the stages were read back where commanded.
fn assert_agrees_with_model(store: &RunStore, flagged: &[i64]) {
    let steps = store.steps().expect("steps");
    let readings = store.readings().expect("readings");
    let of = |id: i64| readings.iter().find(|r| r.step_id == id).expect("read");
    let one = |k: StepKind| {
        let v: Vec<&StoredStep> = steps.iter().filter(|s| s.step.kind == k).collect();
        assert_eq!(v.len(), 1);
        of(v[0].id)
    };
    let (dark, incident) = (one(StepKind::Dark), one(StepKind::Incident));
    assert!(dark.r_mean < 1e-6, "dark {}", dark.r_mean);
    assert!(
        (incident.r_mean - 4.5e-3).abs() < 1e-5,
        "incident {}",
        incident.r_mean
    );
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
    let s_in = (incident.r_mean - dark.r_mean) / 1e-3;
    let mut f = [0.0];
    for s in &steps {
        let r = of(s.id);
        if !flagged.contains(&s.id) {
            assert_eq!(r.flags, 0, "step {} is clean", s.id);
        }
        if let Some(cmd) = r.commanded {
            for (p, c) in r.position.iter().zip(cmd) {
                assert!((p - c).abs() < 0.01, "step {}: at {p}, not {c}", s.id);
            }
        }
        if s.step.kind != StepKind::Sample || flagged.contains(&s.id) {
            continue;
        }
        let pair = s.step.pair.expect("pair").to_dirs();
        model.eval(pair.wi, pair.wo, &mut f);
        let measured = (r.r_mean - dark.r_mean) / s_in / (omega * pair.wo.z);
        assert!(
            (measured - f[0]).abs() < 2e-3 * f[0] + 3.0 * r.r_std / s_in / (omega * pair.wo.z),
            "step {}: measured {measured}, model {}",
            s.id,
            f[0]
        );
    }
}

/// The stored events of `kind`.
fn events_of<'a>(events: &'a [EventRecord], kind: &str) -> Vec<&'a EventRecord> {
    events.iter().filter(|e| e.kind == kind).collect()
}

/// No stage moves any more: every controller at rest a second from now, and every
/// stage where it will still be half a minute later.
fn assert_stopped(sim: &SharedSim) {
    let mut s = lock(sim);
    let t = s.clock().seconds() + 1.0;
    for a in 1..=4 {
        let c = s.controller_mut(a).expect("controller");
        let st = c.state(t);
        assert!(!st.is_moving() && !st.is_homing(), "controller {a}: {st}");
    }
    assert_eq!(s.stage_angles(t), s.stage_angles(t + 30.0));
}

/// The readings `before` (as an earlier session left them) are in the file unchanged:
/// committed readings are never touched again.
fn assert_kept(before: &[ReadingRecord], store: &RunStore) {
    let now = store.readings().expect("readings");
    for r in before {
        let again = now.iter().find(|n| n.step_id == r.step_id).expect("kept");
        assert_eq!(again, r, "step {} kept as committed", r.step_id);
    }
}

/// A session that ended on a persistent fault: `faulted` for `cause`, steps before
/// `at` committed and `at` onwards pending, a `fault` event at step `at`, and the run
/// file's status `faulted`. Returns the readings committed.
fn assert_faulted_at(s: &Session, at: i64, cause: &str) -> Vec<ReadingRecord> {
    let Outcome::Faulted(why) = &s.report.outcome else {
        panic!("expected a faulted session, got {:?}", s.report.outcome);
    };
    assert!(why.contains(cause), "{why}");
    assert_eq!(s.report.measured, at as usize);
    assert_eq!(s.report.finished, at as usize);
    let steps = s.store.steps().expect("steps");
    for st in &steps {
        let want = if st.id < at { "done" } else { "pending" };
        assert_eq!(st.state, want, "step {}", st.id);
    }
    let events = s.store.events().expect("events");
    assert!(
        events_of(&events, "fault")
            .iter()
            .any(|e| e.step_id == Some(at) && !e.message.is_empty()),
        "{events:#?}"
    );
    let stop = events_of(&events, "stop");
    assert!(stop.last().expect("stop").message.contains("resumable"));
    assert_eq!(
        s.store.meta_value("status").expect("meta").as_deref(),
        Some("faulted")
    );
    let before = s.store.readings().expect("readings");
    assert_eq!(before.len(), at as usize);
    before
}

/// A second session, on `sim`, with the cause removed: it completes the run, leaves
/// the first session's readings as they were, and measures each step once.
fn assert_resumes(path: &Path, s: Session, sim: &SharedSim) -> Session {
    let before = s.store.readings().expect("readings");
    let store = reopen(path, s.store);
    let second = run_session(engine_on(store, sim, Vec::new()));
    assert_eq!(second.report.outcome, Outcome::Complete);
    assert_eq!(second.report.measured, STEPS - before.len());
    assert!(matches!(
        second.heard.first(),
        Some(Event::Started { resumed: true, done, total: STEPS }) if *done == before.len()
    ));
    assert_kept(&before, &second.store);
    assert_each_step_once(&second.store);
    assert_agrees_with_model(&second.store, &[]);
    let outcomes: Vec<Option<String>> = second
        .store
        .sessions()
        .expect("sessions")
        .into_iter()
        .map(|s| s.outcome)
        .collect();
    assert_eq!(
        outcomes,
        [Some("faulted".to_string()), Some("complete".to_string())]
    );
    second
}

/// Retries were made and logged: readings carry them, and each reading with retries
/// has its `retry` event saying how many.
fn assert_retries_logged(store: &RunStore) -> u64 {
    let readings = store.readings().expect("readings");
    let events = store.events().expect("events");
    let retry = events_of(&events, "retry");
    let total: u64 = readings.iter().map(|r| r.retries).sum();
    assert!(total > 0, "no retries recorded");
    for r in readings.iter().filter(|r| r.retries > 0) {
        let e = retry
            .iter()
            .find(|e| e.step_id == Some(r.step_id))
            .expect("a retry event per reading with retries");
        assert_eq!(e.message, format!("{} exchanges retried", r.retries));
    }
    assert_eq!(
        retry.len(),
        readings.iter().filter(|r| r.retries > 0).count()
    );
    total
}

// ---------------------------------------------------------------------------------
// Lost, garbled and late replies.

#[test]
fn lost_replies_are_retried_and_the_run_completes() {
    let (_, store) = new_run("drop");
    let sim = fresh_sim(|_| {});
    // From the first step on (after homing, whose `OR` must not be re-sent).
    let hooks = vec![at(0, |s| s.faults_mut().drop_reply = 0.05)];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(s.report.outcome, Outcome::Complete);
    assert_eq!(s.report.measured, STEPS);
    let dropped = lock(&sim).stats().dropped;
    assert!(dropped >= 20, "the fault fired: {dropped}");
    let retried = assert_retries_logged(&s.store);
    // Every lost reply cost exactly one retry: the query asked again, the command
    // whose `TE` answer was lost sent again, or the reading whose flags were lost
    // taken again.
    assert_eq!(retried, dropped);
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[]);
}

#[test]
fn garbled_replies_are_retried_and_the_run_completes() {
    let (_, store) = new_run("corrupt");
    let sim = fresh_sim(|_| {});
    let hooks = vec![at(0, |s| s.faults_mut().corrupt_reply = 0.05)];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(s.report.outcome, Outcome::Complete);
    let corrupted = lock(&sim).stats().corrupted;
    assert!(corrupted >= 20, "the fault fired: {corrupted}");
    // Each garbled reply refused and asked again, once.
    assert_eq!(assert_retries_logged(&s.store), corrupted);
    assert_each_step_once(&s.store);
    // No garbled number was taken for a value.
    assert_agrees_with_model(&s.store, &[]);
}

#[test]
fn late_replies_are_retried_and_the_run_completes() {
    let (_, store) = new_run("late");
    let sim = fresh_sim(|_| {});
    // 150 ms: later than the SMC100 chain's 100 ms timeout (each query is asked again
    // and the first answer arrives meanwhile), within the SR830's 1 s.
    let hooks = vec![at(0, |s| s.faults_mut().reply_delay_s = 0.15)];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(s.report.outcome, Outcome::Complete);
    let retried = assert_retries_logged(&s.store);
    // Every moving step retried its motion queries.
    let readings = s.store.readings().expect("readings");
    for r in readings.iter().filter(|r| r.commanded.is_some()) {
        assert!(r.retries > 0, "step {}", r.step_id);
    }
    assert!(retried > 100, "{retried}");
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[]);
}

#[test]
fn replies_later_than_every_retry_fault_the_session_which_resumes() {
    let (path, store) = new_run("later");
    let sim = fresh_sim(|_| {});
    // From step 4's reading on, every reply comes 5 s late: beyond both drivers'
    // timeouts and retries, for good.
    let hooks = vec![at(4, |s| s.faults_mut().reply_delay_s = 5.0)];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_faulted_at(&s, 4, "no reply");
    // The reading failed first (a recoverable fault: measured again), then the move.
    let faults: Vec<(bool, &str)> = s
        .heard
        .iter()
        .filter_map(|e| match e {
            Event::Fault {
                step_id: Some(4),
                message,
                recovering,
            } => Some((*recovering, message.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(faults.len(), 2, "{faults:?}");
    assert!(faults[0].0 && faults[0].1.contains("SR830"), "{faults:?}");
    assert!(!faults[1].0 && faults[1].1.contains("axis"), "{faults:?}");
    assert_stopped(&sim);
    // The line is fixed; the same instrument (still homed) finishes the run.
    lock(&sim).faults_mut().reply_delay_s = 0.0;
    let second = assert_resumes(&path, s, &sim);
    assert!(
        !second
            .heard
            .iter()
            .any(|e| matches!(e, Event::Homed { .. })),
        "nothing lost its reference"
    );
}

// ---------------------------------------------------------------------------------
// A command never answered.

#[test]
fn a_status_query_never_answered_faults_the_session_mid_move_which_resumes() {
    let (path, store) = new_run("silent-ts");
    let sim = fresh_sim(|_| {});
    // After step 1, the detector arm's controller stops answering `TS`: step 2's
    // move (detector arm 90° → −60°, 7.5 s) starts, and its first status poll fails.
    let hooks = vec![at(1, |s| s.faults_mut().silent.push("2TS".into()))];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_faulted_at(&s, 2, "axis detector");
    // Stopped where the poll failed, far from the −60° it was sent to.
    assert_stopped(&sim);
    let t = lock(&sim).clock().seconds();
    let arm = lock(&sim).stage_angles(t)[1];
    assert!(arm > 0.0 && arm < 90.0, "detector arm at {arm}");
    lock(&sim).faults_mut().silent.clear();
    assert_resumes(&path, s, &sim);
}

#[test]
fn a_detector_query_never_answered_is_measured_again_then_faults() {
    let (path, store) = new_run("silent-snap");
    let sim = fresh_sim(|_| {});
    let hooks = vec![at(5, |s| s.faults_mut().silent.push("SNAP? 1,2".into()))];
    let s = run_session(engine_on(store, &sim, hooks));
    // Each attempt fails after the driver's own retries; the engine measures the step
    // again up to its `max_attempts` (3), then stops.
    assert_faulted_at(&s, 5, "failed 3 times");
    let events = s.store.events().expect("events");
    let faults: Vec<_> = events_of(&events, "fault")
        .into_iter()
        .filter(|e| e.step_id == Some(5))
        .collect();
    assert_eq!(faults.len(), 3, "{faults:#?}");
    assert!(faults.iter().all(|e| e.message.contains("SNAP?")));
    assert_stopped(&sim);
    // Resumed on another day: a new simulator, homed again at start-up.
    let second = assert_resumes(&path, s, &fresh_sim(|_| {}));
    assert!(
        second
            .heard
            .iter()
            .any(|e| matches!(e, Event::Homed { axes } if axes.len() == 4))
    );
}

// ---------------------------------------------------------------------------------
// Power loss.

/// A power loss of controller `address` two seconds into step 3's move: the engine
/// re-homes and measures the step again; nothing is measured twice.
fn power_loss_mid_move(name: &str, address: u8, axis: &str) {
    let (_, store) = new_run(name);
    let at_s = baseline()[2].physical_s + 2.0;
    assert!(baseline()[3].physical_s - at_s > 4.0, "still moving then");
    let sim = fresh_sim(|c| c.faults.power_loss.push(PowerLoss { address, at_s }));
    let s = run_session(engine_on(store, &sim, Vec::new()));
    assert_eq!(lock(&sim).stats().power_losses, 1);
    assert_eq!(
        s.report.outcome,
        Outcome::Complete,
        "{:#?}",
        s.store.events()
    );
    let events = s.store.events().expect("events");
    let fault = events_of(&events, "fault");
    assert!(
        fault
            .iter()
            .any(|e| e.step_id == Some(SWING) && e.message.contains("lost power")),
        "{events:#?}"
    );
    let home = events_of(&events, "home");
    assert_eq!(home.len(), 2, "start-up, then the recovery: {home:#?}");
    assert_eq!(home[1].step_id, Some(SWING));
    // Only the controller that lost power, whichever was being talked to.
    assert_eq!(
        home[1].message,
        format!("re-homed {axis}; measuring the step again")
    );
    assert!(s.heard.iter().any(|e| matches!(
        e,
        Event::Fault {
            step_id: Some(SWING),
            recovering: true,
            ..
        }
    )));
    assert!(
        s.heard
            .iter()
            .any(|e| matches!(e, Event::Homed { axes } if axes == &[axis]))
    );
    // Step 3 was measured after the recovery, once.
    let r3 = s
        .store
        .readings()
        .expect("readings")
        .into_iter()
        .find(|r| r.step_id == SWING)
        .expect("step 3");
    assert!(r3.physical_s > at_s + 3.0, "after the reboot and homing");
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[]);
}

#[test]
fn power_loss_of_the_moving_stage_is_rehomed_and_the_step_measured_again() {
    power_loss_mid_move("power-moving", DETECTOR_ARM, "detector");
}

#[test]
fn power_loss_of_a_stage_at_rest_is_rehomed_and_the_step_measured_again() {
    // The sample rotation stands still at 90° while the detector arm swings; its NUL
    // byte arrives on the shared line in answer to the detector arm's poll.
    power_loss_mid_move("power-idle", SAMPLE_ROT, "sample_rot");
}

// ---------------------------------------------------------------------------------
// A stalled stage.

#[test]
fn a_stalled_stage_faults_the_session_with_every_stage_stopped() {
    let (path, store) = new_run("stall");
    let sim = fresh_sim(|_| {});
    // Armed once the detector arm is at −60° for step 2: it sticks at +30° on its way
    // to +60° for step 3 and the controller disables the motor (following error).
    let stall = Stall {
        address: DETECTOR_ARM,
        at: 30.0,
    };
    let hooks = vec![at(2, move |s| s.faults_mut().stall.push(stall))];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_faulted_at(&s, SWING, "DISABLE");
    assert_stopped(&sim);
    {
        let mut g = lock(&sim);
        let t = g.clock().seconds();
        let arm = g.stage_angles(t)[1];
        assert!((arm - 30.0).abs() < 1e-9, "stuck at {arm}");
        let st = g.controller_mut(DETECTOR_ARM).expect("arm").state(t);
        assert!(st.is_disabled(), "{st}");
        // Fixed: the stage runs freely again.
        g.faults_mut().stall.clear();
        g.controller_mut(DETECTOR_ARM).expect("arm").stall_at(None);
    }
    // Resumed on the same instrument: the disabled controller is enabled again (its
    // reference survives), the others are left alone, and the step is measured.
    let second = assert_resumes(&path, s, &sim);
    let homed: Vec<&Vec<String>> = second
        .heard
        .iter()
        .filter_map(|e| match e {
            Event::Homed { axes } => Some(axes),
            _ => None,
        })
        .collect();
    assert_eq!(homed, [&vec!["detector".to_string()]]);
}

// ---------------------------------------------------------------------------------
// Detector overload and reference unlock.

/// A fault window opened at step `k`'s reading and closed at step `k + 1`'s.
fn window_over_step(
    k: i64,
    open: fn(&mut SimInstrument, Window),
    close: fn(&mut SimInstrument, f64),
) -> Vec<(i64, Hook)> {
    vec![
        at(k, move |s| {
            let t = s.clock().seconds();
            open(
                s,
                Window {
                    from_s: t,
                    to_s: f64::MAX,
                },
            );
        }),
        at(k + 1, move |s| {
            let t = s.clock().seconds();
            close(s, t);
        }),
    ]
}

/// The `flagged` events of the run.
fn flagged_events(store: &RunStore) -> Vec<EventRecord> {
    events_of(&store.events().expect("events"), "flagged")
        .into_iter()
        .cloned()
        .collect()
}

#[test]
fn an_overload_outlasting_the_rereads_is_stored_flagged() {
    let (_, store) = new_run("overload");
    let sim = fresh_sim(|_| {});
    let k = 4;
    let hooks = window_over_step(
        k,
        |s, w| s.faults_mut().overload.push(w),
        |s, t| s.faults_mut().overload[0].to_s = t,
    );
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(s.report.outcome, Outcome::Complete);
    // Autoranging climbed to 1 V and could not clear it; the engine read twice more.
    let flagged = flagged_events(&s.store);
    assert_eq!(flagged.len(), 2, "{flagged:#?}");
    assert!(flagged.iter().all(|e| e.step_id == Some(k)));
    let readings = s.store.readings().expect("readings");
    let r = &readings[k as usize];
    assert_eq!(r.flags & flags::INPUT_OVERLOAD, flags::INPUT_OVERLOAD);
    assert_eq!(r.sensitivity, 26, "1 V full scale");
    assert!(s.heard.iter().any(|e| matches!(
        e,
        Event::Measured { step_id, flags: f, .. } if *step_id == k && f & flags::INPUT_OVERLOAD != 0
    )));
    // The next step autoranged back down and reads clean; so does everything else.
    assert_eq!(readings[k as usize + 1].flags, 0);
    assert!(readings[k as usize + 1].sensitivity < 26);
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[k]);
    // Even the flagged reading is the right value (an input overload does not change
    // the outputs here): stored, not thrown away, for the reduction to judge.
    let b = &baseline()[k as usize];
    assert!(
        (r.r_mean - b.r_mean).abs() < 0.01 * b.r_mean,
        "{} vs {}",
        r.r_mean,
        b.r_mean
    );
}

#[test]
fn an_unlock_outlasting_the_rereads_is_stored_flagged() {
    let (_, store) = new_run("unlock");
    let sim = fresh_sim(|_| {});
    let k = 7;
    let hooks = window_over_step(
        k,
        |s, w| s.faults_mut().unlock.push(w),
        |s, t| s.faults_mut().unlock[0].to_s = t,
    );
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(s.report.outcome, Outcome::Complete);
    let flagged = flagged_events(&s.store);
    assert_eq!(flagged.len(), 2, "{flagged:#?}");
    assert!(flagged.iter().all(|e| e.step_id == Some(k)));
    let readings = s.store.readings().expect("readings");
    let r = &readings[k as usize];
    assert_eq!(r.flags & flags::UNLOCK, flags::UNLOCK);
    // Unlocked, nothing is demodulated: the outputs decayed to noise.
    assert!(
        r.r_mean < 0.05 * baseline()[k as usize].r_mean,
        "{}",
        r.r_mean
    );
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[k]);
}

#[test]
fn a_brief_unlock_is_read_again_and_stored_clean() {
    let (_, store) = new_run("unlock-brief");
    let sim = fresh_sim(|_| {});
    let k = 5;
    // Unlocked for the first 2.8 s of step 5's reading, which waits 1.6 s for the
    // filters and then samples for 1.35 s: that reading is flagged; the reference is
    // back just before the second, whose filters start from nothing.
    let hooks = vec![at(k, |s| {
        let t = s.clock().seconds();
        s.faults_mut().unlock.push(Window {
            from_s: t,
            to_s: t + 2.8,
        });
    })];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(s.report.outcome, Outcome::Complete);
    let flagged = flagged_events(&s.store);
    assert_eq!(flagged.len(), 1, "{flagged:#?}");
    assert_eq!(flagged[0].step_id, Some(k));
    assert!(flagged[0].message.contains("unlock"), "{:?}", flagged[0]);
    // The re-read is clean, and settled: its samples scatter as the noise does, not
    // along the filters' recovery, and agree with the model.
    let r = &s.store.readings().expect("readings")[k as usize];
    let b = &baseline()[k as usize];
    assert_eq!(r.flags, 0);
    assert!(
        r.r_std < 3.0 * b.r_std,
        "r_std {} vs {} without the fault",
        r.r_std,
        b.r_std
    );
    assert!(
        (r.r_mean - b.r_mean).abs() < 1e-3 * b.r_mean,
        "{} vs {}",
        r.r_mean,
        b.r_mean
    );
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[]);
}

// ---------------------------------------------------------------------------------
// Ports that close and reopen.

#[test]
fn ports_that_close_and_reopen_are_reconnected_and_the_run_completes() {
    let (_, store) = new_run("outage");
    let sim = fresh_sim(|_| {});
    // Each port gone for 1.5 s, from 2 s into a step's reading (which takes 3 s):
    // the motion line during step 4's, so that step 5's first command finds it closed
    // (the chain reopens it within 5 × 0.5 s); the detector line during step 7's
    // samples (the SR830 reopens it within 3 × 1 s and starts the reading again).
    let outage = |port: Port| {
        move |s: &mut SimInstrument| {
            let t = s.clock().seconds();
            s.faults_mut().outage.push(PortOutage {
                port,
                window: Window {
                    from_s: t + 2.0,
                    to_s: t + 3.5,
                },
            });
        }
    };
    let hooks = vec![at(4, outage(Port::Motion)), at(7, outage(Port::Detector))];
    let s = run_session(engine_on(store, &sim, hooks));
    assert_eq!(
        s.report.outcome,
        Outcome::Complete,
        "{:#?}",
        s.store.events()
    );
    assert_eq!(s.report.measured, STEPS);
    assert!(
        !s.heard.iter().any(|e| matches!(e, Event::Fault { .. })),
        "the drivers recovered by themselves"
    );
    let readings = s.store.readings().expect("readings");
    let base = baseline();
    // Up to step 4 as without faults, to the last bit; then each outage costs the
    // waits for the port.
    for k in 0..=4 {
        assert_eq!(readings[k].r_mean, base[k].r_mean, "step {k}");
        assert_eq!(readings[k].physical_s, base[k].physical_s, "step {k}");
    }
    let late = |k: usize| readings[k].physical_s - base[k].physical_s;
    assert!(late(5) > 0.9, "two reconnection waits: {}", late(5));
    assert!(
        (late(6) - late(5)).abs() < 0.1,
        "{} then {}",
        late(5),
        late(6)
    );
    // Two 1 s reconnection waits, then the filters settle again and the reading
    // starts over.
    assert!(late(7) - late(6) > 3.0, "{} then {}", late(6), late(7));
    assert_each_step_once(&s.store);
    assert_agrees_with_model(&s.store, &[]);
}

#[test]
fn a_port_gone_for_good_faults_the_session_which_resumes() {
    let (path, store) = new_run("outage-long");
    let sim = fresh_sim(|_| {});
    // The motion line closes after step 8's move and stays closed for 10 minutes,
    // beyond the chain's reconnection budget.
    let hooks = vec![at(8, |s| {
        let t = s.clock().seconds();
        s.faults_mut().outage.push(PortOutage {
            port: Port::Motion,
            window: Window {
                from_s: t,
                to_s: t + 600.0,
            },
        });
    })];
    let s = run_session(engine_on(store, &sim, hooks));
    // Step 8's reading is committed (the detector line is fine); step 9's move cannot
    // start.
    assert_faulted_at(&s, 9, "axis");
    // The port is back later; the same instrument finishes the run.
    lock(&sim).faults_mut().outage.clear();
    assert_resumes(&path, s, &sim);
}
