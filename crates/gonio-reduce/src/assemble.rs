//! The last step: the channels' values gathered into the run's samples, each
//! with its σ (the quadrature sum of its budget's terms) and, in a spectral run,
//! the wavelength term ([`crate::spectral`]); a pair missing a channel is left
//! out and counted. With the channels' reports, they make the [`Reduction`].

use gonio_core::Channels;
use gonio_process::reduction::{BudgetTerm, ChannelReport, Report};
use gonio_process::{Sample, Samples};

use crate::budget::median_max;
use crate::correlations::{self, Parts, Shared};
use crate::spectral::{self, Bandpass};
use crate::values::{PerPair, Values};
use crate::{N_TERMS, POSITION, Reduction, Run, WAVELENGTH, position};

/// The reduction of the run: its samples, and its report of the channels'
/// `reports`. `Err` when no sample was reduced.
pub(crate) fn reduction(
    run: &Run,
    channels: Channels,
    values: Values,
    mut reports: Vec<ChannelReport>,
) -> Result<Reduction, String> {
    let unmeasured = run.groups.unmeasured();
    let Values {
        pairs,
        mut rejected,
        max_pos,
        ..
    } = values;
    let bandpass = run.bandpass.as_ref();
    let (samples, budget, parts, incomplete) =
        samples(pairs.into_values(), bandpass, &channels, run.isotropic);
    if incomplete > 0 {
        rejected.insert("missing-channel".into(), incomplete);
    }
    spectral_terms(&mut reports, &samples, &budget, bandpass, &channels);
    position_terms(&mut reports, &samples, &budget, max_pos);
    if samples.is_empty() {
        return Err("no sample readings to reduce".into());
    }
    let pairs_of = |s: &[Sample]| s.iter().map(|x| x.pair).collect::<Vec<_>>();
    let covariance = correlations::covariance(&pairs_of(&samples), &parts);
    Ok(Reduction {
        samples: Samples {
            channels,
            samples,
            isotropic: run.isotropic,
        },
        report: Report {
            channels: reports,
            solid_angle_sr: run.omega,
            rejected,
            max_position_error_deg: max_pos,
            unmeasured,
            capped: run.capped,
        },
        budget,
        detector: run.detector,
        covariance,
    })
}

/// The samples of the pairs with a value in every channel, each with its budget
/// and its parts ([`crate::correlations`]) per channel (the wavelength term filled
/// in by `bandpass` in a spectral run, the position term from the samples'
/// neighbours: [`crate::position`]), and the number of pairs left out for a
/// missing channel.
#[allow(clippy::type_complexity)]
fn samples(
    pairs: impl Iterator<Item = PerPair>,
    bandpass: Option<&Bandpass>,
    channels: &Channels,
    isotropic: bool,
) -> (
    Vec<Sample>,
    Vec<Vec<[f64; N_TERMS]>>,
    Vec<Vec<Parts>>,
    usize,
) {
    let mut samples = Vec::new();
    let mut budget = Vec::new();
    let mut all_parts = Vec::new();
    let mut incomplete = 0;
    for (pair, v, fl) in pairs {
        if v.iter().any(Option::is_none) {
            incomplete += 1;
            continue;
        }
        let mut value = Vec::new();
        let mut terms: Vec<[f64; N_TERMS]> = Vec::new();
        let mut parts: Vec<Parts> = Vec::new();
        for (f, t, p) in v.into_iter().flatten() {
            value.push(f);
            terms.push(t);
            parts.push(p);
        }
        if let (Some(b), Channels::Wavelengths(w)) = (bandpass, channels) {
            wavelength_terms(b, w, &value, &mut terms, &mut parts);
        }
        samples.push(Sample {
            pair,
            value,
            sigma: None,
            flags: fl,
        });
        budget.push(terms);
        all_parts.push(parts);
    }
    let pairs: Vec<_> = samples.iter().map(|s| s.pair).collect();
    let values: Vec<Vec<f64>> = samples.iter().map(|s| s.value.clone()).collect();
    let reads: Vec<Vec<_>> = all_parts
        .iter()
        .map(|p| p.iter().map(|x| x.read).collect())
        .collect();
    let position = position::sigmas(&pairs, &values, &reads, isotropic);
    for (((s, terms), parts), pos) in samples
        .iter_mut()
        .zip(&mut budget)
        .zip(&mut all_parts)
        .zip(position)
    {
        for ((t, p), x) in terms.iter_mut().zip(parts.iter_mut()).zip(pos) {
            t[POSITION] = x;
            p.independent = p.independent.hypot(x);
        }
        s.sigma = Some(
            terms
                .iter()
                .map(|t| t.iter().map(|x| x * x).sum::<f64>().sqrt())
                .collect(),
        );
    }
    (samples, budget, all_parts, incomplete)
}

