//! Surface files (`SURFACE.toml`): a microgeometry, its facet materials and the
//! channels, read strictly with errors that name the file, line and field.
//!
//! ```toml
//! channels = ["R", "G", "B"]
//!
//! [surface]
//! kind = "gaussian"            # gaussian | sawtooth (alias v-grooves) | cylinders | height-map
//! size = [256, 256]            # cells
//! spacing = 1.0                # lattice spacing (any length unit; only ratios matter)
//! rms_height = 0.9
//! correlation_length = 6.0     # of the autocorrelation σ² exp(−r²/l²)
//! seed = 1
//! material = "gold"
//! orientation_deg = 0.0        # optional, every kind: the patch turned about the normal
//!
//! [materials.gold]
//! kind = "conductor"           # mirror | conductor | dielectric | lambert | model
//! n = [0.18, 0.43, 1.37]
//! k = [3.42, 2.45, 1.80]
//! ```
//!
//! The other kinds:
//! - `sawtooth` / `v-grooves`: `period` (default 1), `angles_deg = [a, b]` — the tilts
//!   of the face facing +x and of the face facing −x — and `faces = ["m0", "m1"]`, their
//!   materials (DeYoung Fig. 2.3). Ridges run along y before `orientation_deg` turns
//!   them.
//! - `cylinders`: `radius`, `spacing` (between axes), `cells_per_period` (default 64),
//!   `material`; the axes run along x (the brushing direction) before
//!   `orientation_deg` turns them.
//! - `height-map`: `file` (relative to the surface file's directory), `spacing`,
//!   `format = "csv"` (one row of heights a line, x along the row, separated by commas
//!   or white space; `#` comments) or `"f64le"` / `"f32le"` (raw little-endian, with
//!   `size = [nx, ny]`), `height_scale` (default 1), `material`.
//!
//! Materials: `mirror` (`reflectance`, default 1 in every channel), `conductor` (`n`,
//! `k`), `dielectric` (`eta`), `lambert` (`albedo`), `model` (`file`, a gonio-brdf model
//! file relative to the surface file, with the same channels). Every numeric material
//! parameter is a list with one value a channel (`docs/CONVENTIONS.md`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_core::Channels;
use gonio_core::limits::Range;
use gonio_core::tomlfile::{self, FileError, Tagged};
use serde::Deserialize;

use crate::heightfield::GaussianParams;
use crate::{HeightField, Material, MicroError};

const KIND: &str = "surface file";

/// Lengths of a surface file (`spacing`, `correlation_length`, `period`, `radius`) in
/// its own unit: only ratios matter in geometric optics, so any unit works, but
/// nothing beyond nine orders of magnitude either way.
pub const LENGTH: Range = Range::closed(1e-9, 1e9, "");
/// The largest continuum RMS slope `2σ/l` of a Gaussian surface: 100, so
/// `rms_height` is at most 50 × `correlation_length` (facets at 89.4° on average).
pub const MAX_RMS_SLOPE: f64 = 100.0;
/// `orientation_deg`: a turn either way.
pub const ORIENTATION: Range = Range::closed(-360.0, 360.0, "deg");
/// A height map's `height_scale`.
pub const HEIGHT_SCALE: Range = Range::closed(-1e6, 1e6, "");
/// Refractive indices (`n` of a conductor, `eta` of a dielectric).
pub const INDEX: Range = Range::positive(100.0, "");
/// A conductor's extinction coefficient `k`.
pub const EXTINCTION: Range = Range::closed(0.0, 100.0, "");

/// The most bytes a height-map file may have: 1 GiB, a 2^27-node `f64le` map (a
/// 11 585 × 11 585 lattice) or a CSV map of about 10^8 heights.
pub const MAX_HEIGHT_MAP_BYTES: u64 = 1 << 30;

