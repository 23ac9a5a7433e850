//! Analytic models (`gonio_brdf::Model`) and RGL materials (`.bsdf`): loaded,
//! evaluated on arrays of directions in parallel, integrated; models written back.

use std::path::PathBuf;

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Dir, SphericalDeg};
use gonio_io::formats::RglBsdf;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;
use rayon::prelude::*;

use crate::errors::{self, Domain};
use crate::interrupt::{self, OnInterrupt};

/// Registers the class.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeModel>()?;
    m.add_class::<NativeBsdf>()?;
    Ok(())
}

/// Pairs evaluated by one task: large enough that scheduling costs nothing.
const CHUNK: usize = 4096;

/// A model: the parsed model and the TOML it was read from.
#[pyclass(frozen, module = "gonio._native", name = "NativeModel")]
pub struct NativeModel {
    /// The model.
    pub model: Model,
}

fn model_err(e: gonio_brdf::ModelError) -> PyErr {
    errors::to_py(e.into(), Domain::Config, None)
}

#[pymethods]
impl NativeModel {
    /// Reads a model file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<NativeModel> {
        let model = py.detach(|| Model::load(&path)).map_err(model_err)?;
        Ok(NativeModel { model })
    }

    /// Parses model TOML; `label` names it in errors.
    #[staticmethod]
    #[pyo3(signature = (text, label = None))]
    fn from_toml(text: &str, label: Option<PathBuf>) -> PyResult<NativeModel> {
        let model = Model::from_toml(text, label.as_deref()).map_err(model_err)?;
        Ok(NativeModel { model })
    }

    /// The model file's text.
    fn to_toml(&self) -> String {
        self.model.to_toml()
    }

    /// The model's kind (`lafortune`, `ward`, …).
    fn kind(&self) -> &'static str {
        self.model.kind().name()
    }

    /// The channel names.
    fn channels(&self) -> Vec<String> {
        self.model.channels().names()
    }

    /// f_r (1/sr) at the pairs of equal-length angle arrays (degrees), as an
    /// `(n, channels)` array; the pairs are shared among `threads` threads.
    #[pyo3(signature = (theta_i, phi_i, theta_o, phi_o, threads = None))]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        theta_i: PyReadonlyArray1<'py, f64>,
        phi_i: PyReadonlyArray1<'py, f64>,
        theta_o: PyReadonlyArray1<'py, f64>,
        phi_o: PyReadonlyArray1<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        eval_pairs(&self.model, py, [theta_i, phi_i, theta_o, phi_o], threads)
    }

    /// Directional albedo at each incident polar angle (degrees) at azimuth `phi_i`:
    /// an `(n, channels)` array (any ideal mirror term included).
    #[pyo3(signature = (theta_i, phi_i = 0.0))]
    fn albedo<'py>(
        slf: Bound<'py, Self>,
        theta_i: Vec<f64>,
        phi_i: f64,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        albedo_of(slf, |m: &NativeModel| &m.model, theta_i, phi_i)
    }
}

/// An RGL material (`.bsdf`), evaluated as Mitsuba 3's `measured` plugin does.
#[pyclass(frozen, module = "gonio._native", name = "NativeBsdf")]
pub struct NativeBsdf {
    /// The material.
    pub bsdf: RglBsdf,
}

#[pymethods]
impl NativeBsdf {
    /// Reads a `.bsdf` file (any input `gonio` opens that is an RGL material).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<NativeBsdf> {
        let opened = py
            .detach(|| gonio_dataset::open(&path, &gonio_dataset::OpenOptions::default()))
            .map_err(|e| errors::input(e.to_string()))?;
        match opened.data {
            gonio_dataset::Dataset::Rgl(bsdf) => Ok(NativeBsdf { bsdf: *bsdf }),
            d => Err(errors::input(format!(
                "{}: a {}, not an RGL material",
                path.display(),
                d.describe()
            ))),
        }
    }

    /// The file's `description`.
    fn description(&self) -> String {
        self.bsdf.description.clone()
    }

    /// The channel names.
    fn channels(&self) -> Vec<String> {
        self.bsdf.channels().names()
    }

    /// True when the file holds one incidence azimuth.
    fn isotropic(&self) -> bool {
        self.bsdf.is_isotropic()
    }

    /// The file's node pairs as an `(n, 4)` array of θi, φi, θo, φo (degrees).
    fn node_pairs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let pairs = self.bsdf.node_pairs();
        let mut out = Vec::with_capacity(4 * pairs.len());
        for (wi, wo) in &pairs {
            let (i, o) = (SphericalDeg::from(*wi), SphericalDeg::from(*wo));
            out.extend([i.theta_deg, i.phi_deg, o.theta_deg, o.phi_deg]);
        }
        let array = numpy::ndarray::Array2::from_shape_vec((pairs.len(), 4), out)
            .map_err(|e| errors::input(e.to_string()))?;
        Ok(array.into_pyarray(py))
    }

    /// As `NativeModel.eval`.
    #[pyo3(signature = (theta_i, phi_i, theta_o, phi_o, threads = None))]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        theta_i: PyReadonlyArray1<'py, f64>,
        phi_i: PyReadonlyArray1<'py, f64>,
        theta_o: PyReadonlyArray1<'py, f64>,
        phi_o: PyReadonlyArray1<'py, f64>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        eval_pairs(&self.bsdf, py, [theta_i, phi_i, theta_o, phi_o], threads)
    }

    /// As `NativeModel.albedo` (integrated numerically over the material's values).
    #[pyo3(signature = (theta_i, phi_i = 0.0))]
    fn albedo<'py>(
        slf: Bound<'py, Self>,
        theta_i: Vec<f64>,
        phi_i: f64,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        albedo_of(slf, |b: &NativeBsdf| &b.bsdf, theta_i, phi_i)
    }
}