/// A spectral pair's wavelength terms ([`Bandpass::terms`]), into its budget and,
/// as one shared error per wavelength, its parts: one scale error moves every
/// sample of a wavelength the way its spectrum slopes there.
fn wavelength_terms(
    b: &Bandpass,
    w: &[f64],
    value: &[f64],
    terms: &mut [[f64; N_TERMS]],
    parts: &mut [Parts],
) {
    let slopes = b.slopes(w, value);
    for (((t, p), x), slope) in terms
        .iter_mut()
        .zip(parts)
        .zip(b.terms(w, value))
        .zip(slopes)
    {
        t[WAVELENGTH] = x;
        let sign = if slope < 0.0 { -1.0 } else { 1.0 };
        if x != 0.0 {
            p.shared.push((Shared::Wavelength, sign * x));
        }
    }
}

/// Adds the position term ([`crate::position`]) to each channel's report: its
/// median and largest value relative to the samples' f.
fn position_terms(
    reports: &mut [ChannelReport],
    samples: &[Sample],
    budget: &[Vec<[f64; N_TERMS]>],
    max_pos: f64,
) {
    for (c, report) in reports.iter_mut().enumerate() {
        let rels = samples
            .iter()
            .zip(budget)
            .filter(|(s, _)| s.value[c] > 0.0)
            .map(|(s, t)| t[c][POSITION] / s.value[c])
            .collect();
        let (rel_median, rel_max) = median_max(rels);
        report.budget.push(BudgetTerm {
            term: crate::POSITION_TERM,
            source: format!(
                "the read-back directions' offsets from the nominal ones (largest {max_pos:.1e}°) times the BRDF's slope there, from the neighbouring samples (central differences of ln f)"
            ),
            correlation: "independent",
            rel_median,
            rel_max,
        });
    }
}

/// Adds the wavelength term to each channel's report of a spectral run of two
/// wavelengths or more: its median and largest value relative to the samples' f.
fn spectral_terms(
    reports: &mut [ChannelReport],
    samples: &[Sample],
    budget: &[Vec<[f64; N_TERMS]>],
    bandpass: Option<&Bandpass>,
    channels: &Channels,
) {
    let (Some(b), Channels::Wavelengths(w)) = (bandpass, channels) else {
        return;
    };
    if w.len() < 2 {
        return;
    }
    for (c, report) in reports.iter_mut().enumerate() {
        let rels = samples
            .iter()
            .zip(budget)
            .filter(|(s, _)| s.value[c] > 0.0)
            .map(|(s, t)| t[c][WAVELENGTH] / s.value[c])
            .collect();
        let (rel_median, rel_max) = median_max(rels);
        report.budget.push(BudgetTerm {
            term: spectral::TERM,
            source: b.source(),
            correlation: spectral::CORRELATION,
            rel_median,
            rel_max,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gonio_core::SphericalDeg;
    use gonio_core::dirfile::PairDeg;

    /// A complete pair's σ is the quadrature sum of its terms (3, 4: 5); a pair
    /// missing a channel is counted, not reduced; the flags carry over.
    #[test]
    fn complete_pairs_become_samples_with_their_quadrature_sigma() {
        let pair = PairDeg {
            incident: SphericalDeg::new(0.0, 0.0),
            outgoing: SphericalDeg::new(30.0, 0.0),
        };
        let mut terms = [0.0; N_TERMS];
        terms[0] = 3.0;
        terms[2] = 4.0;
        let pairs: Vec<PerPair> = vec![
            (pair, vec![Some((0.5, terms, Parts::default()))], 7),
            (pair, vec![None], 0),
        ];
        let (samples, budget, _, incomplete) =
            samples(pairs.into_iter(), None, &Channels::Single, true);
        assert_eq!(incomplete, 1);
        assert_eq!(samples.len(), 1);
        assert_eq!(samples[0].value, [0.5]);
        assert_eq!(samples[0].sigma, Some(vec![5.0]));
        assert_eq!(samples[0].flags, 7);
        assert_eq!(budget, [vec![terms]]);
    }
}