/// A microgeometry sample: the height field, the material of each material id, the
/// channels, and the turn of the patch about the normal.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// The channels every energy and BRDF value has.
    pub channels: Channels,
    /// The microgeometry.
    pub surface: HeightField,
    /// The material of each id the surface uses (`materials[id]`).
    pub materials: Vec<Material>,
    /// The patch's turn about the normal, radians: a direction at azimuth φ in the
    /// sample frame is at φ − orientation in the height field's frame.
    pub orientation: f64,
}

impl Sample {
    /// Checks that every material id of the surface has a material and every material
    /// one value a channel.
    pub fn new(
        channels: Channels,
        surface: HeightField,
        materials: Vec<Material>,
        orientation: f64,
    ) -> Result<Sample, MicroError> {
        if (surface.max_material() as usize) >= materials.len() {
            return Err(MicroError::invalid(
                "materials",
                format!(
                    "the surface uses material id {} but {} materials were given",
                    surface.max_material(),
                    materials.len()
                ),
            ));
        }
        for (i, m) in materials.iter().enumerate() {
            check_material(m, &channels)
                .map_err(|(f, why)| MicroError::invalid(format!("materials[{i}].{f}"), why))?;
        }
        if !orientation.is_finite() {
            return Err(MicroError::invalid("orientation", "must be finite"));
        }
        Ok(Sample {
            channels,
            surface,
            materials,
            orientation,
        })
    }

    /// Reads a surface file (see the module docs): a regular file of at most
    /// [`MAX_CONFIG_BYTES`](gonio_core::input::MAX_CONFIG_BYTES).
    pub fn load(path: &Path) -> Result<Sample, MicroError> {
        let text = tomlfile::read(KIND, path)?;
        Sample::from_toml(&text, Some(path))
    }

    /// Parses a surface file's text; `path` labels errors and anchors the relative
    /// paths of height maps and model files (the current directory without it).
    pub fn from_toml(text: &str, path: Option<&Path>) -> Result<Sample, MicroError> {
        let doc: Doc = tomlfile::parse(KIND, text, path, |_| Ok(()))?;
        let r = Reading {
            text,
            path,
            dir: path
                .and_then(Path::parent)
                .map(Path::to_path_buf)
                .unwrap_or_default(),
        };
        let channels =
            Channels::from_names(&doc.channels).map_err(|e| r.at("channels", e.to_string()))?;
        let mut m = Materials {
            by_name: r.materials(&doc, &channels)?,
            used: Vec::new(),
        };
        let (surface, orient) = match &doc.surface {
            SurfaceSpec::Gaussian(g) => r.gaussian(g, &mut m)?,
            SurfaceSpec::Sawtooth(s) => r.sawtooth(s, &mut m)?,
            SurfaceSpec::Cylinders(c) => r.cylinders(c, &mut m)?,
            SurfaceSpec::HeightMap(h) => r.height_map(h, &mut m)?,
        };
        Sample::new(channels, surface, m.used, orient)
    }
}

/// What every step of reading a surface file needs: its text and path, for errors
/// that name the field and its line, and the directory relative paths start from.
struct Reading<'a> {
    text: &'a str,
    path: Option<&'a Path>,
    dir: PathBuf,
}

/// The materials by name, and those the surface picks, in order: a material's index
/// in the sample is its place in `used`.
struct Materials<'a> {
    by_name: BTreeMap<&'a str, Material>,
    used: Vec<Material>,
}

impl Materials<'_> {
    /// The index of the material `name` (named by `field`), now used.
    fn pick(&mut self, r: &Reading<'_>, name: &str, field: &str) -> Result<u8, MicroError> {
        let m = self.by_name.get(name).ok_or_else(|| {
            r.at(
                field,
                format!("no material named {name:?} under [materials]"),
            )
        })?;
        self.used.push(m.clone());
        Ok((self.used.len() - 1) as u8)
    }
}

