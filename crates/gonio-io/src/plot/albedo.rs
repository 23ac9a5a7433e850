//! Directional albedo against θi, per channel and per model term (Lafortune et al.
//! 1997, Figs. 4b, 7b, 9b).

use gonio_brdf::{Brdf, Lafortune, Model};
use gonio_core::Dir;
use plotters::prelude::*;

use super::draw::{self, Area, Entry, INK, Mark, Sizes};
use super::eval::Evaluator;
use super::font::FAMILY;
use super::output::Figure;
use super::{AlbedoOptions, PanelRect, PlotErrorKind, Source, check_size, same_channels, select};

/// The largest θi drawn, degrees (at 90° every albedo is 0 by definition).
const THETA_MAX: f64 = 89.0;

/// One curve: a value per θi.
struct Series {
    color: RGBColor,
    points: bool,
    values: Vec<f64>,
}

struct Panel {
    name: String,
    series: Vec<Series>,
}

pub(crate) struct AlbedoFig {
    theta: Vec<f64>,
    panels: Vec<Panel>,
    legend: Vec<Entry>,
    title: String,
}

/// One term of a Lafortune model, as a sub-model whose albedo is the term's.
enum Term {
    /// A model on its own (the diffuse term, one lobe).
    Alone(Lafortune),
    /// The mirror term: the albedo of the lobes with it minus that of the lobes alone
    /// (the Eq. 7 term draws on the lobes' power).
    Mirror { with: Lafortune, without: Lafortune },
}

impl Term {
    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        match self {
            Term::Alone(m) => m.albedo(wi, out),
            Term::Mirror { with, without } => {
                let mut base = vec![0.0; out.len()];
                with.albedo(wi, out);
                without.albedo(wi, &mut base);
                for (o, b) in out.iter_mut().zip(base) {
                    *o -= b;
                }
            }
        }
    }
}

fn param(e: gonio_brdf::ParamError) -> PlotErrorKind {
    PlotErrorKind::Input(format!("splitting the Lafortune model into terms: {e}"))
}

/// The terms of a Lafortune model with their names.
fn terms(l: &Lafortune) -> Result<Vec<(String, Term)>, PlotErrorKind> {
    let ch = l.channels().clone();
    let mut out = Vec::new();
    if let Some(d) = l.diffuse() {
        let kind = if d.is_lambert() {
            "Lambert"
        } else {
            "Minnaert"
        };
        let m = Lafortune::new(ch.clone(), vec![])
            .and_then(|m| m.with_diffuse(d.clone()))
            .map_err(param)?;
        out.push((format!("diffuse ({kind})"), Term::Alone(m)));
    }
    for (i, lobe) in l.lobes().iter().enumerate() {
        let m = Lafortune::new(ch.clone(), vec![lobe.clone()]).map_err(param)?;
        out.push((format!("lobe {}", i + 1), Term::Alone(m)));
    }
    if let Some(mirror) = l.mirror_term() {
        let without = Lafortune::new(ch.clone(), l.lobes().to_vec()).map_err(param)?;
        let with = without.clone().with_mirror(mirror.clone()).map_err(param)?;
        out.push(("mirror".into(), Term::Mirror { with, without }));
    }
    Ok(out)
}

/// θi from 0 in steps of `step`, ending at [`THETA_MAX`].
fn thetas(step: f64) -> Vec<f64> {
    let n = (THETA_MAX / step + 1e-9).floor() as usize;
    let mut t: Vec<f64> = (0..=n).map(|k| k as f64 * step).collect();
    if t.last().is_some_and(|&l| l < THETA_MAX - 1e-9) {
        t.push(THETA_MAX);
    }
    t
}

/// ρ per θi (outer) and channel (inner).
fn albedos(f: impl Fn(Dir, &mut [f64]), nc: usize, theta: &[f64], phi: f64) -> Vec<Vec<f64>> {
    theta
        .iter()
        .map(|&t| {
            let mut out = vec![0.0; nc];
            f(Dir::from_angles(t.to_radians(), phi.to_radians()), &mut out);
            out
        })
        .collect()
}

