//! The dark: what the detector reads with the source blocked, subtracted from
//! every reading of its channel, and the signal of a reading less it
//! ([`Dark::signal`]).
//!
//! A lock-in's X and Y average to the coherent signal, while R of a dark reading
//! is mostly noise (its mean is σ√(π/2), not zero), so its dark is a vector, the
//! mean of the dark readings' mean X and Y, and a signal is the length of the
//! reading's vector less it. A picoammeter's dark current has a true mean: the
//! dark is the mean of the dark readings' currents, subtracted with its sign, and
//! it carries the range-accuracy error of the ranges it was read on.

use gonio_run::ReadingRecord;

use crate::Detector;
use crate::budget::{self, RANGES};
use crate::group::Read;
use crate::noise::Noise;

/// A channel's dark.
pub(crate) struct Dark<'a> {
    /// The dark readings.
    pub readings: Vec<Read<'a>>,
    /// The dark subtracted: a lock-in's vector (X, Y), V; a picoammeter's current
    /// [I, 0], A. 0 without dark readings.
    pub xy: [f64; 2],
    /// The σ of each component of the dark's mean.
    pub sigma: f64,
    /// A picoammeter's dark's range-accuracy error per range, A: the mean of the
    /// dark readings' errors, each on its own range (all 0 for a lock-in).
    pub acc: [f64; RANGES],
    /// The detector, which decides how a signal is taken.
    detector: Detector,
}

/// A reading's signal, less the dark.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Signal {
    /// The signal: a lock-in's |(X, Y) − dark|, V; a picoammeter's I − I_dark,
    /// signed, A.
    pub v: f64,
    /// The σ of the reading's mean ([`Noise::sigma_mean`]).
    pub sigma: f64,
    /// The unit vector a dark error moves the signal along (a DC signal: +1).
    pub u: [f64; 2],
    /// The reply rounding relative to the signal.
    pub res: f64,
}

impl<'a> Dark<'a> {
    /// The dark of a channel's dark readings. `Err` for a DC reading on a range
    /// the 6485 has not.
    pub(crate) fn of(
        readings: Vec<Read<'a>>,
        noise: &Noise,
        detector: Detector,
    ) -> Result<Dark<'a>, String> {
        let xy = if readings.is_empty() {
            [0.0, 0.0]
        } else {
            let n = readings.len() as f64;
            [
                readings.iter().map(|(_, r)| r.x_mean).sum::<f64>() / n,
                readings.iter().map(|(_, r)| r.y_mean).sum::<f64>() / n,
            ]
        };
        // The σ of each component of the dark vector's mean.
        let sigma = if readings.is_empty() {
            0.0
        } else {
            readings
                .iter()
                .map(|(_, r)| noise.sigma_mean(r, true).powi(2))
                .sum::<f64>()
                .sqrt()
                / readings.len() as f64
        };
        let mut acc = [0.0f64; RANGES];
        if detector == Detector::Dc {
            for (_, r) in &readings {
                let (k, u) = budget::range_of(r)?;
                acc[k] += u / readings.len() as f64;
            }
        }
        Ok(Dark {
            readings,
            xy,
            sigma,
            acc,
            detector,
        })
    }

    /// A reading's signal less this dark, with its noise σ, the direction a dark
    /// error moves it in and its relative resolution.
    pub(crate) fn signal(&self, r: &ReadingRecord, noise: &Noise) -> Signal {
        let dark = self.xy;
        match self.detector {
            Detector::LockIn => {
                let (x, y) = (r.x_mean - dark[0], r.y_mean - dark[1]);
                let s = x.hypot(y);
                let u = if s > 0.0 { [x / s, y / s] } else { [1.0, 0.0] };
                Signal {
                    v: s,
                    sigma: noise.sigma_mean(r, false),
                    u,
                    res: budget::resolution_rel(s),
                }
            }
            Detector::Dc => {
                let v = r.x_mean - dark[0];
                Signal {
                    v,
                    sigma: noise.sigma_mean(r, false),
                    u: [1.0, 0.0],
                    res: budget::dc_resolution_rel(r.x_mean, v),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Options;
    use crate::test_support::reading;

    fn step(id: i64) -> gonio_run::StoredStep {
        gonio_run::StoredStep {
            id,
            step: gonio_plan::Step {
                kind: gonio_plan::StepKind::Dark,
                channel: None,
                repeat: 0,
                pair: None,
                stages: None,
                plan_index: None,
            },
            state: "done".into(),
            attempts: 1,
        }
    }

    /// A lock-in's dark is the mean vector; a reading's signal is the length of
    /// its vector less it, along the unit vector of the difference.
    #[test]
    fn a_lock_in_s_signal_is_the_length_of_its_vector_less_the_dark() {
        let lockin = |x: f64, y: f64| ReadingRecord {
            x_mean: x,
            y_mean: y,
            r_mean: x.hypot(y),
            ..reading()
        };
        let (d1, d2) = (lockin(1e-6, 3e-6), lockin(3e-6, 1e-6));
        let (s1, s2) = (step(1), step(2));
        let noise = Noise::of_run(&[], &Options::default(), Detector::LockIn);
        let dark =
            Dark::of(vec![(&s1, &d1), (&s2, &d2)], &noise, Detector::LockIn).expect("a dark");
        assert!((dark.xy[0] - 2e-6).abs() < 1e-21 && (dark.xy[1] - 2e-6).abs() < 1e-21);
        assert_eq!(dark.acc, [0.0; RANGES]);
        let sig = dark.signal(&lockin(5e-6, 6e-6), &noise);
        let (x, y) = (5e-6 - dark.xy[0], 6e-6 - dark.xy[1]);
        assert_eq!(sig.v, f64::hypot(x, y));
        assert_eq!(sig.u, [x / sig.v, y / sig.v]);
        assert_eq!(sig.res, budget::resolution_rel(sig.v));
    }

    /// A picoammeter's dark is a signed scalar; its range error is the mean of the
    /// dark readings' own.
    #[test]
    fn a_dc_dark_is_subtracted_with_its_sign() {
        let dc = |i: f64| ReadingRecord {
            x_mean: i,
            ..reading()
        };
        let (d1, d2) = (dc(-2e-12), dc(-4e-12));
        let (s1, s2) = (step(1), step(2));
        let noise = Noise::of_run(&[], &Options::default(), Detector::Dc);
        let dark = Dark::of(vec![(&s1, &d1), (&s2, &d2)], &noise, Detector::Dc).expect("a dark");
        assert!((dark.xy[0] + 3e-12).abs() < 1e-27 && dark.xy[1] == 0.0);
        let (_, u1) = budget::range_sigma(&d1).expect("a range");
        let (_, u2) = budget::range_sigma(&d2).expect("a range");
        assert_eq!(dark.acc[2], u1 / 2.0 + u2 / 2.0);
        // Five samples of scatter 1 pA each: σ of the mean (s²/5)^½, of two, /2.
        let s = (1e-12f64 * 1e-12 / 5.0).sqrt();
        let want = (s.powi(2) + s.powi(2)).sqrt() / 2.0;
        assert_eq!(dark.sigma, want);
        let sig = dark.signal(&dc(1e-9), &noise);
        assert_eq!(sig.v, 1e-9 - dark.xy[0]);
        assert_eq!(sig.u, [1.0, 0.0]);
    }
}
