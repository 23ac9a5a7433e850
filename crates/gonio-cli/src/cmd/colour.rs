//! `gonio colour`: spectra in a CSV file turned into CIE XYZ, chromaticity and sRGB
//! (`gonio_core::colour`, `docs/colour.md`).

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_core::colour::{Adaptation, ColourError};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// The most bytes a spectra file may have: 64 MiB, thousands of spectra at 1 nm.
const MAX_SPECTRA_BYTES: u64 = 64 << 20;

/// The wavelength column's name.
const WAVELENGTH: &str = "wavelength_nm";

/// `gonio colour`: CIE XYZ, xy and sRGB of spectra.
#[derive(clap::Args)]
pub struct ColourArgs {
    /// A CSV file: a `wavelength_nm` column (uniform 1, 5 or 10 nm, covering at least
    /// 400–700 nm) and one column per spectrum (reflectance factor, or BRDF in 1/sr).
    /// Blank lines and lines starting with `#` are skipped.
    input: PathBuf,
    #[command(flatten)]
    conditions: ConditionFlags,
    #[command(flatten)]
    json: JsonFlag,
}

/// The viewing conditions of a colour conversion (`gonio colour`, and spectral data
/// in `gonio export --format merl` and `gonio plot --colour srgb`).
#[derive(Clone, Debug, clap::Args)]
pub struct ConditionFlags {
    /// Colour conversion: the CIE illuminant, D65, D50, A or E.
    #[arg(long, default_value = "D65")]
    illuminant: String,
    /// Colour conversion: the CIE observer, 1931 (2°) or 1964 (10°).
    #[arg(long, default_value = "1931")]
    observer: String,
    /// Colour conversion: chromatic adaptation to the sRGB white before the sRGB
    /// matrix, bradford or none.
    #[arg(long, default_value = "bradford")]
    adaptation: String,
}

impl ConditionFlags {
    /// The conditions, checked: a bad name is bad input.
    pub fn conversion(&self) -> CliResult<gonio_io::rgb::Conversion> {
        Ok(gonio_io::rgb::Conversion {
            illuminant: self
                .illuminant
                .parse()
                .map_err(|e| CliError::Input(format!("--illuminant: {e}")))?,
            observer: self
                .observer
                .parse()
                .map_err(|e| CliError::Input(format!("--observer: {e}")))?,
            adaptation: self
                .adaptation
                .parse()
                .map_err(|e| CliError::Input(format!("--adaptation: {e}")))?,
        })
    }
}

/// The spectra of a file: the wavelengths, then each column's name, values and the
/// 1-based line of each row.
struct Spectra {
    wavelengths: Vec<f64>,
    lines: Vec<usize>,
    columns: Vec<(String, Vec<f64>)>,
}

/// `FILE:LINE: field `NAME`: MESSAGE`, the form every input error takes.
fn at(
    path: &Path,
    line: Option<usize>,
    field: Option<&str>,
    msg: impl std::fmt::Display,
) -> CliError {
    struct Located<'a>(&'a Path, Option<usize>, Option<&'a str>, String);
    impl std::fmt::Display for Located<'_> {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            gonio_core::text::write_located(f, Some(self.0), "", self.1, None, self.2, &self.3)
        }
    }
    CliError::Input(Located(path, line, field, msg.to_string()).to_string())
}

fn read_spectra(path: &Path) -> CliResult<Spectra> {
    let bytes = gonio_core::input::read_bounded(path, MAX_SPECTRA_BYTES)
        .map_err(|e| CliError::Input(e.to_string()))?;
    parse_spectra(path, &bytes)
}

/// The spectra of a file's bytes; `path` names it in messages.
fn parse_spectra(path: &Path, bytes: &[u8]) -> CliResult<Spectra> {
    let text = std::str::from_utf8(gonio_core::text::strip_bom_bytes(bytes))
        .map_err(|_| at(path, None, None, "not UTF-8 text"))?;
    let mut rows = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hline, header) = rows.next().ok_or_else(|| {
        at(
            path,
            None,
            None,
            "no header line (expected `wavelength_nm,NAME,…`)",
        )
    })?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let Some(wcol) = names.iter().position(|n| *n == WAVELENGTH) else {
        return Err(at(
            path,
            Some(hline),
            None,
            format!("no `{WAVELENGTH}` column in the header {header:?}"),
        ));
    };
    for (i, n) in names.iter().enumerate() {
        if n.is_empty() {
            return Err(at(
                path,
                Some(hline),
                None,
                format!("column {} has no name", i + 1),
            ));
        }
        if names[..i].contains(n) {
            return Err(at(path, Some(hline), Some(n), "named twice"));
        }
    }
    if names.len() < 2 {
        return Err(at(
            path,
            Some(hline),
            None,
            "no spectrum columns after `wavelength_nm`",
        ));
    }
    let mut s = Spectra {
        wavelengths: Vec::new(),
        lines: Vec::new(),
        columns: names
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != wcol)
            .map(|(_, n)| (n.to_string(), Vec::new()))
            .collect(),
    };
    for (line, row) in rows {
        let fields: Vec<&str> = row.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(at(
                path,
                Some(line),
                None,
                format!("{} fields, the header has {}", fields.len(), names.len()),
            ));
        }
        let mut col = 0;
        for (i, f) in fields.iter().enumerate() {
            let v: f64 = f
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    at(
                        path,
                        Some(line),
                        Some(names[i]),
                        format!("{f:?} is not a finite number"),
                    )
                })?;
            if i == wcol {
                s.wavelengths.push(v);
            } else {
                s.columns[col].1.push(v);
                col += 1;
            }
        }
        s.lines.push(line);
    }
    if s.wavelengths.is_empty() {
        return Err(at(path, None, None, "no data rows after the header"));
    }
    Ok(s)
}

