//! The values: a channel's sample readings reduced to f_r by Eq. A.15,
//!
//!   f_r = S / (Φ(t) · Ω · cos θo),
//!
//! S the signal less the dark and Φ(t) the incident flux at the reading's time,
//! each with its budget: per term of [`DC_TERMS`](crate::DC_TERMS), the sample's
//! standard uncertainty ([`Channel::terms`]). A sample reading is left out (and
//! counted by reason) when it carries a rejected flag or looks at a grazing
//! angle. The channels' values are gathered per pair and repeat ([`Values`]) until
//! every channel has been reduced.

use std::collections::BTreeMap;

use gonio_core::dirfile::PairDeg;
use gonio_run::{ReadingRecord, flags};

use crate::budget::{self, RANGES};
use crate::calibration::Calibrations;
use crate::correlations::{Parts, Shared};
use crate::dark::{Dark, Signal};
use crate::drift::IncidentFlux;
use crate::group::{Read, flag_reason};
use crate::{Detector, N_TERMS, Run};

/// A pair's directions, its (value, budget) per channel as the channels are
/// reduced, and the union of its readings' flags.
pub(crate) type PerPair = (PairDeg, Vec<Option<(f64, [f64; N_TERMS], Parts)>>, u32);

/// The run's sample values as the channels are reduced, and what was left out.
pub(crate) struct Values {
    /// The number of channels.
    nc: usize,
    /// Per pair and repeat (its plan index and repeat), the value per channel.
    pub pairs: BTreeMap<(usize, u32), PerPair>,
    /// Sample readings left out, by reason.
    pub rejected: BTreeMap<String, usize>,
    /// The largest difference between read-back and commanded directions, deg.
    pub max_pos: f64,
}

/// What a channel's samples are reduced with: the steps before.
pub(crate) struct Channel<'c> {
    /// The channel's index.
    pub ci: usize,
    /// Its dark.
    pub dark: &'c Dark<'c>,
    /// Its calibration.
    pub cal: &'c Calibrations<'c>,
    /// Its incident flux.
    pub flux: &'c IncidentFlux,
    /// The `standard` term, relative ([`Calibrations::standard_rel`]).
    pub standard_rel: f64,
}

/// One channel's samples as reduced.
pub(crate) struct Reduced {
    /// How many were reduced.
    pub count: usize,
    /// Per term, each one's σ relative to its f.
    pub rels: [Vec<f64>; N_TERMS],
}

/// Where a sample stands against the incident flux.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scaled {
    /// f_r, 1/sr.
    pub f: f64,
    /// Φ Ω cos θo, what the signal is divided by.
    pub scale: f64,
    /// The relative uncertainty of Φ's time dependence (the `drift` term).
    pub drift_rel: f64,
    /// The relative uncertainty of interpolated calibrations at the sample's time.
    pub interp_rel: f64,
}

impl Values {
    /// No values yet, for `nc` channels.
    pub(crate) fn new(nc: usize) -> Values {
        Values {
            nc,
            pairs: BTreeMap::new(),
            rejected: BTreeMap::new(),
            max_pos: 0.0,
        }
    }

    /// Reduces the channel's sample readings `samples` into the pairs' values.
    /// `Err` for a DC reading on a range the 6485 has not.
    pub(crate) fn add(
        &mut self,
        run: &Run,
        samples: &[Read],
        c: &Channel,
    ) -> Result<Reduced, String> {
        let reject = run.opts.reject_flags;
        let mut count = 0;
        let mut rels: [Vec<f64>; N_TERMS] = Default::default();
        for (s, r) in samples {
            let (Some(pair), Some(index)) = (s.step.pair, s.step.plan_index) else {
                continue;
            };
            self.max_pos = self.max_pos.max(position_error(&pair, &r.read_pair));
            if r.flags & reject != 0 {
                *self
                    .rejected
                    .entry(flag_reason(r.flags & reject))
                    .or_default() += 1;
                continue;
            }
            let cos_o = pair.to_dirs().wo.z;
            if cos_o <= 0.0 {
                *self.rejected.entry("grazing".into()).or_default() += 1;
                continue;
            }
            let sig = c.dark.signal(r, &run.noise);
            let (phi, drift_rel, interp_rel) = c.flux.flux.at(run.groups.time_of(r));
            let scale = phi * run.omega * cos_o;
            let at = Scaled {
                f: sig.v / scale,
                scale,
                drift_rel,
                interp_rel,
            };
            let (terms, abs) = c.terms(r, &sig, at, run.detector)?;
            for (k, t) in terms.iter().enumerate() {
                rels[k].push(*t);
            }
            let parts = c.parts(r, &sig, at, run.groups.time_of(r), run.detector)?;
            let nc = self.nc;
            let entry = self
                .pairs
                .entry((index, s.step.repeat))
                .or_insert_with(|| (pair, vec![None; nc], 0));
            entry.1[c.ci] = Some((at.f, abs, parts));
            // How a reading was taken is no concern of the sample's.
            entry.2 |= r.flags & !flags::HOW_READ;
            count += 1;
        }
        Ok(Reduced { count, rels })
    }
}

