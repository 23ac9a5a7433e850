//! Point-to-point motion of a stage, and of a set of stages moving together.

/// Duration (s) of a move of `distance` (any sign) for a stage that accelerates at
/// `acceleration` up to `velocity`, cruises, and decelerates to rest: a trapezoidal
/// velocity profile, or a triangular one when the move is too short to reach
/// `velocity` — the profile an SMC100 executes and answers `PT` with.
pub fn trapezoid_time(distance: f64, velocity: f64, acceleration: f64) -> f64 {
    let d = distance.abs();
    if d == 0.0 {
        return 0.0;
    }
    let ramp = velocity * velocity / acceleration;
    if d >= ramp {
        2.0 * velocity / acceleration + (d - ramp) / velocity
    } else {
        2.0 * (d / acceleration).sqrt()
    }
}

/// One stage's motion limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisMotion {
    /// Top speed, degrees per second.
    pub velocity: f64,
    /// Acceleration and deceleration, degrees per second squared.
    pub acceleration: f64,
}

impl AxisMotion {
    /// Time of a move of `distance` degrees (any sign) on this stage.
    pub fn move_time(&self, distance: f64) -> f64 {
        trapezoid_time(distance, self.velocity, self.acceleration)
    }

    /// True when both figures are finite and positive.
    pub fn is_valid(&self) -> bool {
        self.velocity.is_finite()
            && self.acceleration.is_finite()
            && self.velocity > 0.0
            && self.acceleration > 0.0
    }
}

/// The stages of an instrument, in the order of the position vectors.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionModel {
    /// One entry per stage, in the order of the position vectors.
    pub axes: Vec<AxisMotion>,
}

impl MotionModel {
    /// Time of a step: the slowest axis' trapezoid time (the stages move concurrently).
    ///
    /// Coordinates beyond the number of axes (or axes beyond the coordinates) are
    /// ignored; an empty model makes every step free.
    pub fn step_time(&self, from: &[f64], to: &[f64]) -> f64 {
        self.axes
            .iter()
            .zip(from.iter().zip(to))
            .map(|(ax, (a, b))| ax.move_time(b - a))
            .fold(0.0, f64::max)
    }

    /// Time to visit `points` in `order` starting at `start`.
    ///
    /// # Panics
    /// If `order` holds an index out of `points`' range.
    pub fn path_time(&self, start: &[f64], points: &[[f64; 4]], order: &[usize]) -> f64 {
        let mut at = start;
        let mut total = 0.0;
        for &i in order {
            let p = &points[i];
            total += self.step_time(at, p);
            at = p;
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::trapezoid_time;

    #[test]
    fn trapezoid_and_triangle() {
        // 20 °/s, 80 °/s²: ramps of 0.25 s and 2.5°; 10° takes 0.75 s.
        assert!((trapezoid_time(10.0, 20.0, 80.0) - 0.75).abs() < 1e-15);
        assert!((trapezoid_time(-10.0, 20.0, 80.0) - 0.75).abs() < 1e-15);
        // 1°: a triangle, 2·√(1/80) s.
        assert!((trapezoid_time(1.0, 20.0, 80.0) - 2.0 * (1.0f64 / 80.0).sqrt()).abs() < 1e-15);
        // Continuous where the two meet (5° = v²/a).
        assert!((trapezoid_time(5.0, 20.0, 80.0) - 0.5).abs() < 1e-15);
        assert_eq!(trapezoid_time(0.0, 20.0, 80.0), 0.0);
    }
}