impl Reading<'_> {
    /// The error at `field`, with its line in the text.
    fn at(&self, field: &str, msg: String) -> MicroError {
        FileError::at_field(KIND, self.path, self.text, field.to_string(), msg).into()
    }

    /// A length in [`LENGTH`].
    fn length(&self, v: f64, field: &str) -> Result<f64, MicroError> {
        LENGTH.check(v).map_err(|m| self.at(field, m))
    }

    /// The surface's orientation, radians (0 without one).
    fn orientation(&self, o: Option<f64>) -> Result<f64, MicroError> {
        ORIENTATION
            .check(o.unwrap_or(0.0))
            .map(f64::to_radians)
            .map_err(|m| self.at("surface.orientation_deg", m))
    }

    /// The `[materials]`, by name, each checked against the channels (a model file's
    /// read and its channels matched).
    fn materials<'d>(
        &self,
        doc: &'d Doc,
        channels: &Channels,
    ) -> Result<BTreeMap<&'d str, Material>, MicroError> {
        let nc = channels.len();
        let mut by_name: BTreeMap<&str, Material> = BTreeMap::new();
        for (name, spec) in &doc.materials {
            let f = |k: &str| format!("materials.{name}.{k}");
            let m = match spec {
                MaterialSpec::Mirror(MirrorSpec { reflectance }) => Material::Mirror {
                    reflectance: reflectance.clone().unwrap_or_else(|| vec![1.0; nc]),
                },
                MaterialSpec::Conductor(ConductorSpec { n, k }) => Material::Conductor {
                    n: n.clone(),
                    k: k.clone(),
                },
                MaterialSpec::Dielectric(DielectricSpec { eta }) => {
                    Material::Dielectric { eta: eta.clone() }
                }
                MaterialSpec::Lambert(LambertSpec { albedo }) => Material::Lambert {
                    albedo: albedo.clone(),
                },
                MaterialSpec::Model(ModelSpec { file }) => {
                    let p = self.dir.join(file);
                    let model = Model::load(&p).map_err(|e| MicroError::Model {
                        surface: self
                            .path
                            .map_or_else(|| format!("<{KIND}>"), |p| p.display().to_string()),
                        field: f("file"),
                        source: Box::new(e),
                    })?;
                    if model.channels() != channels {
                        return Err(self.at(
                            &f("file"),
                            format!(
                                "the model {} has channels {:?}, the surface {:?}",
                                p.display(),
                                model.channels().names(),
                                channels.names()
                            ),
                        ));
                    }
                    Material::Model(Box::new(model))
                }
            };
            check_material(&m, channels).map_err(|(k, why)| self.at(&f(&k), why))?;
            by_name.insert(name.as_str(), m);
        }
        Ok(by_name)
    }

    /// A Gaussian random surface: its size, spacing and correlation length in range, its
    /// RMS height within the slope the simulation holds, and its generation within
    /// the work limit.
    fn gaussian(
        &self,
        GaussianSpec {
            size,
            spacing,
            rms_height,
            correlation_length,
            seed,
            material,
            orientation_deg,
        }: &GaussianSpec,
        mats: &mut Materials<'_>,
    ) -> Result<(HeightField, f64), MicroError> {
        let spacing = self.length(spacing.unwrap_or(1.0), "surface.spacing")?;
        if size[0] < 2 || size[1] < 2 || size[0].saturating_mul(size[1]) > 1 << 26 {
            return Err(self.at(
                "surface.size",
                "needs at least 2 × 2 and at most 2^26 cells".into(),
            ));
        }
        let l = self.length(*correlation_length, "surface.correlation_length")?;
        let max_rms = 0.5 * MAX_RMS_SLOPE * l;
        Range::closed(0.0, max_rms, "")
            .check(*rms_height)
            .map_err(|m| {
                let why = if rms_height.is_finite() {
                    format!(
                        "{m} (at most {} × correlation_length: an RMS slope 2σ/l of \
                         at most {MAX_RMS_SLOPE})",
                        0.5 * MAX_RMS_SLOPE
                    )
                } else {
                    m
                };
                self.at("surface.rms_height", why)
            })?;
        let work = crate::heightfield::gaussian_work(size[0], size[1], l / spacing);
        if work.is_nan() || work > crate::heightfield::MAX_GAUSSIAN_WORK {
            return Err(self.at(
                "surface.correlation_length",
                format!(
                    "a correlation of {} cells on {} × {} cells takes {work:.2e} \
                     kernel products to generate, more than 2^34; shorten it or the \
                     size",
                    gonio_core::limits::num(l / spacing),
                    size[0],
                    size[1],
                ),
            ));
        }
        mats.pick(self, material, "surface.material")?;
        let hf = HeightField::gaussian(&GaussianParams {
            nx: size[0],
            ny: size[1],
            spacing,
            rms_height: *rms_height,
            correlation_length: l,
            seed: *seed,
        })
        .map_err(|e| self.at("surface", e.to_string()))?;
        Ok((hf, self.orientation(*orientation_deg)?))
    }

    /// A sawtooth of two faces, each tilted between 1° and 89°.
    fn sawtooth(
        &self,
        SawtoothSpec {
            period,
            angles_deg,
            faces,
            orientation_deg,
        }: &SawtoothSpec,
        mats: &mut Materials<'_>,
    ) -> Result<(HeightField, f64), MicroError> {
        let period = self.length(period.unwrap_or(1.0), "surface.period")?;
        for a in angles_deg {
            if !(a.is_finite() && (1.0..=89.0).contains(a)) {
                return Err(self.at(
                    "surface.angles_deg",
                    format!("face tilts must be between 1° and 89°, got {a}"),
                ));
            }
        }
        mats.pick(self, &faces[0], "surface.faces")?;
        mats.pick(self, &faces[1], "surface.faces")?;
        let hf = HeightField::sawtooth(
            period,
            angles_deg[0].to_radians(),
            angles_deg[1].to_radians(),
        )
        .map_err(|e| self.at("surface", e.to_string()))?;
        Ok((hf, self.orientation(*orientation_deg)?))
    }

    /// Parallel cylinders: radius, spacing and cells per period in range.
    fn cylinders(
        &self,
        CylindersSpec {
            radius,
            spacing,
            cells_per_period,
            material,
            orientation_deg,
        }: &CylindersSpec,
        mats: &mut Materials<'_>,
    ) -> Result<(HeightField, f64), MicroError> {
        let r = self.length(*radius, "surface.radius")?;
        let s = self.length(*spacing, "surface.spacing")?;
        let cells = cells_per_period.unwrap_or(64);
        if !(4..=1 << 20).contains(&cells) {
            return Err(self.at(
                "surface.cells_per_period",
                format!("must be in 4..=2^20, got {cells}"),
            ));
        }
        mats.pick(self, material, "surface.material")?;
        let hf =
            HeightField::cylinders(r, s, cells).map_err(|e| self.at("surface", e.to_string()))?;
        Ok((hf, self.orientation(*orientation_deg)?))
    }

    /// A height map read from a file (CSV, or raw `f64le`/`f32le` of a given size),
    /// scaled.
    fn height_map(
        &self,
        HeightMapSpec {
            file,
            spacing,
            format,
            size,
            height_scale,
            material,
            orientation_deg,
        }: &HeightMapSpec,
        mats: &mut Materials<'_>,
    ) -> Result<(HeightField, f64), MicroError> {
        let spacing = self.length(*spacing, "surface.spacing")?;
        let scale = HEIGHT_SCALE
            .check(height_scale.unwrap_or(1.0))
            .map_err(|m| self.at("surface.height_scale", m))?;
        let fmt = format.as_deref().unwrap_or("csv");
        if !["csv", "f64le", "f32le"].contains(&fmt) {
            return Err(self.at(
                "surface.format",
                format!("unknown format {fmt:?} (csv, f64le or f32le)"),
            ));
        }
        if fmt != "csv" && size.is_none() {
            return Err(self.at(
                "surface.size",
                format!("the {fmt} format needs size = [nx, ny]"),
            ));
        }
        mats.pick(self, material, "surface.material")?;
        let p = self.dir.join(file);
        let (nx, ny, mut h) = read_height_map(&p, fmt, *size)?;
        h.iter_mut().for_each(|v| *v *= scale);
        let hf =
            HeightField::new(nx, ny, spacing, spacing, h).map_err(|e| MicroError::HeightMap {
                path: p.clone(),
                line: None,
                message: e.to_string(),
            })?;
        Ok((hf, self.orientation(*orientation_deg)?))
    }
}