/// f_r of `brdf` at the pairs of equal-length angle arrays (degrees), as an
/// `(n, channels)` array; the pairs are shared among `threads` threads.
fn eval_pairs<'py>(
    brdf: &dyn Brdf,
    py: Python<'py>,
    [theta_i, phi_i, theta_o, phi_o]: [PyReadonlyArray1<'py, f64>; 4],
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = theta_i.len()?;
    if [phi_i.len()?, theta_o.len()?, phi_o.len()?] != [n, n, n] {
        return Err(errors::input(
            "theta_i, phi_i, theta_o, phi_o: arrays of one length",
        ));
    }
    let nc = brdf.channels().len();
    let (ti, pi, to, po) = (
        theta_i.as_slice()?,
        phi_i.as_slice()?,
        theta_o.as_slice()?,
        phi_o.as_slice()?,
    );
    let fill = |out: &mut [f64]| {
        out.par_chunks_mut(CHUNK * nc)
            .enumerate()
            .for_each(|(c, block)| {
                for (k, row) in block.chunks_mut(nc).enumerate() {
                    let j = c * CHUNK + k;
                    let d = PairDeg {
                        incident: SphericalDeg::new(ti[j], pi[j]),
                        outgoing: SphericalDeg::new(to[j], po[j]),
                    }
                    .to_dirs();
                    brdf.eval(d.wi, d.wo, row);
                }
            });
    };
    let mut out = vec![0.0; n * nc];
    py.detach(|| match threads {
        Some(t) => rayon::ThreadPoolBuilder::new()
            .num_threads(t.max(1))
            .build()
            .map(|p| p.install(|| fill(&mut out)))
            .map_err(|e| e.to_string()),
        None => {
            fill(&mut out);
            Ok(())
        }
    })
    .map_err(errors::input)?;
    let array = numpy::ndarray::Array2::from_shape_vec((n, nc), out)
        .map_err(|e| errors::input(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

/// The directional albedo of the BRDF `get` gives of `slf`, at each incident polar
/// angle (degrees) at azimuth `phi_i`, interruptibly.
fn albedo_of<'py, T>(
    slf: Bound<'py, T>,
    get: fn(&T) -> &dyn Brdf,
    theta_i: Vec<f64>,
    phi_i: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>>
where
    T: pyo3::PyClass<Frozen = pyo3::pyclass::boolean_struct::True> + Sync + Send,
{
    let py = slf.py();
    if let Some(t) = theta_i.iter().find(|t| !(0.0..=90.0).contains(*t)) {
        return Err(errors::input(format!(
            "theta_i: {t} is outside [0, 90] degrees"
        )));
    }
    if !phi_i.is_finite() {
        return Err(errors::input(format!(
            "phi_i: {phi_i} is not a finite angle"
        )));
    }
    let this: Py<T> = slf.unbind();
    let n = theta_i.len();
    let nc = get(this.get()).channels().len();
    let values = interrupt::run(py, None, OnInterrupt::Abandon, move || {
        let model = get(this.get());
        theta_i
            .par_iter()
            .flat_map_iter(|t| {
                let mut a = vec![0.0; nc];
                model.albedo(Dir::from(SphericalDeg::new(*t, phi_i)), &mut a);
                a
            })
            .collect::<Vec<f64>>()
    })?;
    let array = numpy::ndarray::Array2::from_shape_vec((n, nc), values)
        .map_err(|e| errors::input(e.to_string()))?;
    Ok(array.into_pyarray(py))
}
