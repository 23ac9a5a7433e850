//! `gonio export`, `gonio plot` and `gonio report`: results in the formats and
//! figures people already use, and the page a lab attaches to a sample.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_io::formats::{self, Data, Format};
use gonio_io::plot::{self, ChannelChoice, Output, Source};
use gonio_io::report::{self, Contents, Figure, Image};
use gonio_process::{Samples, Table, measure};
use gonio_run::RunStore;
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::output;
use crate::process_cmd::{self, Input, ReduceArgs};

fn plot_err(e: plot::PlotError) -> CliError {
    if e.is_input() {
        CliError::Input(e.to_string())
    } else {
        CliError::Runtime(e.to_string())
    }
}

/// `gonio export INPUT --format merl|astm|csv --out FILE`.
pub fn export(
    input: &Path,
    format: &str,
    out: &Path,
    reduction: &ReduceArgs,
    json_out: bool,
) -> CliResult<()> {
    let format = Format::from_name(format)
        .ok_or_else(|| CliError::Input(format!("--format: merl, astm or csv, got {format:?}")))?;
    let (inp, _) = process_cmd::load(input, reduction, None)?;
    let data = match inp {
        Input::Table(t) => Data::Table(t),
        Input::Samples(s) => Data::Samples(s),
        Input::Merl(m) => Data::Merl(*m),
    };
    formats::write_file(format, &data, out).map_err(|e| CliError::Input(e.to_string()))?;
    let bytes = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
    if json_out {
        return output::json(&json!({
            "out": out.display().to_string(),
            "format": format.name(),
            "from": data.kind(),
            "bytes": bytes,
        }));
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(
            w,
            "{}: {} ({} bytes) from {}",
            out.display(),
            format.title(),
            bytes,
            data.kind()
        )?;
        w.flush()
    })())
}

/// The arguments of `gonio plot`.
pub struct PlotArgs {
    /// The input.
    pub input: PathBuf,
    /// A fitted model file.
    pub fit: Option<PathBuf>,
    /// polar, hemisphere, albedo, separability, sphere.
    pub kind: String,
    /// The output (.png or .svg).
    pub out: PathBuf,
    /// Incident polar angles, degrees.
    pub theta_i: Vec<f64>,
    /// A channel by name.
    pub channel: Option<String>,
    /// Light direction (sphere), degrees from the view axis.
    pub light_theta: f64,
    /// Light azimuth (sphere), degrees.
    pub light_phi: f64,
    /// Run-file reduction options.
    pub reduction: ReduceArgs,
}

/// What a plot's input became.
enum Loaded {
    Model(Model),
    Table(Table),
    Samples(Samples),
    Merl(Box<gonio_io::formats::merl::MerlBrdf>),
}

fn load_for_plot(path: &Path, reduction: &ReduceArgs) -> CliResult<Loaded> {
    // A model file is plotted as the model (its terms in the albedo plot).
    if let Ok(text) = std::fs::read_to_string(path)
        && text.lines().map(str::trim).any(|l| l.starts_with("kind"))
        && !text.contains("\"separable\"")
        && !text.contains("\"spherical-harmonics\"")
    {
        return Ok(Loaded::Model(Model::from_toml(&text, Some(path))?));
    }
    Ok(match process_cmd::load(path, reduction, None)?.0 {
        Input::Table(t) => Loaded::Table(t),
        Input::Samples(s) => Loaded::Samples(s),
        Input::Merl(m) => Loaded::Merl(m),
    })
}

impl Loaded {
    fn source(&self) -> Source<'_> {
        match self {
            Loaded::Model(m) => Source::Model(m),
            Loaded::Table(t) => Source::Brdf(t),
            Loaded::Samples(s) => Source::Samples(s),
            Loaded::Merl(m) => Source::Brdf(m.as_ref()),
        }
    }
}