/// Checks one material's per-channel lists; `Err((field, why))`.
fn check_material(m: &Material, channels: &Channels) -> Result<(), (String, String)> {
    let nc = channels.len();
    let list = |name: &str, v: &[f64], ok: &dyn Fn(f64) -> bool, what: &str| {
        if v.len() != nc {
            return Err((
                name.to_string(),
                format!("{} values for {nc} channels", v.len()),
            ));
        }
        match v.iter().position(|x| !ok(*x)) {
            Some(i) => Err((
                name.to_string(),
                format!("value {i} ({}) {what}", gonio_core::limits::num(v[i])),
            )),
            None => Ok(()),
        }
    };
    let unit = |x: f64| (0.0..=1.0).contains(&x);
    match m {
        Material::Mirror { reflectance } => {
            list("reflectance", reflectance, &unit, "must be in [0, 1]")
        }
        Material::Lambert { albedo } => list("albedo", albedo, &unit, "must be in [0, 1]"),
        Material::Conductor { n, k } => {
            list("n", n, &|x| INDEX.contains(x), "must be in (0, 100]")?;
            list("k", k, &|x| EXTINCTION.contains(x), "must be in [0, 100]")
        }
        Material::Dielectric { eta } => {
            list("eta", eta, &|x| INDEX.contains(x), "must be in (0, 100]")
        }
        Material::Model(m) => {
            if m.channels() == channels {
                Ok(())
            } else {
                Err((
                    "file".into(),
                    "the model's channels differ from the surface's".into(),
                ))
            }
        }
    }
}

