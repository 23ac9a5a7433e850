//! The k-separable representation of a tabulated BRDF (DeYoung Sec. 4.2.4 and 5.1.4):
//! f(ωi, ωo) = Σ_j f_in^(j)(φi, θi) · f_out^(j)(φo, θo), with f_in^(j) = d_jj u^(j)
//! (Eq. 5.13) and f_out^(j) = v^(j) (Eq. 5.14) from the SVD of the matrix A of
//! Eq. 4.13. It is a compressed BRDF in its own right: k·(P + Q) numbers instead of
//! P·Q, evaluated by bilinear interpolation of each factor (the product of two
//! bilinear interpolants is the quadrilinear interpolant of A^(k), so evaluation at
//! the nodes is exactly A^(k) and between them matches [`Table::eval_angles`] on it).
//!
//! When the table carries uncertainties, the factors minimise the weighted error
//! Σ w_pq (A_pq − A^(k)_pq)² with w = σ_min²/σ² — the weighting Ch. 5 asks for — by
//! the expectation–maximisation iteration for weighted low-rank approximation
//! (Srebro & Jaakkola 2003): fill A's less certain entries from the current
//! approximation, take the rank-k SVD, repeat. Without uncertainties it is the plain
//! truncated SVD, the optimum in the Frobenius norm (Eckart–Young).

use faer::Mat;
use serde::{Deserialize, Serialize};

use std::path::Path;

use gonio_core::tomlfile::{self, FileError};
use gonio_core::{Channels, Dir};

use crate::measure::{full_form, matrix};
use crate::{Axis, Grid, ProcessError, Table};

/// Iterations of the weighted (EM) factorisation at most, and its stopping rule on
/// the relative change of A^(k) between iterations.
const EM_ITERATIONS: usize = 500;
const EM_TOLERANCE: f64 = 1e-10;

/// One separated component of one channel: f_in^(j) over the incident nodes (φi, θi)
/// and f_out^(j) over the outgoing nodes (φo, θo), both lexicographic.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Term {
    /// f_in^(j) = d_jj u^(j), Eq. 5.13 (P values).
    #[serde(rename = "in")]
    pub f_in: Vec<f64>,
    /// f_out^(j) = v^(j), Eq. 5.14 (Q values).
    #[serde(rename = "out")]
    pub f_out: Vec<f64>,
}

/// A k-separable BRDF.
#[derive(Clone, Debug, PartialEq)]
pub struct SeparableBrdf {
    /// The channels.
    pub channels: Channels,
    /// The 4D grid the factors live on.
    pub grid: Grid,
    /// Components per channel.
    pub k: usize,
    /// `terms[ch][j]`.
    pub terms: Vec<Vec<Term>>,
    /// The iterations the weighted factorisation took per channel (0: plain SVD).
    pub iterations: Vec<usize>,
}

/// The rank-k approximation of `a` from a thin SVD: (U_k D_k, V_k).
fn truncated(a: &Mat<f64>, k: usize) -> Result<(Mat<f64>, Mat<f64>), ProcessError> {
    let (s, u, v) = crate::svd::thin(a.as_ref())?;
    let k = k.min(a.nrows()).min(a.ncols());
    let us = Mat::from_fn(a.nrows(), k, |r, j| u[(r, j)] * s[j]);
    let vk = Mat::from_fn(a.ncols(), k, |c, j| v[(c, j)]);
    Ok((us, vk))
}

/// The rank-k factors of `a`, weighted by `w` (entries in (0, 1]) when given.
pub(crate) fn factor(
    a: &Mat<f64>,
    w: Option<&Mat<f64>>,
    k: usize,
) -> Result<(Mat<f64>, Mat<f64>, usize), ProcessError> {
    let (mut us, mut vk) = truncated(a, k)?;
    let Some(w) = w else {
        return Ok((us, vk, 0));
    };
    let mut approx = &us * vk.transpose();
    for it in 1..=EM_ITERATIONS {
        let filled = Mat::from_fn(a.nrows(), a.ncols(), |r, c| {
            w[(r, c)] * a[(r, c)] + (1.0 - w[(r, c)]) * approx[(r, c)]
        });
        (us, vk) = truncated(&filled, k)?;
        let next = &us * vk.transpose();
        let change = (&next - &approx).norm_l2();
        let size = next.norm_l2().max(f64::MIN_POSITIVE);
        approx = next;
        if change <= EM_TOLERANCE * size {
            return Ok((us, vk, it));
        }
    }
    Ok((us, vk, EM_ITERATIONS))
}

