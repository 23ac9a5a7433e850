//! The step time as a metric: each axis' trapezoid profile, and the maximum over
//! axes that the k-d tree of `gonio_core` prunes with.

use gonio_core::kdtree::Metric;

use super::AxisMotion;

/// An axis' trapezoid profile with the divisions of [`trapezoid_time`](gonio_core::motion::trapezoid_time) done once: the
/// search evaluates it millions of times. (It may differ from `trapezoid_time` in the
/// last bit; every comparison [`optimise`](super::optimise) promises is made with
/// [`MotionModel::path_time`].)
#[derive(Clone, Copy)]
pub(super) struct Profile {
    /// Distance of the full acceleration and deceleration ramps, `v²/a`.
    ramp: f64,
    /// Their time, `2v/a`.
    t_ramp: f64,
    inv_v: f64,
    /// `4/a`: a triangular move of `d` lasts `2√(d/a) = √(4d/a)`.
    four_over_a: f64,
}

impl Profile {
    /// An axis that never costs time.
    pub(super) const FREE: Profile = Profile {
        ramp: f64::INFINITY,
        t_ramp: 0.0,
        inv_v: 0.0,
        four_over_a: 0.0,
    };

    pub(super) fn new(ax: AxisMotion) -> Profile {
        let (v, a) = (ax.velocity, ax.acceleration);
        Profile {
            ramp: v * v / a,
            t_ramp: 2.0 * v / a,
            inv_v: 1.0 / v,
            four_over_a: 4.0 / a,
        }
    }

    /// Time of a move of `d ≥ 0`.
    #[inline(always)]
    fn time(&self, d: f64) -> f64 {
        if d >= self.ramp {
            self.t_ramp + (d - self.ramp) * self.inv_v
        } else {
            (d * self.four_over_a).sqrt()
        }
    }
}

/// The step time `maxᵢ tᵢ(|pᵢ − qᵢ|)` as the k-d tree's metric: its box bound is
/// `maxᵢ tᵢ(gapᵢ)`, and nodes split on the axis of widest extent *in time*.
#[derive(Clone, Copy)]
pub(super) struct StepTime {
    /// The four axes' profiles (a missing axis moves for free).
    pub(super) axes: [Profile; 4],
}

impl Metric<4> for StepTime {
    #[inline]
    fn distance(&self, q: &[f64; 4], p: &[f64; 4]) -> f64 {
        let t = |k: usize| self.axes[k].time((q[k] - p[k]).abs());
        t(0).max(t(1)).max(t(2).max(t(3)))
    }

    #[inline]
    fn box_bound(&self, q: &[f64; 4], lo: &[f64; 4], hi: &[f64; 4]) -> f64 {
        let mut m = 0.0f64;
        for (k, ax) in self.axes.iter().enumerate() {
            let gap = (lo[k] - q[k]).max(q[k] - hi[k]).max(0.0);
            m = m.max(ax.time(gap));
        }
        m
    }

    #[inline]
    fn spread(&self, axis: usize, width: f64) -> f64 {
        self.axes[axis].time(width)
    }
}
