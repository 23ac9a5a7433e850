//! A simulated run against its truth: the run file of a simulated acquisition keeps
//! the sample the simulator measured, so the reduction can say how far its values
//! lie from that sample's BRDF in the units it states — per sample and against the
//! full covariance ([`gonio_process::covariance`]) — and which shared error moved
//! the run.

use gonio_brdf::{Brdf, Model};
use gonio_core::Channels;
use gonio_process::covariance::Agreement;

use crate::Reduction;

/// The truth of a simulated run: the simulator's sample model (its text, as the run
/// file keeps it). `None` for a laboratory run, or a simulated sample that is a table
/// rather than a model file.
pub fn simulated_sample(sim_sample: Option<&str>) -> Option<Model> {
    Model::from_toml(sim_sample?, None).ok()
}

/// The model's value at every sample of `red`, per channel of the reduction: the
/// model's own channel where the names agree, a single-channel model's one value
/// for every channel, else (wavelength channels) linear interpolation between the
/// model's wavelengths, held beyond them. `None` when the channels cannot be
/// matched.
pub fn truth(red: &Reduction, model: &Model) -> Option<Vec<Vec<f64>>> {
    let mc = model.channels();
    let rc = &red.samples.channels;
    let nc = rc.len();
    let pick: Vec<Pick> = (0..nc)
        .map(|c| {
            let name = rc.name(c);
            if let Some(i) = mc.index_of(&name) {
                Some(Pick::Own(i))
            } else if mc.len() == 1 {
                Some(Pick::Own(0))
            } else {
                match (mc, rc) {
                    (Channels::Wavelengths(m), Channels::Wavelengths(r)) => {
                        Some(Pick::Between(m.to_vec(), r[c]))
                    }
                    _ => None,
                }
            }
        })
        .collect::<Option<_>>()?;
    let mut out = vec![0.0; mc.len()];
    Some(
        red.samples
            .samples
            .iter()
            .map(|s| {
                let d = s.pair.to_dirs();
                model.eval(d.wi, d.wo, &mut out);
                pick.iter().map(|p| p.value(&out)).collect()
            })
            .collect(),
    )
}

/// Where a reduction's channel takes its truth from the model's values.
enum Pick {
    /// The model's channel of this index.
    Own(usize),
    /// Interpolated between the model's wavelengths (nm) at this one.
    Between(Vec<f64>, f64),
}

impl Pick {
    fn value(&self, out: &[f64]) -> f64 {
        match self {
            Pick::Own(i) => out[*i],
            Pick::Between(w, nm) => {
                let k = w.partition_point(|x| x < nm);
                if k == 0 {
                    out[0]
                } else if k >= w.len() {
                    out[w.len() - 1]
                } else {
                    let t = (nm - w[k - 1]) / (w[k] - w[k - 1]);
                    out[k - 1] + t * (out[k] - out[k - 1])
                }
            }
        }
    }
}

/// Every channel of `red` against `truth` ([`truth`]): per-sample and full χ²/n,
/// the mean z, and the shared sources' shifts ([`Agreement`]).
pub fn agreements(red: &Reduction, truth: &[Vec<f64>]) -> Vec<Agreement> {
    (0..red.samples.channels.len())
        .filter_map(|c| {
            let r: Vec<f64> = red
                .samples
                .samples
                .iter()
                .zip(truth)
                .map(|(s, t)| s.value[c] - t[c])
                .collect();
            red.covariance.agreement(c, &r)
        })
        .collect()
}