pub(crate) fn build(
    data: &Source<'_>,
    fit: Option<&Model>,
    opts: &AlbedoOptions,
) -> Result<AlbedoFig, PlotErrorKind> {
    check_size(opts.size, (320, 240))?;
    if !(opts.step_deg >= 0.25 && opts.step_deg <= 30.0) {
        return Err(PlotErrorKind::Input(format!(
            "the θi step must lie in [0.25°, 30°], got {}°",
            opts.step_deg
        )));
    }
    if !opts.phi_i_deg.is_finite() {
        return Err(PlotErrorKind::Input("φi is not a finite number".into()));
    }
    same_channels(data.channels(), fit.map(|f| f.channels()))?;
    let chans = select(opts.channel, data.channels())?;
    let nc = data.channels().len();
    let theta = thetas(opts.step_deg);
    let phi = opts.phi_i_deg;
    let eval = Evaluator::new(data, opts.kernel)?;
    let data_values = albedos(|wi, o| eval.brdf().albedo(wi, o), nc, &theta, phi);
    // The model drawn as lines: the fit, or the data when it is a model shown alone.
    let (line_model, line_label, data_points): (Option<&dyn Brdf>, &str, bool) = match (fit, data) {
        (Some(f), _) => (Some(f.as_brdf()), &opts.fit_label, true),
        (None, Source::Samples(_)) => (None, "", true),
        (None, Source::Model(m)) => (Some(m.as_brdf()), &opts.data_label, false),
        (None, Source::Brdf(b)) => (Some(*b), &opts.data_label, false),
    };
    let lafortune = match (fit, data) {
        (Some(Model::Lafortune(l)), _) => Some(l),
        (None, Source::Model(Model::Lafortune(l))) => Some(l),
        _ => None,
    };
    let term_list = match lafortune {
        Some(l) if opts.terms => terms(l)?,
        _ => Vec::new(),
    };
    let line_values = match (line_model, data_points) {
        (Some(m), true) => Some(albedos(|wi, o| m.albedo(wi, o), nc, &theta, phi)),
        (Some(_), false) => Some(data_values.clone()),
        (None, _) => None,
    };
    let term_values: Vec<Vec<Vec<f64>>> = term_list
        .iter()
        .map(|(_, t)| albedos(|wi, o| t.albedo(wi, o), nc, &theta, phi))
        .collect();
    let column = |v: &[Vec<f64>], ch: usize| v.iter().map(|r| r[ch]).collect::<Vec<f64>>();
    let term_color = |k: usize| draw::series_color(k);
    let panels = chans
        .iter()
        .map(|&ch| {
            let mut series = Vec::new();
            for (k, tv) in term_values.iter().enumerate() {
                series.push(Series {
                    color: term_color(k),
                    points: false,
                    values: column(tv, ch),
                });
            }
            if let Some(lv) = &line_values {
                series.push(Series {
                    color: INK,
                    points: false,
                    values: column(lv, ch),
                });
            }
            if data_points {
                series.push(Series {
                    color: INK,
                    points: true,
                    values: column(&data_values, ch),
                });
            }
            Panel {
                name: data.channels().name(ch),
                series,
            }
        })
        .collect();
    let mut legend = Vec::new();
    if data_points {
        legend.push(Entry::new(
            Mark::Point(INK),
            format!("{} (total)", opts.data_label),
        ));
    }
    if line_model.is_some() {
        legend.push(Entry::new(Mark::Line(INK), format!("{line_label} (total)")));
    }
    if !term_list.is_empty() {
        legend.push(Entry::new(Mark::Heading, format!("terms of {line_label}")));
        for (k, (name, _)) in term_list.iter().enumerate() {
            legend.push(Entry::new(Mark::Line(term_color(k)), name.clone()));
        }
    }
    let title = opts.title.clone().unwrap_or_else(|| {
        format!(
            "Directional albedo ρ(θi) = ∫ f_r cos θo dωo   (φi = {})",
            draw::fmt_deg(phi)
        )
    });
    Ok(AlbedoFig {
        theta,
        panels,
        legend,
        title,
    })
}