impl Channel<'_> {
    /// A sample's budget: per term its σ relative to f, and absolute, 1/sr. A
    /// signal not above 0 has only its noise, absolute (relative to |f|).
    pub(crate) fn terms(
        &self,
        r: &ReadingRecord,
        sig: &Signal,
        at: Scaled,
        detector: Detector,
    ) -> Result<([f64; N_TERMS], [f64; N_TERMS]), String> {
        let Signal {
            v,
            sigma: sv,
            u,
            res,
        } = *sig;
        let Scaled {
            f,
            scale,
            drift_rel,
            interp_rel,
        } = at;
        if v > 0.0 {
            let cal = self.cal;
            // A dark error d moves S by −u·d and the calibration by −u_c·d: f by
            // f (u_c/S_c − u/S)·d.
            let dk = [cal.dark[0] - u[0] / v, cal.dark[1] - u[1] / v];
            // Each range's error z_k moves f (Eq. A.15 is S/Φ) by the sample's
            // relative error on it less the calibration's, the dark's moving
            // both: on one range, gain errors cancel in the ratio.
            let own = budget::range_rel(r, v, detector)?;
            let acc = (0..RANGES)
                .map(|k| own[k] - self.dark.acc[k] / v - cal.acc[k])
                .map(|c| c * c)
                .sum::<f64>()
                .sqrt();
            let terms = [
                sv / v,
                res,
                self.dark.sigma * dk[0].hypot(dk[1]),
                self.flux.c_rel.hypot(interp_rel).hypot(cal.res),
                drift_rel,
                self.standard_rel,
                acc,
                0.0,
                0.0,
            ];
            return Ok((terms, terms.map(|t| t * f)));
        }
        let mut terms = [0.0; N_TERMS];
        terms[0] = sv / scale / f.abs().max(f64::MIN_POSITIVE);
        let mut abs = [0.0; N_TERMS];
        abs[0] = sv / scale;
        Ok((terms, abs))
    }
}

impl Channel<'_> {
    /// A sample's error as its independent σ and its coefficients on the shared
    /// errors ([`crate::correlations`]), 1/sr: the terms of [`Channel::terms`] taken
    /// apart, so that they add in quadrature to the same σ. The calibration and
    /// the standard move every sample alike; the wavelength term is added with the
    /// channels ([`crate::assemble`]).
    pub(crate) fn parts(
        &self,
        r: &ReadingRecord,
        sig: &Signal,
        at: Scaled,
        t: f64,
        detector: Detector,
    ) -> Result<Parts, String> {
        let (_, abs) = self.terms(r, sig, at, detector)?;
        if sig.v <= 0.0 {
            return Ok(Parts {
                independent: abs[0],
                read: Some(r.read_pair),
                shared: Vec::new(),
            });
        }
        let (f, v, u, cal) = (at.f, sig.v, sig.u, self.cal);
        let mut shared = vec![
            (
                Shared::DarkX,
                f * self.dark.sigma * (cal.dark[0] - u[0] / v),
            ),
            (
                Shared::DarkY,
                f * self.dark.sigma * (cal.dark[1] - u[1] / v),
            ),
            (Shared::Calibration, abs[3]),
            (Shared::Standard, abs[5]),
        ];
        let own = budget::range_rel(r, v, detector)?;
        shared.extend((0..RANGES).map(|k| {
            let c = own[k] - self.dark.acc[k] / v - cal.acc[k];
            (Shared::Range(k), f * c)
        }));
        shared.extend(
            self.flux
                .flux
                .drift_parts(t)
                .into_iter()
                .map(|(k, x)| (k, f * x)),
        );
        shared.retain(|(_, x)| *x != 0.0);
        Ok(Parts {
            independent: abs[0].hypot(abs[1]),
            read: Some(r.read_pair),
            shared,
        })
    }
}