/// The weights w = σ_min²/σ² of one channel's matrix, when every σ is positive.
pub(crate) fn weights(t: &Table, ch: usize) -> Option<Mat<f64>> {
    let s = t.channel_sigma(ch)?;
    if s.iter().any(|x| x.is_nan() || *x <= 0.0) {
        return None;
    }
    let min = s.iter().copied().fold(f64::INFINITY, f64::min);
    let q = t.grid.n_out();
    Some(Mat::from_fn(t.grid.n_in(), q, |r, c| {
        (min / s[r * q + c]).powi(2)
    }))
}

impl SeparableBrdf {
    /// Separates a table into k components per channel (an isotropic table is first
    /// expanded over a full turn of φi). `weighted` uses the table's uncertainties.
    pub fn from_table(t: &Table, k: usize, weighted: bool) -> Result<SeparableBrdf, ProcessError> {
        if k == 0 {
            return Err(ProcessError::Value("k must be at least 1".into()));
        }
        let full = full_form(t)?;
        let mut terms = Vec::new();
        let mut iterations = Vec::new();
        for ch in 0..full.channels.len() {
            let a = matrix(&full, ch);
            let w = if weighted { weights(&full, ch) } else { None };
            let (us, vk, it) = factor(&a, w.as_ref(), k)?;
            iterations.push(it);
            terms.push(
                (0..us.ncols())
                    .map(|j| Term {
                        f_in: (0..us.nrows()).map(|r| us[(r, j)]).collect(),
                        f_out: (0..vk.nrows()).map(|c| vk[(c, j)]).collect(),
                    })
                    .collect(),
            );
        }
        Ok(SeparableBrdf {
            channels: full.channels.clone(),
            grid: full.grid,
            k,
            terms,
            iterations,
        })
    }

    /// Numbers stored, k·(P + Q) per channel (Eq. 4.12 for k = 1).
    pub fn stored_values(&self) -> usize {
        self.terms
            .iter()
            .flatten()
            .map(|t| t.f_in.len() + t.f_out.len())
            .sum()
    }

    /// Storage against the table it came from, k(P + Q)/(PQ); DeYoung reports 4.4 % for
    /// k = 5 on his velvet BRDF (Sec. 5.2).
    pub fn storage_ratio(&self) -> f64 {
        self.stored_values() as f64 / (self.grid.len() * self.channels.len()) as f64
    }

    /// Channel `ch` at angles (φi, θi, φo, θo), radians: Σ_j f_in^(j) f_out^(j), each
    /// factor bilinear between its nodes.
    pub fn eval_angles(&self, ch: usize, ang: [f64; 4]) -> f64 {
        let g = &self.grid;
        let bilinear = |pa: &Axis, ta: &Axis, v: &[f64], p: f64, t: f64| {
            let (a0, a1, wa) = pa.locate(p);
            let (b0, b1, wb) = ta.locate(t);
            let at = |a: usize, b: usize| v[a * ta.n + b];
            (1.0 - wa) * ((1.0 - wb) * at(a0, b0) + wb * at(a0, b1))
                + wa * ((1.0 - wb) * at(a1, b0) + wb * at(a1, b1))
        };
        self.terms[ch]
            .iter()
            .map(|t| {
                bilinear(&g.phi_i, &g.theta_i, &t.f_in, ang[0], ang[1])
                    * bilinear(&g.phi_o, &g.theta_o, &t.f_out, ang[2], ang[3])
            })
            .sum()
    }

