//! `gonio report`: the run's one self-contained HTML page — metadata, calibration,
//! measures, fit and plots.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_io::plot::{self, Output, Source};
use gonio_io::report::{self, Contents, Figure, Image};
use gonio_plan::StepKind;
use gonio_process::{Samples, Table, measure};
use gonio_run::{DecisionRecord, RunStore};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::{JsonFlag, ReduceFlags};
use crate::output;

/// `gonio report`: write the run report.
#[derive(clap::Args)]
pub struct ReportArgs {
    /// The run file.
    run: PathBuf,
    /// The directory to write report.html into.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: output::ForceFlag,
    #[command(flatten)]
    reduction: ReduceFlags,
    #[command(flatten)]
    json: JsonFlag,
}

impl ReportArgs {
    /// Checks every flag's value without reading the input: what a batch does
    /// before it starts any task.
    pub(crate) fn check_values(&self) -> CliResult<()> {
        self.reduction.options().map(drop)
    }
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

/// Writes DIR/report.html as `gonio report RUN.gonio --out DIR` does: the `--json`
/// object, and the page's contents.
pub(crate) fn write(a: &ReportArgs) -> CliResult<(serde_json::Value, Contents)> {
    let (run, out_dir) = (a.run.as_path(), a.out.as_path());
    let path = out_dir.join("report.html");
    // Checked before the work when the directory exists; it is made only after.
    if out_dir.exists() {
        output::Target::new(&path, a.force.force)?;
    }
    let page = build_report(run, &a.reduction)?;
    std::fs::create_dir_all(out_dir).map_err(|e| {
        CliError::Input(format!(
            "{}: cannot create the directory: {e}",
            out_dir.display()
        ))
    })?;
    output::Target::new(&path, a.force.force)?.write(report::html(&page).as_bytes())?;
    let json = json!({
        "out": path.display().to_string(),
        "figures": page.figure_count(),
        "notes": page.notes,
    });
    Ok((json, page))
}

/// The page `gonio report` writes, made in memory: nothing is written, `--out`
/// not even checked.
pub(crate) fn page(a: &ReportArgs) -> CliResult<(serde_json::Value, String)> {
    let page = build_report(&a.run, &a.reduction)?;
    let json = json!({
        "figures": page.figure_count(),
        "notes": page.notes,
    });
    Ok((json, report::html(&page)))
}

/// `gonio report RUN.gonio --out DIR`: writes DIR/report.html and prints its path.
pub fn run(a: ReportArgs) -> CliResult<()> {
    let (json, page) = write(&a)?;
    if a.json.json {
        output::json(&json)?;
    } else {
        let path = a.out.join("report.html");
        let mut w = output::stdout();
        output::finish((|| {
            writeln!(w, "{}: {} figures", path.display(), page.figure_count())?;
            for n in &page.notes {
                writeln!(w, "note: {n}")?;
            }
            w.flush()
        })())?;
    }
    Ok(())
}

/// The report's contents for a run file.
pub fn build_report(run: &Path, reduction: &ReduceFlags) -> CliResult<Contents> {
    // Examined before SQLite opens it: a FIFO would hold the open forever.
    gonio_core::input::regular_file(run).map_err(|e| CliError::Input(e.to_string()))?;
    let store = RunStore::open_read_only(run)?;
    let meta = store.meta().map_err(|e| CliError::Runtime(e.to_string()))?;
    let adaptive = adaptive_record(&store);
    drop(store);
    let opened = gonio_dataset::open(run, &reduction.open_options()?)?;
    let red = opened.reduction.as_ref();
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
    match adaptive {
        Ok(Some(rec)) => c.adaptive = Some(adaptive_part(rec, &mut c.notes)),
        Ok(None) => {}
        Err(e) => c.notes.push(format!(
            "the adaptive run's decisions could not be read: {e}"
        )),
    }
    // Each key with a label that says what its value is (a key's own name, such as
    // `created_s`, is not a label: the value shown is a UTC date, not seconds).
    for (k, label) in [
        ("status", "status"),
        ("software", "software"),
        ("seed", "random seed"),
        ("notes", "notes"),
        ("created_s", "created (UTC)"),
        ("instrument_path", "instrument config file"),
        ("plan_path", "plan file"),
    ] {
        if let Some(v) = meta.get(k) {
            let v = if k == "created_s" {
                v.parse::<f64>()
                    .map(gonio_run::utc)
                    .unwrap_or_else(|_| v.clone())
            } else {
                v.clone()
            };
            c.metadata.push((label.into(), v));
        }
    }
    for (k, name) in [("instrument", "instrument config"), ("plan", "plan")] {
        if let Some(v) = meta.get(k) {
            c.configs.push((name.into(), v.clone()));
        }
    }
    c.reduction = red.map(|r| r.report.clone());
    let samples = opened.data.to_samples(200_000, run)?;
    c.metadata
        .push(("BRDF samples".into(), samples.samples.len().to_string()));
    // The measures take the table every command takes (a half turn unfolded, the
    // run's own grid), and the energy measure the samples themselves.
    let table = match opened.data.tabulate(None, run) {
        Ok(tab) => {
            c.metadata
                .push(("symmetry assumed".into(), tab.symmetry.describe().into()));
            if let Some(f) = &tab.fill
                && !f.interpolated.is_empty()
            {
                c.notes.push(format!(
                    "The measures use the run's own grid: {} of its {} nodes were not \
                     measured (the detector shadows the source near retro-reflection) and \
                     were interpolated from their neighbours.",
                    f.interpolated.len(),
                    f.nodes
                ));
            }
            c.measures =
                measure::report_with(&tab.table, tab.measured.as_ref(), &[1, 2, 5], 5).ok();
            Some(tab.table)
        }
        Err(e) => {
            c.notes.push(format!(
                "DeYoung's measures need data over the hemisphere: {e}"
            ));
            None
        }
    };
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

/// A sample direction and its batch (0 = the coarse pass).
type BatchPoint = (usize, PairDeg);

/// What the run file holds of an adaptive run's choices.
struct AdaptiveRecord {
    decisions: Vec<DecisionRecord>,
    /// Every sample point with its batch (0 = the coarse pass).
    points: Vec<BatchPoint>,
    /// The sample directions with at least one reading done, as the bits of their
    /// four angles (the same numbers the steps were stored with).
    measured: BTreeSet<[u64; 4]>,
}

fn pair_key(p: &PairDeg) -> [u64; 4] {
    [
        p.incident.theta_deg.to_bits(),
        p.incident.phi_deg.to_bits(),
        p.outgoing.theta_deg.to_bits(),
        p.outgoing.phi_deg.to_bits(),
    ]
}

/// The decisions and the points by batch; `None` for a run without decisions (its
/// schedule was all fixed at creation).
fn adaptive_record(store: &RunStore) -> Result<Option<AdaptiveRecord>, String> {
    let decisions = store.decisions().map_err(|e| e.to_string())?;
    if decisions.is_empty() {
        return Ok(None);
    }
    let points = gonio_reduce::adaptive::points_by_batch(store).map_err(|e| e.to_string())?;
    let measured = store
        .steps()
        .map_err(|e| e.to_string())?
        .iter()
        .filter(|s| s.step.kind == StepKind::Sample && s.state == "done")
        .filter_map(|s| s.step.pair.as_ref().map(pair_key))
        .collect();
    Ok(Some(AdaptiveRecord {
        decisions,
        points,
        measured,
    }))
}

/// The report's adaptive section: the decisions as rows (the budget and each batch's
/// estimated time from its `detail`), and the figure of the measured directions; a
/// figure that cannot be drawn becomes a note.
fn adaptive_part(rec: AdaptiveRecord, notes: &mut Vec<String>) -> report::Adaptive {
    let details: Vec<Option<serde_json::Value>> = rec
        .decisions
        .iter()
        .map(|d| serde_json::from_str(&d.detail).ok())
        .collect();
    for (d, v) in rec.decisions.iter().zip(&details) {
        if v.is_none() {
            notes.push(format!(
                "adaptive batch {}: its decision's detail is not JSON; its estimated time is \
                 not shown",
                d.id
            ));
        }
    }
    let budget_points = details
        .iter()
        .flatten()
        .find_map(|v| v.get("budget_points")?.as_u64());
    let decisions: Vec<report::DecisionRow> = rec
        .decisions
        .iter()
        .zip(&details)
        .map(|(d, v)| report::DecisionRow {
            batch: d.id,
            points: d.points,
            steps: d.steps,
            method: d.method.clone(),
            readings: d.readings,
            estimate_s: v
                .as_ref()
                .and_then(|v| v.get("estimate_s")?.as_f64())
                .filter(|s| s.is_finite()),
        })
        .collect();
    let coarse_points = rec.points.iter().filter(|(b, _)| *b == 0).count();
    let batches = rec.decisions.len();
    let (shown, left): (Vec<BatchPoint>, Vec<BatchPoint>) = rec
        .points
        .into_iter()
        .partition(|(_, p)| rec.measured.contains(&pair_key(p)));
    let mut incidences: Vec<(f64, f64)> = shown
        .iter()
        .map(|(_, p)| (p.incident.theta_deg, p.incident.phi_deg))
        .collect();
    incidences.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    incidences.dedup();
    let title = "Where the points went";
    let figure = match points_svg(&shown, batches, incidences.len()) {
        Ok(image) => Some(Figure {
            title: title.into(),
            caption: format!(
                "The measured sample directions on the outgoing hemisphere, a panel per \
                 incidence: radius ∝ θo (azimuthal equidistant, the rim is θo = 90°), angle \
                 φo counter-clockwise from the sample's +x; ○ marks the direction towards \
                 the light and × the mirror direction. Grey points are the coarse pass; \
                 batches 1 to {batches} follow the colour bar (viridis, later is lighter).{}",
                if left.is_empty() {
                    String::new()
                } else {
                    format!(
                        " {} scheduled direction(s) not yet measured are not drawn.",
                        left.len()
                    )
                }
            ),
            image,
        }),
        Err(e) => {
            notes.push(format!("{title}: {e}"));
            None
        }
    };
    report::Adaptive {
        budget_points,
        coarse_points,
        decisions,
        figure,
    }
}

/// The sample directions as SVG: a few hundred circles are smaller and sharper as
/// vectors than as pixels.
fn points_svg(points: &[BatchPoint], batches: usize, incidences: usize) -> Result<Image, String> {
    svg_of(|o| {
        plot::sample_points(
            o,
            points,
            batches,
            &plot::PointsOptions {
                size: plot::PointsOptions::size_for(incidences),
                ..plot::PointsOptions::default()
            },
        )
    })
}

/// The report's figures; a figure that cannot be drawn becomes a note.
fn figures(c: &mut Contents, samples: &Samples, table: Option<&Table>, fit: Option<&Model>) {
    let data_src = match table {
        Some(t) => Source::Brdf(t),
        None => Source::Samples(samples),
    };
    let fit_brdf: Option<&dyn Brdf> = fit.map(|m| m as &dyn Brdf);
    let thetas = shown_thetas(samples);
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
                &plot::PolarOptions {
                    data_label: "measured data".into(),
                    fit_label: "fitted model".into(),
                    ..plot::PolarOptions::default()
                },
            )
        }),
    );
    let Whole {
        src: hemi_src,
        fit: hemi_fit,
        who,
        first,
        shows,
    } = whole(table, fit, data_src);
    let t0 = thetas.get(thetas.len() / 2).copied().unwrap_or(30.0);
    push(
        &format!("Hemisphere: {shows}"),
        &format!(
            "f_r · cos θo over the outgoing hemisphere at θi = {t0}°, {who} (Lafortune Figs. 12, 14)."
        ),
        png_of(|o| {
            plot::hemisphere(
                o,
                &hemi_src,
                hemi_fit,
                t0,
                &plot::HemisphereOptions {
                    data_label: first.into(),
                    fit_label: "fitted model".into(),
                    ..plot::HemisphereOptions::default()
                },
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
        svg_of(|o| {
            plot::albedo(
                o,
                &albedo_src,
                fit,
                &plot::AlbedoOptions {
                    data_label: if matches!(albedo_src, Source::Model(_)) {
                        "fitted model".into()
                    } else {
                        "measured data".into()
                    },
                    fit_label: "fitted model".into(),
                    ..plot::AlbedoOptions::default()
                },
            )
        }),
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
        &format!("Rendered sphere: {shows}"),
        &format!("A sphere under a directional light at 45° from the view, upper left: {who}."),
        png_of(|o| {
            plot::sphere(
                o,
                &hemi_src,
                hemi_fit,
                &plot::SphereOptions {
                    data_label: first.into(),
                    fit_label: "fitted model".into(),
                    ..plot::SphereOptions::default()
                },
            )
        }),
    );
}

/// The incidence angles the plane-of-incidence figure shows: the samples' own, at
/// most four of them (the first, last and two between).
fn shown_thetas(samples: &Samples) -> Vec<f64> {
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
    thetas
}

/// What the whole-hemisphere figures (hemisphere, sphere) show, and how their
/// captions and panels say it.
struct Whole<'a> {
    src: Source<'a>,
    fit: Option<&'a dyn Brdf>,
    /// What the caption says is shown.
    who: &'static str,
    /// The first panel's label.
    first: &'static str,
    /// What the title says is shown.
    shows: &'static str,
}

/// The source and labels of the whole-hemisphere figures, from what the run has:
/// a table of the data, a fitted model, either or neither.
fn whole<'a>(table: Option<&Table>, fit: Option<&'a Model>, data_src: Source<'a>) -> Whole<'a> {
    let fit_brdf: Option<&dyn Brdf> = fit.map(|m| m as &dyn Brdf);
    // The hemisphere, albedo and sphere need the whole hemisphere: the data when it is
    // a table, otherwise the fitted model (said so in the caption).
    // Each panel is labelled with what it shows: the measured table, or the fitted
    // model standing in for it (the plots' default label "data" would call a model
    // measured).
    let (src, fit_brdf, who, first, shows) = match (table, fit) {
        (Some(_), _) => (
            data_src,
            fit_brdf,
            "the measured data (left) and the fitted model (right)",
            "measured data",
            if fit_brdf.is_some() {
                "measured data and fitted model"
            } else {
                "measured data"
            },
        ),
        (None, Some(m)) => (
            Source::Model(m),
            None,
            "the fitted model (the run's pairs do not cover the hemisphere)",
            "fitted model",
            "fitted model",
        ),
        (None, None) => (
            data_src,
            None,
            "the measured data",
            "measured data",
            "measured data",
        ),
    };
    Whole {
        src,
        fit: fit_brdf,
        who,
        first,
        shows,
    }
}
