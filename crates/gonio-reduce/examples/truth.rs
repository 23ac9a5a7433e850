//! The investigation behind the uncertainty budget: a simulated run of a known
//! sample, reduced, against the sample's own BRDF, with the simulator's noise and
//! effects switched on and off one at a time.
//!
//! `cargo run -p gonio-reduce --profile ci --example truth -- PLAN.toml paint|ct|MODEL.toml SEED [quiet] [integrate] [transient] [buffer] [budget] [dump] [percentiles]`
//!
//! `dump` prints each reading: R, r_std, n, time constant, flags and the instrument
//! time since the one before.
//!
//! `budget` prints where the instrument's time went: motion and reading per step
//! (the engine's `step timing` events) and the lines sent on each line, by command
//! (the driver's wire log).
//!
//! `buffer` lets the lock-in read through its data buffer where its estimate says
//! that is faster (`buffer = true` added to `config/instrument-sim.toml`'s
//! `[detector.lockin]`).

#[path = "../tests/it/truth/mod.rs"]
mod truth;

use gonio_reduce::{Calibration, Drift, Options, Reduction, reduce};
use gonio_run::RunStore;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let plan_path = args
        .get(1)
        .cloned()
        .unwrap_or("config/plan-hemisphere.toml".into());
    // `paint`, `ct`, or a model file's path.
    let file_text;
    let sample = match args.get(2).map(String::as_str) {
        Some("ct") => Some(truth::COOK_TORRANCE),
        Some(p) if p.ends_with(".toml") => {
            file_text = std::fs::read_to_string(p).expect("model file");
            Some(file_text.as_str())
        }
        _ => None,
    };
    let seed: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(11);
    let quiet = args.iter().any(|a| a == "quiet");
    let integrate = args.iter().any(|a| a == "integrate");
    let transient = args.iter().any(|a| a == "transient");
    let plan = std::fs::read_to_string(truth::root().join(&plan_path)).expect("plan");
    let buffer = args.iter().any(|a| a == "buffer");
    let budget = args
        .iter()
        .any(|a| a == "budget")
        .then(budget::Budget::install);
    let tweak = |s: &mut gonio_sim::SimConfig| {
        if quiet {
            s.lockin.amplifier_noise = 0.0;
            s.lockin.shot_noise = 0.0;
        }
        s.optics.integrate_aperture = integrate;
        if transient {
            s.lockin.point_start = gonio_sim::lockin::PointStart::Previous;
        }
    };
    let (store, model) = if buffer {
        truth::measure_buffered("example", &plan, sample, seed, tweak)
    } else {
        truth::measure("example", &plan, sample, seed, tweak)
    };
    let readings = store.readings().expect("readings");
    if args.iter().any(|a| a == "compare") {
        let (plain, _) = truth::measure("example2", &plan, sample, seed, tweak);
        let other = plain.readings().expect("readings");
        let mut prev = (0.0, 0.0);
        for (a, b) in readings.iter().zip(other.iter()) {
            let rel = a.r_mean / b.r_mean - 1.0;
            let (da, db) = (a.physical_s - prev.0, b.physical_s - prev.1);
            prev = (a.physical_s, b.physical_s);
            if gonio_run::flags::buffer_interval_s(a.flags).is_some() {
                println!(
                    "buffered step {}: {:.3e} V {:.2} s (n {}, T {}) vs {:.2} s (n {}, T {})",
                    a.step_id, a.r_mean, da, a.n, a.time_constant_s, db, b.n, b.time_constant_s
                );
            }
            if rel.abs() > 1e-3 {
                println!(
                    "step {} {}: {:.6e} (n {}, flags {:#x}, sens {}) vs {:.6e} (n {}, sens {}) {rel:+.3e}",
                    a.step_id,
                    b.step_id,
                    a.r_mean,
                    a.n,
                    a.flags,
                    a.sensitivity,
                    b.r_mean,
                    b.n,
                    b.sensitivity
                );
            }
        }
    }
    let buffered = readings
        .iter()
        .filter(|r| gonio_run::flags::buffer_interval_s(r.flags).is_some())
        .count();
    let physical = readings.iter().map(|r| r.physical_s).fold(0.0, f64::max);
    println!(
        "instrument time {physical:.1} s; {buffered} of {} readings through the buffer",
        readings.len()
    );
    if let Some(b) = &budget {
        b.print(&readings);
    }
    if args.iter().any(|a| a == "dump") {
        let mut prev = 0.0;
        for r in &readings {
            println!(
                "reading {} R {:.4e} s {:.4e} n {} T {} flags {:#x} took {:.3} s",
                r.step_id,
                r.r_mean,
                r.r_std,
                r.n,
                r.time_constant_s,
                r.flags,
                r.physical_s - prev
            );
            prev = r.physical_s;
        }
    }
    if args.iter().any(|a| a == "cal") {
        print_calibration_readings(&store);
    }
    for (name, opts) in [
        ("auto", Options::default()),
        (
            "standard",
            Options {
                calibration: Calibration::Standard,
                ..Options::default()
            },
        ),
        (
            "no drift",
            Options {
                drift: Drift::None,
                ..Options::default()
            },
        ),
    ] {
        let Ok(red) = reduce(&store, &opts) else {
            println!("{name}: does not reduce");
            continue;
        };
        let r = truth::residuals(&red, &model);
        print_summary(name, &red, &model, &r);
        if name == "auto" {
            print_sigma_spread(&red, &store);
        }
        if args.iter().any(|a| a == "detail") && name == "auto" {
            print_detail(&red, &r);
        }
    }
}

