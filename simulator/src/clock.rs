//! Simulated time. The simulator and the driver read one clock, so a move that takes
//! ten physical seconds takes ten seconds of simulated time whatever the wall clock
//! says — and the run's physical duration is always known.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use gonio_driver::Clock;

#[derive(Debug)]
enum Mode {
    /// Time advances only when someone sleeps on the clock.
    Driven { now: Duration },
    /// Time follows the wall clock, `1/scale` times as fast.
    FreeRunning { origin: Instant },
}

/// A clock for the simulated instrument and, in-process, for the driver too.
///
/// *Driven* (in-process): physical time moves only when the driver waits on it
/// (`sleep`), and each wait also takes `scale` × its length in wall time — scale 0
/// runs as fast as the machine goes, 1 in real time. *Free-running* (a standalone
/// simulator talking to a driver in another process): physical time is wall time
/// divided by `scale`. Clones share the time.
#[derive(Debug, Clone)]
pub struct SimClock {
    mode: Arc<Mutex<Mode>>,
    scale: f64,
}

impl SimClock {
    /// A driven clock at time zero; `scale` ≥ 0.
    pub fn driven(scale: f64) -> Self {
        SimClock {
            mode: Arc::new(Mutex::new(Mode::Driven {
                now: Duration::ZERO,
            })),
            scale: scale.max(0.0),
        }
    }

    /// A free-running clock; `scale` > 0 (1 = real time, 0.1 = ten times faster).
    pub fn free_running(scale: f64) -> Self {
        SimClock {
            mode: Arc::new(Mutex::new(Mode::FreeRunning {
                origin: Instant::now(),
            })),
            scale: if scale > 0.0 { scale } else { 1.0 },
        }
    }

    /// Physical time in seconds.
    pub fn seconds(&self) -> f64 {
        self.now().as_secs_f64()
    }

    /// Moves a driven clock forward by `d` without waiting (for tests and faults).
    pub fn advance(&self, d: Duration) {
        let mut m = self.mode.lock().unwrap_or_else(|p| p.into_inner());
        if let Mode::Driven { now } = &mut *m {
            *now = now.saturating_add(d);
        }
    }
}

impl Clock for SimClock {
    fn now(&self) -> Duration {
        let m = self.mode.lock().unwrap_or_else(|p| p.into_inner());
        match &*m {
            Mode::Driven { now } => *now,
            Mode::FreeRunning { origin } => secs(origin.elapsed().as_secs_f64() / self.scale),
        }
    }

    fn sleep(&self, d: Duration) {
        let wall = secs(d.as_secs_f64() * self.scale);
        let driven = {
            let mut m = self.mode.lock().unwrap_or_else(|p| p.into_inner());
            match &mut *m {
                Mode::Driven { now } => {
                    *now = now.saturating_add(d);
                    true
                }
                Mode::FreeRunning { .. } => false,
            }
        };
        if !wall.is_zero() || !driven {
            std::thread::sleep(wall);
        }
    }
}

/// `s` seconds as a `Duration`, never panicking: negative and NaN become zero, and
/// anything beyond `Duration::MAX` saturates (the config's limits keep real values
/// far inside; this only keeps an arithmetic accident from aborting a run).
pub(crate) fn secs(s: f64) -> Duration {
    Duration::try_from_secs_f64(s.max(0.0)).unwrap_or(Duration::MAX)
}
