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

/// One axis' share of the serial exchanges of a move, s, as its line's session makes
/// them: what a step costs beyond the stages' own motion. The controller family's
/// protocol fills it in (an SMC100 chain's `TP`, `PT`, `PA`, `TE`, `TS` at 57 600
/// baud; an APT controller's status requests and move message).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisExchanges {
    /// The serial line the axis is on: the axes of one line are commanded one after
    /// another, each line's at the same time as the others'.
    pub line: usize,
    /// Before the move: the position read, s.
    pub before_s: f64,
    /// Before a move that goes somewhere: the controller's own time estimate asked, s.
    pub estimate_s: f64,
    /// The move command on the wire, s: the stage starts once it has arrived.
    pub command_s: f64,
    /// After the command: its check, s.
    pub check_s: f64,
    /// One status query of the wait for the stage to stop, s.
    pub status_s: f64,
    /// The pause before each round of status queries, s.
    pub poll_s: f64,
    /// After the move: the position read back, s.
    pub after_s: f64,
}

/// The serial exchanges of a move of every stage, by axis, in the order the stages'
/// targets are given (the engine's role order). See [`MoveExchanges::move_s`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MoveExchanges {
    /// One entry per axis.
    pub axes: Vec<AxisExchanges>,
}

impl MoveExchanges {
    /// The time a move takes from its first byte to its last, s, each axis' stage
    /// moving for `motion_s[k]` (0: commanded where it stands), as a motion session
    /// makes it on each line: for each axis in turn, the position read, the estimate
    /// (when it moves), the command, whose arrival starts the stage, and the command's
    /// check; then rounds of a pause and a status query to every axis still moving,
    /// until none is; then every position read back. Lines work at the same time:
    /// the move ends with the slowest.
    pub fn move_s(&self, motion_s: &[f64]) -> f64 {
        let lines = self.axes.iter().map(|a| a.line + 1).max().unwrap_or(0);
        (0..lines)
            .map(|line| self.line_s(line, motion_s))
            .fold(0.0, f64::max)
    }

    /// One line's part of [`move_s`](Self::move_s).
    fn line_s(&self, line: usize, motion_s: &[f64]) -> f64 {
        let on: Vec<(&AxisExchanges, f64)> = self
            .axes
            .iter()
            .zip(motion_s.iter().copied().chain(std::iter::repeat(0.0)))
            .filter(|(a, _)| a.line == line)
            .collect();
        let mut t = 0.0;
        // When each stage stops.
        let mut ends = Vec::with_capacity(on.len());
        for &(a, d) in &on {
            t += a.before_s;
            if d > 0.0 {
                t += a.estimate_s;
            }
            t += a.command_s;
            ends.push(t + d);
            t += a.check_s;
        }
        // Every commanded axis is asked at least once; a status query sees the stage
        // as it is when the query arrives.
        let mut waiting: Vec<usize> = (0..on.len()).collect();
        while !waiting.is_empty() {
            t += on[waiting[0]].0.poll_s;
            waiting.retain(|&k| {
                let still = ends[k] > t;
                t += on[k].0.status_s;
                still
            });
        }
        t + on.iter().map(|(a, _)| a.after_s).sum::<f64>()
    }

    /// The time to read where every stage stands, s: a step that does not move
    /// asks each axis in turn.
    pub fn positions_s(&self) -> f64 {
        self.axes.iter().map(|a| a.before_s).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::{AxisExchanges, MoveExchanges, trapezoid_time};

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

    /// Round numbers: each query 10 ms, a command 1 ms, polls every 50 ms.
    fn axis(line: usize) -> AxisExchanges {
        AxisExchanges {
            line,
            before_s: 0.010,
            estimate_s: 0.010,
            command_s: 0.001,
            check_s: 0.010,
            status_s: 0.010,
            poll_s: 0.050,
            after_s: 0.010,
        }
    }

    #[test]
    fn a_move_is_its_commands_its_polls_and_its_read_backs() {
        let one = MoveExchanges {
            axes: vec![axis(0), axis(0)],
        };
        // Nothing moves: 2 × (TP, PA, TE) = 42 ms; a round (50 ms, 2 × TS); 2 × TP.
        assert!((one.move_s(&[0.0, 0.0]) - (0.042 + 0.070 + 0.020)).abs() < 1e-12);
        // The first stage moves 0.1 s from its command's arrival (21 ms, until 121 ms):
        // it is still moving at the first round's status (102 ms), stopped at the
        // second round's (172 ms), which asks it alone.
        let t = 0.021 + 0.031 + 0.050 + 0.020 + 0.050 + 0.010 + 0.020;
        assert!(
            (one.move_s(&[0.1, 0.0]) - t).abs() < 1e-12,
            "{}",
            one.move_s(&[0.1, 0.0])
        );
        // On two lines the axes are commanded at once: the slower line's time.
        let two = MoveExchanges {
            axes: vec![axis(0), axis(1)],
        };
        assert!(two.move_s(&[0.1, 0.0]) < t);
        assert!((two.move_s(&[0.0, 0.0]) - (0.021 + 0.060 + 0.010)).abs() < 1e-12);
        // Where the stages stand: each position asked in turn.
        assert!((two.positions_s() - 0.020).abs() < 1e-12);
    }
}
