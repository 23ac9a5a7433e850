//! The stage motion the simulated motion controllers share (the SMC100's and the APT
//! controllers'): a point-to-point move along a trapezoidal or triangular velocity
//! profile, and where it passes a position (a stalled stage's sticking point).

/// A point-to-point move with a trapezoidal (or triangular) velocity profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Profile {
    /// Start position (counter units).
    pub from: f64,
    /// End position.
    pub to: f64,
    /// Start time, s.
    pub t0: f64,
    /// Peak velocity reached.
    pub v: f64,
    /// Acceleration.
    pub a: f64,
    /// Duration of the acceleration (and of the deceleration) phase.
    pub t_acc: f64,
    /// Total duration.
    pub duration: f64,
}

impl Profile {
    /// A move from `from` to `to` starting at `t0` with velocity `v` and acceleration `a`.
    pub fn new(from: f64, to: f64, t0: f64, v: f64, a: f64) -> Self {
        let d = (to - from).abs();
        let (vp, t_acc, duration) = if d >= v * v / a {
            // Trapezoid: accelerate to v, cruise, decelerate.
            (v, v / a, 2.0 * v / a + (d - v * v / a) / v)
        } else {
            // Triangle: never reaches v.
            let t = (d / a).sqrt();
            (a * t, t, 2.0 * t)
        };
        Profile {
            from,
            to,
            t0,
            v: vp,
            a,
            t_acc,
            duration,
        }
    }

    /// The duration of a move of length `distance` (what `PT` answers).
    pub fn duration_for(distance: f64, v: f64, a: f64) -> f64 {
        gonio_core::motion::trapezoid_time(distance, v, a)
    }

    /// Position at time `t`.
    pub fn position(&self, t: f64) -> f64 {
        let s = (t - self.t0).clamp(0.0, self.duration);
        let dir = (self.to - self.from).signum();
        let travelled = if s <= self.t_acc {
            0.5 * self.a * s * s
        } else if s <= self.duration - self.t_acc {
            0.5 * self.a * self.t_acc * self.t_acc + self.v * (s - self.t_acc)
        } else {
            let r = self.duration - s;
            (self.to - self.from).abs() - 0.5 * self.a * r * r
        };
        self.from + dir * travelled
    }

    /// Speed at time `t`.
    pub fn speed(&self, t: f64) -> f64 {
        let s = (t - self.t0).clamp(0.0, self.duration);
        if s <= self.t_acc {
            self.a * s
        } else if s <= self.duration - self.t_acc {
            self.v
        } else {
            self.a * (self.duration - s)
        }
    }

    /// When the move ends.
    pub fn end(&self) -> f64 {
        self.t0 + self.duration
    }

    /// When the move passes position `x`, if it does: bisected, the profile being
    /// monotonic.
    pub fn crossing(&self, x: f64) -> Option<f64> {
        let side = |t: f64| (self.position(t) - x).signum();
        let (mut lo, mut hi) = (self.t0, self.end());
        if side(lo) == side(hi) && side(hi) != 0.0 {
            return None;
        }
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if side(mid) == side(lo) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(hi)
    }
}