/// The input error for a spectrum the colorimeter refused, at the line it concerns.
fn colour_error(path: &Path, s: &Spectra, name: &str, e: ColourError) -> CliError {
    let line_of = |w: f64| {
        s.wavelengths
            .iter()
            .position(|x| *x == w)
            .map(|i| s.lines[i])
    };
    match e {
        ColourError::Spacing { to_nm, .. } => at(path, line_of(to_nm), Some(WAVELENGTH), e),
        ColourError::BadWavelength { index, .. } => {
            at(path, s.lines.get(index).copied(), Some(WAVELENGTH), e)
        }
        ColourError::NotFinite { wavelength_nm, .. } => {
            at(path, line_of(wavelength_nm), Some(name), e)
        }
        ColourError::Coverage { .. } => at(path, None, Some(WAVELENGTH), e),
        e => at(path, None, Some(name), e),
    }
}

/// What `gonio colour` computes: each spectrum's colour under the conditions.
pub(crate) struct Colours {
    input: PathBuf,
    /// The first and last wavelengths, nm.
    range_nm: (f64, f64),
    conversion: gonio_io::rgb::Conversion,
    white: gonio_core::colour::Xyz,
    colours: Vec<(String, gonio_core::colour::Colour)>,
}

impl Colours {
    fn adaptation_name(&self) -> &'static str {
        match self.conversion.adaptation {
            Adaptation::Bradford => "bradford",
            Adaptation::None => "none",
        }
    }

    /// The `--json` object.
    pub(crate) fn json(&self) -> serde_json::Value {
        let spectra: Vec<_> = self
            .colours
            .iter()
            .map(|(name, c)| {
                json!({
                    "name": name,
                    "X": c.xyz.x,
                    "Y": c.xyz.y,
                    "Z": c.xyz.z,
                    "x": c.xy.map(|p| p.0),
                    "y": c.xy.map(|p| p.1),
                    "srgb_linear": c.srgb_linear,
                    "srgb": c.srgb,
                    "srgb8": c.srgb8,
                })
            })
            .collect();
        let w = &self.white;
        json!({
            "input": self.input.display().to_string(),
            "illuminant": self.conversion.illuminant.name(),
            "observer": self.conversion.observer.name(),
            "adaptation": self.adaptation_name(),
            "white": {"X": w.x, "Y": w.y, "Z": w.z},
            "spectra": spectra,
        })
    }
}

/// The colours of the spectra `a` names, or of `text` (a spectra file's contents
/// from memory, which the input word then only names in messages).
pub(crate) fn compute(a: &ColourArgs, text: Option<&str>) -> CliResult<Colours> {
    let conv = a.conditions.conversion()?;
    let path = a.input.as_path();
    let spectra = match text {
        Some(t) => parse_spectra(path, t.as_bytes())?,
        None => read_spectra(path)?,
    };
    let c = conv.colorimeter();
    let mut colours = Vec::with_capacity(spectra.columns.len());
    for (name, values) in &spectra.columns {
        let colour = c
            .colour(&spectra.wavelengths, values)
            .map_err(|e| colour_error(path, &spectra, name, e))?;
        colours.push((name.clone(), colour));
    }
    let w = &spectra.wavelengths;
    Ok(Colours {
        input: a.input.clone(),
        range_nm: (w[0], w[w.len() - 1]),
        white: c.white(),
        conversion: conv,
        colours,
    })
}

/// `gonio colour FILE.csv [--illuminant D65] [--observer 1931] [--adaptation bradford]
/// [--json]`.
pub fn run(a: ColourArgs) -> CliResult<()> {
    let c = compute(&a, None)?;
    if a.json.json {
        return output::json(&c.json());
    }
    let (path, out) = (c.input.as_path(), &c.colours);
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: {} spectra, {}–{} nm; illuminant {}, {} observer, adaptation {} \
             (Y = 1 for a perfect white; BRDF input gives Y in 1/sr)",
            path.display(),
            out.len(),
            c.range_nm.0,
            c.range_nm.1,
            c.conversion.illuminant,
            c.conversion.observer.title(),
            c.adaptation_name(),
        )?;
        let width = out
            .iter()
            .map(|(n, _)| n.chars().count())
            .max()
            .unwrap_or(4)
            .max(4);
        writeln!(
            w,
            "{:width$}  {:>9} {:>9} {:>9}  {:>7} {:>7}  {:>8} {:>8} {:>8}  sRGB",
            "name", "X", "Y", "Z", "x", "y", "R lin", "G lin", "B lin"
        )?;
        for (name, c) in out.iter() {
            let (x, y) = match c.xy {
                Some((x, y)) => (format!("{x:.5}"), format!("{y:.5}")),
                None => ("-".into(), "-".into()),
            };
            let [r, g, b] = c.srgb8;
            writeln!(
                w,
                "{name:width$}  {:>9.6} {:>9.6} {:>9.6}  {x:>7} {y:>7}  {:>8.5} {:>8.5} {:>8.5}  #{r:02x}{g:02x}{b:02x}",
                c.xyz.x, c.xyz.y, c.xyz.z, c.srgb_linear[0], c.srgb_linear[1], c.srgb_linear[2],
            )?;
        }
        w.flush()
    })())
}