/// `gonio plot INPUT [--fit FIT.toml] --kind … --out FILE.png|svg`.
pub fn plot(a: PlotArgs) -> CliResult<()> {
    let data = load_for_plot(&a.input, &a.reduction)?;
    let fit = match &a.fit {
        Some(p) => Some(Model::from_toml(
            &std::fs::read_to_string(p)
                .map_err(|e| CliError::Input(format!("{}: {e}", p.display())))?,
            Some(p),
        )?),
        None => None,
    };
    let src = data.source();
    let channel = match &a.channel {
        None => ChannelChoice::All,
        Some(name) => ChannelChoice::One(src.channels().index_of(name).ok_or_else(|| {
            CliError::Input(format!(
                "--channel: {name:?} is not one of {}",
                src.channels().names().join(", ")
            ))
        })?),
    };
    let fit_brdf: Option<&dyn Brdf> = fit.as_ref().map(|m| m as &dyn Brdf);
    let out = Output::File(&a.out);
    match a.kind.as_str() {
        "polar" => plot::polar(
            out,
            &src,
            fit_brdf,
            &a.theta_i,
            &plot::PolarOptions {
                channel,
                ..plot::PolarOptions::default()
            },
        ),
        "hemisphere" => plot::hemisphere(
            out,
            &src,
            fit_brdf,
            a.theta_i.first().copied().unwrap_or(30.0),
            &plot::HemisphereOptions {
                channel,
                ..plot::HemisphereOptions::default()
            },
        ),
        "albedo" => plot::albedo(
            out,
            &src,
            fit.as_ref(),
            &plot::AlbedoOptions {
                channel,
                ..plot::AlbedoOptions::default()
            },
        ),
        "separability" => {
            let table = match &data {
                Loaded::Table(t) => t.clone(),
                Loaded::Model(m) => Table::from_brdf(m, gonio_process::Grid::hemisphere(9, 36))
                    .map_err(|e| CliError::Input(e.to_string()))?,
                Loaded::Merl(m) => {
                    Table::from_brdf(m.as_ref(), gonio_process::Grid::hemisphere(9, 36))
                        .map_err(|e| CliError::Input(e.to_string()))?
                }
                Loaded::Samples(_) => {
                    return Err(CliError::Input(format!(
                        "{}: separability needs a table (these samples are not on a grid)",
                        a.input.display()
                    )));
                }
            };
            let name = a
                .input
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            plot::separability(
                out,
                &[(name.as_str(), &table)],
                &[],
                &plot::SeparabilityOptions {
                    channel,
                    ..plot::SeparabilityOptions::default()
                },
            )
        }
        "sphere" => plot::sphere(
            out,
            &src,
            fit_brdf,
            &plot::SphereOptions {
                channel,
                light_theta_deg: a.light_theta,
                light_phi_deg: a.light_phi,
                ..plot::SphereOptions::default()
            },
        ),
        k => {
            return Err(CliError::Input(format!(
                "--kind: polar, hemisphere, albedo, separability or sphere, got {k:?}"
            )));
        }
    }
    .map_err(plot_err)?;
    Ok(())
}