fn read_height_map(
    path: &Path,
    fmt: &str,
    size: Option<[usize; 2]>,
) -> Result<(usize, usize, Vec<f64>), MicroError> {
    let err = |line: Option<usize>, message: String| MicroError::HeightMap {
        path: path.to_path_buf(),
        line,
        message,
    };
    let bytes = gonio_core::input::read_bounded(path, MAX_HEIGHT_MAP_BYTES)
        .map_err(|e| err(None, e.reason()))?;
    if fmt == "csv" {
        let text = String::from_utf8(bytes).map_err(|_| err(None, "not UTF-8 text".into()))?;
        let mut rows: Vec<Vec<f64>> = Vec::new();
        let mut first_line = 0;
        for (k, line) in gonio_core::text::strip_bom(&text).lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let mut row = Vec::new();
            for tok in line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|t| !t.is_empty())
            {
                let v: f64 = tok
                    .parse()
                    .map_err(|_| err(Some(k + 1), format!("{tok:?} is not a number")))?;
                if !v.is_finite() {
                    return Err(err(Some(k + 1), format!("{tok:?} is not finite")));
                }
                row.push(v);
            }
            if let Some(r0) = rows.first()
                && r0.len() != row.len()
            {
                return Err(err(
                    Some(k + 1),
                    format!(
                        "{} heights, but line {} has {}",
                        row.len(),
                        first_line,
                        r0.len()
                    ),
                ));
            }
            if rows.is_empty() {
                first_line = k + 1;
            }
            rows.push(row);
        }
        let ny = rows.len();
        let nx = rows.first().map_or(0, Vec::len);
        if nx == 0 {
            return Err(err(None, "no heights".into()));
        }
        if let Some([sx, sy]) = size
            && (sx, sy) != (nx, ny)
        {
            return Err(err(
                None,
                format!("{nx} × {ny} heights, but size = [{sx}, {sy}]"),
            ));
        }
        return Ok((nx, ny, rows.concat()));
    }
    let [nx, ny] = size.unwrap_or([0, 0]);
    let w = if fmt == "f64le" { 8 } else { 4 };
    let want = nx.saturating_mul(ny).saturating_mul(w);
    if nx == 0 || ny == 0 || bytes.len() != want {
        return Err(err(
            None,
            format!(
                "{} bytes, but {nx} × {ny} {fmt} heights need {want}",
                bytes.len()
            ),
        ));
    }
    let h = bytes
        .chunks_exact(w)
        .map(|c| {
            if w == 8 {
                let mut b = [0u8; 8];
                b.copy_from_slice(c);
                f64::from_le_bytes(b)
            } else {
                let mut b = [0u8; 4];
                b.copy_from_slice(c);
                f64::from(f32::from_le_bytes(b))
            }
        })
        .collect::<Vec<_>>();
    if let Some(k) = h.iter().position(|v| !v.is_finite()) {
        return Err(err(None, format!("height {k} is not finite")));
    }
    Ok((nx, ny, h))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Doc {
    channels: Vec<String>,
    surface: SurfaceSpec,
    #[serde(default)]
    materials: BTreeMap<String, MaterialSpec>,
}