/// The larger of the angles between the commanded and the read-back incident
/// and outgoing directions, deg.
fn position_error(a: &PairDeg, b: &PairDeg) -> f64 {
    let d = |x: gonio_core::SphericalDeg, y: gonio_core::SphericalDeg| {
        gonio_core::Dir::from(x)
            .angle_to(gonio_core::Dir::from(y))
            .to_degrees()
    };
    d(a.incident, b.incident).max(d(a.outgoing, b.outgoing))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Options;
    use crate::drift::Flux;
    use crate::noise::Noise;
    use crate::test_support::reading;
    use gonio_core::SphericalDeg;

    /// A lock-in sample of S = 2 V along X, against a calibration whose dark
    /// sensitivity is (¼, 0) and a dark of σ 0.01: each term by hand.
    #[test]
    fn a_sample_s_terms_are_its_relative_errors_times_f() {
        let noise = Noise::of_run(&[], &Options::default(), Detector::LockIn);
        let step = gonio_run::StoredStep {
            id: 1,
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
        };
        // A dark of half-mean-R² variance 0.5·0.02² + …: its σ is whatever the
        // dark step says; the term is σ·|u_c/S_c − u/S|.
        let dark_reading = gonio_run::ReadingRecord {
            x_mean: 0.0,
            y_mean: 0.0,
            r_mean: 0.02,
            r_std: 0.0,
            n: 1,
            ..reading()
        };
        let dark =
            Dark::of(vec![(&step, &dark_reading)], &noise, Detector::LockIn).expect("a dark");
        assert!(dark.sigma > 0.0);
        let cal = Calibrations {
            use_standard: false,
            readings: Vec::new(),
            measured: Vec::new(),
            dark: [0.25, 0.0],
            res: 1e-3,
            acc: [0.0; RANGES],
        };
        let flux = IncidentFlux {
            flux: Flux::Constant(1.0),
            c: 1.0,
            c_rel: 0.01,
            source: String::new(),
            n_refs: 0,
            drift_max: 0.0,
        };
        let ch = Channel {
            ci: 0,
            dark: &dark,
            cal: &cal,
            flux: &flux,
            standard_rel: 3e-3,
        };
        let sig = Signal {
            v: 2.0,
            sigma: 0.02,
            u: [1.0, 0.0],
            res: 1e-6,
        };
        let at = Scaled {
            f: 5.0,
            scale: 0.4,
            drift_rel: 2e-3,
            interp_rel: 0.0,
        };
        let (rel, abs) = ch
            .terms(&reading(), &sig, at, Detector::LockIn)
            .expect("terms");
        let want = [
            0.01,
            1e-6,
            dark.sigma * 0.25,
            0.01f64.hypot(1e-3),
            2e-3,
            3e-3,
            0.0,
            0.0,
            0.0,
        ];
        assert_eq!(rel, want);
        assert_eq!(abs, want.map(|t| t * 5.0));
        // A signal not above 0 keeps its noise, absolute.
        let (rel, abs) = ch
            .terms(&reading(), &Signal { v: -1.0, ..sig }, at, Detector::LockIn)
            .expect("terms");
        assert_eq!(abs[0], 0.02 / 0.4);
        assert_eq!(rel[0], 0.02 / 0.4 / 5.0);
        assert!(rel[1..].iter().chain(&abs[1..]).all(|t| *t == 0.0));
    }

    #[test]
    fn the_position_error_is_the_larger_of_the_two_directions() {
        let pair = |ti: f64, to: f64| PairDeg {
            incident: SphericalDeg::new(ti, 0.0),
            outgoing: SphericalDeg::new(to, 180.0),
        };
        let e = position_error(&pair(30.0, 40.0), &pair(30.5, 42.0));
        assert!((e - 2.0).abs() < 1e-9, "{e}");
        assert_eq!(position_error(&pair(30.0, 40.0), &pair(30.0, 40.0)), 0.0);
    }
}