fn svg_of(
    f: impl FnOnce(Output<'_>) -> Result<plot::Drawn, plot::PlotError>,
) -> Result<Image, String> {
    let mut s = String::new();
    f(Output::Svg(&mut s)).map_err(|e| e.to_string())?;
    Ok(Image::Svg(s))
}

/// Colour maps and renderings as PNG: as SVG they are hundreds of kilobytes of
/// rectangles.
fn png_of(
    f: impl FnOnce(Output<'_>) -> Result<plot::Drawn, plot::PlotError>,
) -> Result<Image, String> {
    let mut b = Vec::new();
    f(Output::Png(&mut b)).map_err(|e| e.to_string())?;
    Ok(Image::Png(b))
}

/// `gonio report RUN.gonio --out DIR`: writes DIR/report.html and returns its path.
pub fn report(
    run: &Path,
    out_dir: &Path,
    reduction: &ReduceArgs,
    json_out: bool,
) -> CliResult<PathBuf> {
    let page = build_report(run, reduction)?;
    std::fs::create_dir_all(out_dir).map_err(|e| {
        CliError::Input(format!(
            "{}: cannot create the directory: {e}",
            out_dir.display()
        ))
    })?;
    let path = out_dir.join("report.html");
    std::fs::write(&path, report::html(&page))
        .map_err(|e| CliError::Input(format!("{}: cannot write: {e}", path.display())))?;
    if json_out {
        output::json(&json!({
            "out": path.display().to_string(),
            "figures": page.figures.len(),
            "notes": page.notes,
        }))?;
    } else {
        let mut w = output::open(None)?;
        output::finish((|| {
            writeln!(w, "{}: {} figures", path.display(), page.figures.len())?;
            for n in &page.notes {
                writeln!(w, "note: {n}")?;
            }
            w.flush()
        })())?;
    }
    Ok(path)
}

/// The report's contents for a run file.
pub fn build_report(run: &Path, reduction: &ReduceArgs) -> CliResult<Contents> {
    let store = RunStore::open(run).map_err(|e| {
        if e.is_bad_input() {
            CliError::Input(e.to_string())
        } else {
            CliError::Runtime(e.to_string())
        }
    })?;
    let meta = store.meta().map_err(|e| CliError::Runtime(e.to_string()))?;
    drop(store);
    let (input, red) = process_cmd::load(run, reduction, None)?;
    let mut c = Contents {
        title: format!(
            "Gonio run report: {}",
            meta.get("name")
                .cloned()
                .unwrap_or_else(|| run.display().to_string())
        ),
        ..Contents::default()
    };
    c.metadata
        .push(("run file".into(), run.display().to_string()));
    for k in [
        "status",
        "software",
        "seed",
        "notes",
        "created_s",
        "instrument_path",
        "plan_path",
    ] {
        if let Some(v) = meta.get(k) {
            let v = if k == "created_s" {
                v.parse::<f64>()
                    .map(gonio_run::utc)
                    .unwrap_or_else(|_| v.clone())
            } else {
                v.clone()
            };
            c.metadata.push((k.replace('_', " "), v));
        }
    }
    for (k, name) in [("instrument", "instrument config"), ("plan", "plan")] {
        if let Some(v) = meta.get(k) {
            c.configs.push((name.into(), v.clone()));
        }
    }
    c.reduction = red.as_ref().map(|r| r.report.clone());
    let samples = input.to_samples(200_000);
    c.metadata
        .push(("BRDF samples".into(), samples.samples.len().to_string()));
    let table = match &input {
        Input::Table(t) => Some(t.clone()),
        _ => None,
    };
    match &table {
        Some(t) => c.measures = measure::report(t, &[1, 2, 5], 5).ok(),
        None => c.notes.push(
            "DeYoung's measures need a table: the run's pairs do not form a complete grid \
             (an in-plane scan, or pairs the arms could not reach)."
                .into(),
        ),
    }
    // The lobe fit and the comparison models.
    let data = gonio_fit::FitData::from_samples(&samples, &gonio_fit::DataOptions::default());
    let fitted = match data {
        Ok(d) => {
            let lobes = if d.len() >= 60 { 3 } else { 1 };
            let opts = gonio_fit::FitOptions {
                shape: gonio_fit::Shape {
                    lobes,
                    ..gonio_fit::FitOptions::default().shape
                },
                ..gonio_fit::FitOptions::default()
            };
            match gonio_fit::fit_lobes(&d, &opts) {
                Ok(f) => {
                    for k in gonio_fit::compare::Kind::ALL {
                        if let Ok(rows) = gonio_fit::compare::fit_model(k, &d) {
                            c.comparison.extend(rows);
                        }
                    }
                    let m = f.model.clone();
                    c.fit = Some(f);
                    m
                }
                Err(e) => {
                    c.notes.push(format!("no lobe fit: {e}"));
                    None
                }
            }
        }
        Err(e) => {
            c.notes.push(format!("no lobe fit: {e}"));
            None
        }
    };
    figures(&mut c, &samples, table.as_ref(), fitted.as_ref());
    Ok(c)
}

/// The report's figures; a figure that cannot be drawn becomes a note.
fn figures(c: &mut Contents, samples: &Samples, table: Option<&Table>, fit: Option<&Model>) {
    let data_src = match table {
        Some(t) => Source::Brdf(t),
        None => Source::Samples(samples),
    };
    let fit_brdf: Option<&dyn Brdf> = fit.map(|m| m as &dyn Brdf);
    let mut thetas: Vec<f64> = samples
        .samples
        .iter()
        .map(|s| s.pair.incident.theta_deg)
        .collect();
    thetas.sort_by(f64::total_cmp);
    thetas.dedup();
    if thetas.len() > 4 {
        let n = thetas.len();
        thetas = vec![thetas[0], thetas[n / 3], thetas[2 * n / 3], thetas[n - 1]];
    }
    let mut push = |title: &str, caption: &str, r: Result<Image, String>| match r {
        Ok(image) => c.figures.push(Figure {
            title: title.into(),
            caption: caption.into(),
            image,
        }),
        Err(e) => c.notes.push(format!("{title}: {e}")),
    };
    push(
        "Plane of incidence",
        "f_r in the plane of incidence for the measured incidence angles: the data as points, \
         the lobe fit as lines (Lafortune et al. 1997, Figs. 11 and 13).",
        svg_of(|o| {
            plot::polar(
                o,
                &data_src,
                fit_brdf,
                &thetas,
                &plot::PolarOptions::default(),
            )
        }),
    );
    // The hemisphere, albedo and sphere need the whole hemisphere: the data when it is
    // a table, otherwise the fitted model (said so in the caption).
    let (hemi_src, hemi_fit, who) = match (table, fit) {
        (Some(_), _) => (data_src, fit_brdf, "the data (left) and the fit (right)"),
        (None, Some(m)) => (
            Source::Model(m),
            None,
            "the fitted model (the run's pairs do not cover the hemisphere)",
        ),
        (None, None) => (data_src, None, "the data"),
    };
    let t0 = thetas.get(thetas.len() / 2).copied().unwrap_or(30.0);
    push(
        "Hemisphere",
        &format!(
            "f_r · cos θo over the outgoing hemisphere at θi = {t0}°, {who} (Lafortune Figs. 12, 14)."
        ),
        png_of(|o| {
            plot::hemisphere(
                o,
                &hemi_src,
                hemi_fit,
                t0,
                &plot::HemisphereOptions::default(),
            )
        }),
    );
    let albedo_src = match (table, fit) {
        (None, Some(m)) => Source::Model(m),
        _ => data_src,
    };
    push(
        "Directional albedo",
        "Directional-hemispherical reflectance against θi, total and per term of the lobe fit \
         (Lafortune Figs. 4b, 7b, 9b).",
        svg_of(|o| plot::albedo(o, &albedo_src, fit, &plot::AlbedoOptions::default())),
    );
    if let Some(t) = table {
        push(
            "Separability",
            "P_s^(k) against k (DeYoung Eq. 4.20, Fig. 5.9).",
            svg_of(|o| {
                plot::separability(
                    o,
                    &[("data", t)],
                    &[],
                    &plot::SeparabilityOptions::default(),
                )
            }),
        );
    }
    push(
        "Rendered sphere",
        &format!("A sphere under a directional light at 45° from the view, upper left: {who}."),
        png_of(|o| plot::sphere(o, &hemi_src, hemi_fit, &plot::SphereOptions::default())),
    );
}