    /// All channels at a pair of directions.
    pub fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        let ang = [wi.phi(), wi.theta(), wo.phi(), wo.theta()];
        for (ch, o) in out.iter_mut().enumerate() {
            *o = self.eval_angles(ch, ang);
        }
    }

    /// The table A^(k) the factors reconstruct (Eq. 4.19).
    pub fn to_table(&self) -> Result<Table, ProcessError> {
        let (p, q) = (self.grid.n_in(), self.grid.n_out());
        let n = p * q;
        let mut values = vec![0.0; n * self.channels.len()];
        for (ch, terms) in self.terms.iter().enumerate() {
            for t in terms {
                for r in 0..p {
                    let a = t.f_in[r];
                    let row = &mut values[ch * n + r * q..ch * n + (r + 1) * q];
                    for (x, b) in row.iter_mut().zip(&t.f_out) {
                        *x += a * b;
                    }
                }
            }
        }
        Table::new(self.channels.clone(), self.grid, values, None)
    }

    /// The separable file (TOML): `kind = "separable"`, channels, k, the grid in
    /// degrees, and per channel its terms.
    pub fn to_toml(&self) -> String {
        let file = SepFile {
            kind: "separable".into(),
            channels: self.channels.names(),
            k: self.k,
            grid: GridFile::from(&self.grid),
            channel: self
                .terms
                .iter()
                .enumerate()
                .map(|(ch, terms)| ChannelFile {
                    name: self.channels.name(ch),
                    term: terms.clone(),
                })
                .collect(),
        };
        toml::to_string(&file).unwrap_or_else(|e| format!("# could not serialise: {e}\n"))
    }

    /// Reads a separable file strictly (unknown keys are errors); errors name the line
    /// and field at fault. `path` only labels errors.
    pub fn from_toml(text: &str, path: Option<&Path>) -> Result<SeparableBrdf, FileError> {
        const KIND: &str = "separable file";
        let f: SepFile = tomlfile::parse(KIND, text, path, SepFile::check)?;
        let channels = Channels::from_names(&f.channels)
            .map_err(|e| FileError::at_field(KIND, path, text, "channels".into(), e.to_string()))?;
        let grid = f
            .grid
            .to_grid()
            .map_err(|e| FileError::at_field(KIND, path, text, "grid".into(), e.to_string()))?;
        let bad = |field: String, msg: String| FileError::at_field(KIND, path, text, field, msg);
        if f.channel.len() != channels.len() {
            return Err(bad(
                "channel".into(),
                format!(
                    "{} channel blocks for {} channels",
                    f.channel.len(),
                    channels.len()
                ),
            ));
        }
        for (ch, c) in f.channel.iter().enumerate() {
            if c.term.len() != f.k {
                return Err(bad(
                    format!("channel[{ch}].term"),
                    format!("{} terms, k = {}", c.term.len(), f.k),
                ));
            }
            for (j, t) in c.term.iter().enumerate() {
                if t.f_in.len() != grid.n_in() || t.f_out.len() != grid.n_out() {
                    return Err(bad(
                        format!("channel[{ch}].term[{j}]"),
                        format!(
                            "in/out have {}/{} values, the grid needs {}/{}",
                            t.f_in.len(),
                            t.f_out.len(),
                            grid.n_in(),
                            grid.n_out()
                        ),
                    ));
                }
            }
        }
        Ok(SeparableBrdf {
            channels,
            grid,
            k: f.k,
            terms: f.channel.into_iter().map(|c| c.term).collect(),
            iterations: Vec::new(),
        })
    }
}

impl gonio_brdf::Brdf for SeparableBrdf {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        SeparableBrdf::eval(self, wi, wo, out);
    }

    fn proposals(&self, _wi: Dir, out: &mut Vec<gonio_brdf::Weighted>) {
        crate::grid::cosine_proposal(out);
    }

    fn is_reciprocal(&self) -> bool {
        false
    }
}

/// A grid axis in a file, degrees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct AxisFile {
    pub start: f64,
    pub step: f64,
    pub n: usize,
}

/// A grid in a file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GridFile {
    pub isotropic: bool,
    pub phi_i: AxisFile,
    pub theta_i: AxisFile,
    pub phi_o: AxisFile,
    pub theta_o: AxisFile,
}

impl From<&Grid> for GridFile {
    fn from(g: &Grid) -> GridFile {
        let a = |x: &Axis| AxisFile {
            start: x.start.to_degrees(),
            step: x.step.to_degrees(),
            n: x.n,
        };
        GridFile {
            isotropic: g.isotropic,
            phi_i: a(&g.phi_i),
            theta_i: a(&g.theta_i),
            phi_o: a(&g.phi_o),
            theta_o: a(&g.theta_o),
        }
    }
}

impl GridFile {
    pub(crate) fn to_grid(&self) -> Result<Grid, ProcessError> {
        let a = |x: &AxisFile| Axis::from_deg(x.start, x.step, x.n);
        let g = Grid {
            phi_i: a(&self.phi_i),
            theta_i: a(&self.theta_i),
            phi_o: a(&self.phi_o),
            theta_o: a(&self.theta_o),
            isotropic: self.isotropic,
        };
        g.validate()?;
        Ok(g)
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ChannelFile {
    name: String,
    term: Vec<Term>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SepFile {
    kind: String,
    channels: Vec<String>,
    k: usize,
    grid: GridFile,
    channel: Vec<ChannelFile>,
}

impl SepFile {
    fn check(&self) -> Result<(), (String, String)> {
        if self.kind != "separable" {
            return Err((
                "kind".into(),
                format!("expected \"separable\", found {:?}", self.kind),
            ));
        }
        if self.k == 0 {
            return Err(("k".into(), "must be at least 1".into()));
        }
        for (ch, c) in self.channel.iter().enumerate() {
            for (j, t) in c.term.iter().enumerate() {
                if t.f_in.iter().chain(&t.f_out).any(|x| !x.is_finite()) {
                    return Err((
                        format!("channel[{ch}].term[{j}]"),
                        "values must be finite".into(),
                    ));
                }
                if t.f_in
                    .iter()
                    .chain(&t.f_out)
                    .any(|x| x.abs() > crate::MAX_MAGNITUDE)
                {
                    return Err((
                        format!("channel[{ch}].term[{j}]"),
                        format!(
                            "values must be at most {:e} in magnitude",
                            crate::MAX_MAGNITUDE
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}