/// The calibration, dark and drift readings, one line each (`cal`).
fn print_calibration_readings(store: &RunStore) {
    let steps = store.steps().expect("steps");
    for r in store.readings().expect("readings") {
        let kind = steps
            .iter()
            .find(|s| s.id == r.step_id)
            .map(|s| s.step.kind);
        if !matches!(kind, Some(gonio_plan::StepKind::Sample)) {
            println!(
                "{kind:?} t {:.1} x {:.6e} y {:+.3e} r_std {:.3e} sens {:.0e} flags {} autorange {} retries {} tc {} n {}",
                r.physical_s,
                r.x_mean,
                r.y_mean,
                r.r_std,
                r.sensitivity_v,
                r.flags,
                r.autorange_steps,
                r.retries,
                r.time_constant_s,
                r.n
            );
        }
    }
}

/// One reduction against the truth: χ², the mean z and relative error, the
/// calibration and drift, the dark and incident readings, the budget's terms, and
/// χ² with the common scale removed.
fn print_summary(name: &str, red: &Reduction, model: &gonio_brdf::Model, r: &[(f64, f64)]) {
    let n = r.len() as f64;
    let mean_z = r.iter().map(|x| x.0).sum::<f64>() / n;
    let rel_sd = (r
        .iter()
        .map(|x| (x.1 - truth::mean_rel(r)).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let c = &red.report.channels[0];
    println!(
        "{name}: n {} chi2/n {:.3} correlated {:.3} mean z {:+.3} mean rel {:+.3e} sd rel {:.3e} | cal rel sigma {:.3e} ({} readings) drift refs {} max|g-1| {:.2e}",
        r.len(),
        truth::chi2(r),
        truth::chi2_correlated(red, model),
        mean_z,
        truth::mean_rel(r),
        rel_sd,
        c.incident_rel_sigma,
        c.calibration_readings,
        c.drift_readings,
        c.drift_max
    );
    println!(
        "   dark ({:+.3e}, {:+.3e}) V; C {:.8e} V (relative to 4.5 V, the simulator's: {:+.3e})",
        c.dark_v[0],
        c.dark_v[1],
        c.incident_v,
        c.incident_v / 4.5 - 1.0
    );
    for t in &c.budget {
        println!(
            "   {:<11} {:.2e} / {:.2e} {}",
            t.term, t.rel_median, t.rel_max, t.source
        );
    }
    // With a common scale removed: the scatter alone.
    let k = truth::mean_rel(r);
    let mut chi_s = 0.0;
    for (s, (z, e)) in red.samples.samples.iter().zip(r) {
        let sig = s.sigma.as_ref().expect("sigma")[0];
        let truth_v = s.value[0] / (1.0 + e);
        let zz = (s.value[0] - truth_v * (1.0 + k)) / sig;
        let _ = z;
        chi_s += zz * zz;
    }
    if let Some(t) = gonio_reduce::agreement::truth(red, model) {
        for a in gonio_reduce::agreement::agreements(red, &t) {
            let top: Vec<String> = a
                .shifts
                .iter()
                .take(3)
                .map(|(s, x)| format!("{} {x:+.2}", red.covariance.sources[*s].label))
                .collect();
            println!(
                "   full covariance: chi2/n {:.3} (plain {:.3}), mean z {:+.3} (shared fraction {:.3}); shifts: {}",
                a.chi2_full,
                a.chi2_plain,
                a.mean_z,
                a.shared_fraction,
                top.join(", ")
            );
        }
    }
    println!(
        "   chi2/n with the common scale removed {:.3}; largest position error {:.2e}°",
        chi_s / n,
        red.report.max_position_error_deg
    );
}

/// How large σ is relative to f: its median and upper percentiles, the share
/// within 1.1e-4, and the run's physical time (for `auto`).
fn print_sigma_spread(red: &Reduction, store: &RunStore) {
    let mut rel: Vec<f64> = red
        .samples
        .samples
        .iter()
        .map(|s| s.sigma.as_ref().expect("sigma")[0] / s.value[0])
        .collect();
    rel.sort_by(f64::total_cmp);
    let q = |p: f64| rel[((rel.len() - 1) as f64 * p).round() as usize];
    let within = rel.iter().filter(|x| **x <= 1.1e-4).count() as f64 / rel.len() as f64;
    let physical = store
        .readings()
        .expect("readings")
        .iter()
        .map(|r| r.physical_s)
        .fold(0.0, f64::max);
    println!(
        "   sigma/f median {:.3e} p90 {:.3e} p95 {:.3e}; {:.1} % within 1.1e-4; physical time {physical:.1} s",
        q(0.5),
        q(0.9),
        q(0.95),
        100.0 * within
    );
}

/// The samples by size of f in eighths, with χ² and σ in each, then the twelve
/// largest |z| (`detail`).
fn print_detail(red: &Reduction, r: &[(f64, f64)]) {
    let mut v: Vec<(f64, f64, f64, String)> = red
        .samples
        .samples
        .iter()
        .zip(r)
        .map(|(s, (z, e))| {
            let sig = s.sigma.as_ref().expect("sigma")[0];
            (
                s.value[0],
                *z,
                sig / s.value[0],
                format!("{:?} {e:+.2e}", s.pair),
            )
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    for chunk in v.chunks(v.len() / 8 + 1) {
        let m = chunk.len() as f64;
        println!(
            "   f {:.3e}..{:.3e}: chi2/n {:.2} mean z {:+.2} rel sigma {:.2e}",
            chunk[0].0,
            chunk[chunk.len() - 1].0,
            chunk.iter().map(|x| x.1 * x.1).sum::<f64>() / m,
            chunk.iter().map(|x| x.1).sum::<f64>() / m,
            chunk.iter().map(|x| x.2).sum::<f64>() / m,
        );
    }
    v.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    for x in v.iter().take(12) {
        println!(
            "   z {:+.2} f {:.3e} rel sigma {:.2e} {}",
            x.1, x.0, x.2, x.3
        );
    }
}

/// Where the instrument's time goes, from the engine's and the driver's tracing
/// events: a subscriber of its own, so the example needs no subscriber crate.
mod budget {
    use std::collections::BTreeMap;
    use std::fmt::Debug;
    use std::sync::{Arc, Mutex};

    use tracing::field::{Field, Visit};
    use tracing::span::{Attributes, Id, Record};
    use tracing::{Event, Metadata, Subscriber};

    #[derive(Default)]
    struct Tally {
        steps: usize,
        moving_s: f64,
        reading_s: f64,
        rereads: u64,
        /// Lines sent, by line (`motion`: an SMC100 address first; else `detector`)
        /// and command.
        sent: BTreeMap<(&'static str, String), usize>,
    }

    /// The tally, shared with the subscriber.
    pub struct Budget(Arc<Mutex<Tally>>);

    struct Counter(Arc<Mutex<Tally>>);

    #[derive(Default)]
    struct Fields {
        moving_s: Option<f64>,
        reading_s: Option<f64>,
        rereads: u64,
        dir: Option<String>,
        line: Option<String>,
    }

    impl Visit for Fields {
        fn record_f64(&mut self, field: &Field, value: f64) {
            match field.name() {
                "moving_s" => self.moving_s = Some(value),
                "reading_s" => self.reading_s = Some(value),
                _ => {}
            }
        }
        fn record_u64(&mut self, field: &Field, value: u64) {
            if field.name() == "rereads" {
                self.rereads = value;
            }
        }
        fn record_i64(&mut self, field: &Field, value: i64) {
            self.record_u64(field, value.max(0) as u64);
        }
        fn record_str(&mut self, field: &Field, value: &str) {
            self.record_debug(field, &format_args!("{value}"));
        }
        fn record_debug(&mut self, field: &Field, value: &dyn Debug) {
            match field.name() {
                "dir" => self.dir = Some(format!("{value:?}")),
                "line" => self.line = Some(format!("{value:?}")),
                _ => {}
            }
        }
    }

    /// The command of a line sent: an SMC100's two letters after its address, an
    /// SR830's mnemonic.
    fn command(line: &str) -> (&'static str, String) {
        let body = line.trim_start_matches(|c: char| c.is_ascii_digit());
        if body.len() < line.len() {
            ("motion", body.chars().take(2).collect())
        } else {
            let end = line
                .find(|c: char| c == ' ' || c == '\\' || c.is_ascii_digit())
                .unwrap_or(line.len());
            ("detector", line[..end].to_string())
        }
    }

    impl Subscriber for Counter {
        fn enabled(&self, m: &Metadata<'_>) -> bool {
            m.is_event()
                && (m.target() == "gonio_driver::wire"
                    || m.target().starts_with("gonio_acquire::engine"))
        }
        fn new_span(&self, _: &Attributes<'_>) -> Id {
            Id::from_u64(1)
        }
        fn record(&self, _: &Id, _: &Record<'_>) {}
        fn record_follows_from(&self, _: &Id, _: &Id) {}
        fn event(&self, e: &Event<'_>) {
            let mut f = Fields::default();
            e.record(&mut f);
            let mut t = self.0.lock().expect("tally");
            if let (Some(m), Some(r)) = (f.moving_s, f.reading_s) {
                t.steps += 1;
                t.moving_s += m;
                t.reading_s += r;
                t.rereads += f.rereads;
            } else if f.dir.as_deref() == Some("tx")
                && let Some(line) = f.line
            {
                *t.sent.entry(command(&line)).or_default() += 1;
            }
        }
        fn enter(&self, _: &Id) {}
        fn exit(&self, _: &Id) {}
    }

    impl Budget {
        /// Installs the counting subscriber for the whole process.
        pub fn install() -> Budget {
            let tally = Arc::new(Mutex::new(Tally::default()));
            tracing::subscriber::set_global_default(Counter(tally.clone())).expect("subscriber");
            Budget(tally)
        }

        /// The budget: motion, reading, and each line's commands.
        pub fn print(&self, readings: &[gonio_run::ReadingRecord]) {
            let t = self.0.lock().expect("tally");
            let window: u64 = readings.iter().map(|r| u64::from(r.n)).sum();
            println!(
                "budget: {} steps; motion {:.1} s, reading {:.1} s ({} rereads); {} snapshots in the readings' windows",
                t.steps, t.moving_s, t.reading_s, t.rereads, window
            );
            for ((line, cmd), n) in &t.sent {
                println!("   {line} {cmd}: {n}");
            }
        }
    }
}