impl AlbedoFig {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        panel: &Panel,
        rect: (i32, i32, i32, i32),
        sz: &Sizes,
    ) -> Result<PanelRect, String> {
        let (x, y, w, h) = rect;
        let sub = root
            .clone()
            .shrink((x, y), (w.max(1) as u32, h.max(1) as u32));
        let ymax = panel
            .series
            .iter()
            .flat_map(|s| s.values.iter())
            .fold(0.0f64, |a, &v| a.max(v));
        let ymax = if ymax > 0.0 && ymax.is_finite() {
            let step = draw::nice_step(ymax * 1.08, 5);
            step * (ymax * 1.08 / step).ceil()
        } else {
            1.0
        };
        let ystep = draw::nice_step(ymax, 5);
        let mut chart = ChartBuilder::on(&sub)
            .caption(
                format!("channel {}", panel.name),
                (FAMILY, sz.label).into_font(),
            )
            .margin(sz.px(10.0))
            .x_label_area_size(sz.px(52.0))
            .y_label_area_size(sz.px(66.0))
            .build_cartesian_2d(0f64..90f64, 0f64..ymax)
            .map_err(draw::de)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .bold_line_style(draw::GRID)
            .x_labels(10)
            .y_labels(8)
            .x_label_formatter(&|v| draw::fmt_deg(*v))
            .y_label_formatter(&|v| draw::fmt_tick(*v, ystep / 2.0))
            .label_style((FAMILY, sz.tick))
            .axis_desc_style((FAMILY, sz.label))
            .x_desc("θi (degrees)")
            .y_desc("directional albedo ρ (dimensionless)")
            .draw()
            .map_err(draw::de)?;
        let lw = sz.px(2.0).max(1) as u32;
        for s in &panel.series {
            let pts: Vec<(f64, f64)> = self
                .theta
                .iter()
                .copied()
                .zip(s.values.iter().copied())
                .collect();
            if s.points {
                for p in pts {
                    let at = chart.backend_coord(&p);
                    draw::dot(root, at, sz.px(3.5), s.color)?;
                }
            } else {
                chart
                    .draw_series(LineSeries::new(pts, s.color.stroke_width(lw)))
                    .map_err(draw::de)?;
            }
        }
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        Ok(PanelRect {
            label: panel.name.clone(),
            x0: xr.start,
            y0: yr.start,
            x1: xr.end,
            y1: yr.end,
        })
    }
}

impl Figure for AlbedoFig {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        _cell: u32,
    ) -> Result<Vec<PanelRect>, String> {
        root.fill(&WHITE).map_err(draw::de)?;
        let sz = Sizes::for_area(root);
        let (w, h) = root.dim_in_pixel();
        let (w, h) = (w as i32, h as i32);
        let top = draw::title(root, &self.title, &sz)?;
        let lw = sz.px(220.0);
        let region = (sz.px(4.0), top, w - lw - sz.px(8.0), h - top - sz.px(4.0));
        let n = self.panels.len();
        let (rows, cols) = draw::grid_for(n, region.2 as f64, region.3 as f64, 1.3);
        let rects = draw::split(region, rows, cols, n);
        let mut out = Vec::new();
        for (p, rect) in self.panels.iter().zip(rects) {
            out.push(self.draw_panel(root, p, rect, &sz)?);
        }
        draw::legend(
            root,
            &self.legend,
            (w - lw - sz.px(2.0), top + sz.px(40.0)),
            lw - sz.px(8.0),
            &sz,
        )?;
        Ok(out)
    }
}