/// The `[surface]` table: one struct a kind, read through [`Tagged`] so that an error
/// in a field names `surface.FIELD` and its line.
enum SurfaceSpec {
    Gaussian(GaussianSpec),
    Sawtooth(SawtoothSpec),
    Cylinders(CylindersSpec),
    HeightMap(HeightMapSpec),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GaussianSpec {
    size: [usize; 2],
    spacing: Option<f64>,
    rms_height: f64,
    correlation_length: f64,
    seed: u64,
    material: String,
    orientation_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SawtoothSpec {
    period: Option<f64>,
    angles_deg: [f64; 2],
    faces: [String; 2],
    orientation_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CylindersSpec {
    radius: f64,
    spacing: f64,
    cells_per_period: Option<usize>,
    material: String,
    orientation_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct HeightMapSpec {
    file: PathBuf,
    spacing: f64,
    format: Option<String>,
    size: Option<[usize; 2]>,
    height_scale: Option<f64>,
    material: String,
    orientation_deg: Option<f64>,
}

impl<'de> Deserialize<'de> for SurfaceSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let t = Tagged::read(d, &["gaussian", "sawtooth", "cylinders", "height-map"])?;
        match t.kind() {
            "gaussian" => t.fields().map(SurfaceSpec::Gaussian),
            "sawtooth" | "v-grooves" => t.fields().map(SurfaceSpec::Sawtooth),
            "cylinders" => t.fields().map(SurfaceSpec::Cylinders),
            "height-map" => t.fields().map(SurfaceSpec::HeightMap),
            _ => Err(t.unknown_kind()),
        }
    }
}

/// A `[materials.NAME]` table, read like [`SurfaceSpec`].
enum MaterialSpec {
    Mirror(MirrorSpec),
    Conductor(ConductorSpec),
    Dielectric(DielectricSpec),
    Lambert(LambertSpec),
    Model(ModelSpec),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MirrorSpec {
    reflectance: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ConductorSpec {
    n: Vec<f64>,
    k: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DielectricSpec {
    eta: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LambertSpec {
    albedo: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelSpec {
    file: PathBuf,
}

impl<'de> Deserialize<'de> for MaterialSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let t = Tagged::read(
            d,
            &["mirror", "conductor", "dielectric", "lambert", "model"],
        )?;
        match t.kind() {
            "mirror" => t.fields().map(MaterialSpec::Mirror),
            "conductor" => t.fields().map(MaterialSpec::Conductor),
            "dielectric" => t.fields().map(MaterialSpec::Dielectric),
            "lambert" => t.fields().map(MaterialSpec::Lambert),
            "model" => t.fields().map(MaterialSpec::Model),
            _ => Err(t.unknown_kind()),
        }
    }
}
