//! The correlations: which errors the samples share, and by how much each sample
//! moves with each ([`gonio_process::covariance::Covariance`]).
//!
//! The budget's terms ([`DC_TERMS`](crate::DC_TERMS)) are magnitudes. Behind the
//! shared ones lie a few independent errors, each a standard normal draw that
//! moves every sample it touches by a signed coefficient:
//! - the dark vector's two components (one for a DC run's scalar dark): a dark
//!   error d moves f by f·(u_c/S_c − u/S)·d, so a weak sample and the calibration
//!   move oppositely;
//! - the calibration scale (one per channel, every sample alike);
//! - the drift: a fitted line's slope, which moves samples before and after the
//!   calibrations' time oppositely, or each drift reference's noise, shared by the
//!   samples between it and its neighbours;
//! - the reference standard's certificate (one per channel);
//! - a picoammeter's accuracy on each range it read on;
//! - a spectral run's wavelength scale (one per wavelength, each sample by its own
//!   slope).
//!
//! The noise and the reply rounding are each sample's own. For every sample the
//! independent σ and the coefficients add in quadrature to its stated σ.

use std::collections::BTreeSet;

use gonio_core::dirfile::PairDeg;
use gonio_process::covariance::{Covariance, Source};

/// One independent error behind a shared term.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Shared {
    /// The dark vector's X component (a DC dark's current).
    DarkX,
    /// The dark vector's Y component.
    DarkY,
    /// The calibration scale.
    Calibration,
    /// The slope of the line fitted to the drift references.
    DriftSlope,
    /// The noise of the drift reference of this index (in time order).
    DriftReference(usize),
    /// The reference standard's certificate.
    Standard,
    /// The picoammeter's accuracy on the range of this index.
    Range(usize),
    /// The wavelength scale (and passband) at the channel's wavelength.
    Wavelength,
}

impl Shared {
    /// The budget term it belongs to.
    fn term(self) -> &'static str {
        match self {
            Shared::DarkX | Shared::DarkY => "dark",
            Shared::Calibration => "calibration",
            Shared::DriftSlope | Shared::DriftReference(_) => "drift",
            Shared::Standard => "standard",
            Shared::Range(_) => "range accuracy",
            Shared::Wavelength => crate::spectral::TERM,
        }
    }

    /// What it is, for a person.
    fn label(self) -> String {
        match self {
            Shared::DarkX => "dark X".into(),
            Shared::DarkY => "dark Y".into(),
            Shared::Calibration => "calibration scale".into(),
            Shared::DriftSlope => "drift line's slope".into(),
            Shared::DriftReference(k) => format!("drift reference {}", k + 1),
            Shared::Standard => "reference standard's certificate".into(),
            Shared::Range(k) => format!(
                "range accuracy {}",
                crate::budget::ranges_label(u8::try_from(k).into_iter())
            ),
            Shared::Wavelength => "wavelength scale".into(),
        }
    }
}

/// A sample's error on one channel: its independent σ and its signed coefficient
/// on each shared error, 1/sr.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Parts {
    /// The independent σ (noise, reply rounding and, once the samples are
    /// gathered, the position term).
    pub independent: f64,
    /// Where the stages stood for the reading.
    pub read: Option<PairDeg>,
    /// The shared errors' coefficients.
    pub shared: Vec<(Shared, f64)>,
}

/// The covariance of samples at `pairs` from each one's parts per channel.
pub(crate) fn covariance(pairs: &[PairDeg], parts: &[Vec<Parts>]) -> Covariance {
    let nc = parts.first().map_or(0, Vec::len);
    let keys: Vec<(usize, Shared)> = (0..nc)
        .flat_map(|c| {
            let used: BTreeSet<Shared> = parts
                .iter()
                .flat_map(|p| p[c].shared.iter().map(|(k, _)| *k))
                .collect();
            used.into_iter().map(move |k| (c, k))
        })
        .collect();
    let sources = keys
        .iter()
        .map(|&(channel, k)| Source {
            term: k.term().into(),
            channel,
            label: k.label(),
        })
        .collect();
    let coefficients = parts
        .iter()
        .map(|p| {
            keys.iter()
                .map(|&(c, key)| {
                    p[c].shared
                        .iter()
                        .filter(|(k, _)| *k == key)
                        .map(|(_, v)| v)
                        .sum()
                })
                .collect()
        })
        .collect();
    let independent = parts
        .iter()
        .map(|p| p.iter().map(|x| x.independent).collect())
        .collect();
    Covariance {
        directions: pairs
            .iter()
            .map(|p| {
                let (i, o) = (p.incident, p.outgoing);
                [i.theta_deg, i.phi_deg, o.theta_deg, o.phi_deg]
            })
            .collect(),
        sources,
        independent,
        coefficients,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two samples on two channels: the sources are per channel, in key order; each
    /// sample's coefficients sit under its channel's sources, zero elsewhere; its σ
    /// is the independent part and the coefficients in quadrature.
    #[test]
    fn sources_are_per_channel_and_the_sigma_adds_up() {
        let p = |ind: f64, shared: Vec<(Shared, f64)>| Parts {
            independent: ind,
            read: None,
            shared,
        };
        let parts = vec![
            vec![
                p(3.0, vec![(Shared::Calibration, 4.0)]),
                p(1.0, vec![(Shared::DarkX, 2.0), (Shared::DarkY, -2.0)]),
            ],
            vec![
                p(
                    1.0,
                    vec![
                        (Shared::DriftReference(1), -0.5),
                        (Shared::Calibration, 1.0),
                    ],
                ),
                p(2.0, vec![(Shared::DarkX, -1.0)]),
            ],
        ];
        let c = covariance(&[], &parts);
        let labels: Vec<(usize, &str)> = c
            .sources
            .iter()
            .map(|s| (s.channel, s.label.as_str()))
            .collect();
        assert_eq!(
            labels,
            [
                (0, "calibration scale"),
                (0, "drift reference 2"),
                (1, "dark X"),
                (1, "dark Y"),
            ]
        );
        assert_eq!(c.coefficients[0], [4.0, 0.0, 2.0, -2.0]);
        assert_eq!(c.coefficients[1], [1.0, -0.5, -1.0, 0.0]);
        assert_eq!(c.sigma(0, 0), 5.0);
        assert_eq!(c.sigma(0, 1), 3.0);
        assert_eq!(c.sigma(1, 1), 5f64.sqrt());
    }
}
