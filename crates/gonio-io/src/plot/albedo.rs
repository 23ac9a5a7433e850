//! Directional albedo against θi, per channel and per model term (Lafortune et al.
//! 1997, Figs. 4b, 7b, 9b); and, for wavelength channels, against wavelength, one
//! curve per θi ([`SpectralAlbedo`]).

use gonio_brdf::{Brdf, Lafortune, Model};
use gonio_core::Dir;
use plotters::prelude::*;

use super::draw::{self, Area, Entry, INK, Mark, Sizes};
use super::eval::Evaluator;
use super::font::FAMILY;
use super::output::Figure;
use super::{
    AlbedoOptions, PanelRect, PlotErrorKind, Source, check_size, check_theta_i, same_channels,
    select,
};

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

/// What a spectral albedo plot draws: the directional albedo
/// ρ(θi, λ) = ∫ f_r cos θo dωo at each wavelength channel, for each requested θi
/// (at the options' φi), from [`Brdf::albedo`] (for samples, of the nearest-j
/// interpolation over the hemisphere).
#[derive(Clone, Debug, PartialEq)]
pub struct SpectralAlbedo {
    /// The wavelengths, nm, increasing (the x axis).
    pub wavelengths_nm: Vec<f64>,
    /// The incident polar angles, degrees: one curve each.
    pub theta_i_deg: Vec<f64>,
    /// The data's albedo, `data[k][c]` at `theta_i_deg[k]` and `wavelengths_nm[c]`.
    pub data: Vec<Vec<f64>>,
    /// The fit's albedo, indexed as `data`, when a fit is given.
    pub fit: Option<Vec<Vec<f64>>>,
    /// The φi of the incident directions, degrees.
    pub phi_i_deg: f64,
}

/// The numbers of the spectral albedo plot (see [`SpectralAlbedo`]); the data's
/// channels must be wavelengths (at least one), and a fit must have the same ones.
pub(crate) fn spectral(
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: &[f64],
    opts: &AlbedoOptions,
) -> Result<SpectralAlbedo, PlotErrorKind> {
    let gonio_core::Channels::Wavelengths(wl) = data.channels() else {
        return Err(PlotErrorKind::Input(format!(
            "albedo against wavelength needs wavelength channels; the data has {}",
            data.channels()
        )));
    };
    same_channels(data.channels(), fit.map(|f| f.channels()))?;
    if theta_i_deg.is_empty() {
        return Err(PlotErrorKind::Input(
            "albedo against wavelength needs at least one θi".into(),
        ));
    }
    for &t in theta_i_deg {
        check_theta_i(t)?;
    }
    if !opts.phi_i_deg.is_finite() {
        return Err(PlotErrorKind::Input("φi is not a finite number".into()));
    }
    let nc = wl.len();
    let eval = Evaluator::new(data, opts.kernel)?;
    let data_values = albedos(
        |wi, o| eval.brdf().albedo(wi, o),
        nc,
        theta_i_deg,
        opts.phi_i_deg,
    );
    let fit_values = fit.map(|f| albedos(|wi, o| f.albedo(wi, o), nc, theta_i_deg, opts.phi_i_deg));
    Ok(SpectralAlbedo {
        wavelengths_nm: wl.to_vec(),
        theta_i_deg: theta_i_deg.to_vec(),
        data: data_values,
        fit: fit_values,
        phi_i_deg: opts.phi_i_deg,
    })
}

/// The spectral albedo figure: one panel, a curve per θi.
pub(crate) struct SpectralFig {
    values: SpectralAlbedo,
    /// Data as points (when a fit is drawn, or the data are samples), else as lines.
    data_points: bool,
    legend: Vec<Entry>,
    title: String,
}

pub(crate) fn build_spectral(
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: &[f64],
    opts: &AlbedoOptions,
) -> Result<SpectralFig, PlotErrorKind> {
    check_size(opts.size, (320, 240))?;
    let values = spectral(data, fit, theta_i_deg, opts)?;
    let data_points = fit.is_some() || matches!(data, Source::Samples(_));
    let mut legend = Vec::new();
    for (k, t) in values.theta_i_deg.iter().enumerate() {
        let mark = if data_points {
            Mark::Point(draw::series_color(k))
        } else {
            Mark::Line(draw::series_color(k))
        };
        legend.push(Entry::new(mark, format!("θi = {}", draw::fmt_deg(*t))));
    }
    legend.push(Entry::new(
        if data_points {
            Mark::Point(INK)
        } else {
            Mark::Line(INK)
        },
        opts.data_label.clone(),
    ));
    if fit.is_some() {
        legend.push(Entry::new(Mark::Line(INK), opts.fit_label.clone()));
    }
    let title = opts.title.clone().unwrap_or_else(|| {
        format!(
            "Directional albedo ρ(λ) = ∫ f_r cos θo dωo   (φi = {})",
            draw::fmt_deg(values.phi_i_deg)
        )
    });
    Ok(SpectralFig {
        values,
        data_points,
        legend,
        title,
    })
}

impl SpectralFig {
    /// The data's albedo table (the figure's numbers).
    pub(crate) fn values(&self) -> &SpectralAlbedo {
        &self.values
    }
}

impl Figure for SpectralFig {
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
        let v = &self.values;
        let sub = root.clone().shrink(
            (sz.px(4.0), top),
            (
                (w - lw - sz.px(12.0)).max(1) as u32,
                (h - top - sz.px(4.0)).max(1) as u32,
            ),
        );
        let ymax = v
            .data
            .iter()
            .chain(v.fit.iter().flatten())
            .flatten()
            .fold(0.0f64, |a, &x| a.max(x));
        let ymax = if ymax > 0.0 && ymax.is_finite() {
            let step = draw::nice_step(ymax * 1.08, 5);
            step * (ymax * 1.08 / step).ceil()
        } else {
            1.0
        };
        let ystep = draw::nice_step(ymax, 5);
        // One wavelength still gets an axis: ±10 nm around it.
        let (lo, hi) = match (v.wavelengths_nm.first(), v.wavelengths_nm.last()) {
            (Some(&a), Some(&b)) if b > a => (a, b),
            (Some(&a), _) => (a - 10.0, a + 10.0),
            _ => (0.0, 1.0),
        };
        let xstep = draw::nice_step(hi - lo, 8);
        let mut chart = ChartBuilder::on(&sub)
            .margin(sz.px(10.0))
            .x_label_area_size(sz.px(52.0))
            .y_label_area_size(sz.px(66.0))
            .build_cartesian_2d(lo..hi, 0f64..ymax)
            .map_err(draw::de)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .bold_line_style(draw::GRID)
            .x_labels(10)
            .y_labels(8)
            .x_label_formatter(&|x| draw::fmt_tick(*x, xstep / 2.0))
            .y_label_formatter(&|y| draw::fmt_tick(*y, ystep / 2.0))
            .label_style((FAMILY, sz.tick))
            .axis_desc_style((FAMILY, sz.label))
            .x_desc("wavelength λ (nm)")
            .y_desc("directional albedo ρ (dimensionless)")
            .draw()
            .map_err(draw::de)?;
        let lw_px = sz.px(2.0).max(1) as u32;
        let curve = |row: &[f64]| -> Vec<(f64, f64)> {
            v.wavelengths_nm
                .iter()
                .copied()
                .zip(row.iter().copied())
                .collect()
        };
        for (k, row) in v.data.iter().enumerate() {
            let color = draw::series_color(k);
            if self.data_points {
                for p in curve(row) {
                    let at = chart.backend_coord(&p);
                    draw::dot(root, at, sz.px(3.5), color)?;
                }
            } else {
                chart
                    .draw_series(LineSeries::new(curve(row), color.stroke_width(lw_px)))
                    .map_err(draw::de)?;
            }
        }
        for (k, row) in v.fit.iter().flatten().enumerate() {
            chart
                .draw_series(LineSeries::new(
                    curve(row),
                    draw::series_color(k).stroke_width(lw_px),
                ))
                .map_err(draw::de)?;
        }
        draw::legend(
            root,
            &self.legend,
            (w - lw - sz.px(2.0), top + sz.px(40.0)),
            lw - sz.px(8.0),
            &sz,
        )?;
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        Ok(vec![PanelRect {
            label: "albedo".into(),
            x0: xr.start,
            y0: yr.start,
            x1: xr.end,
            y1: yr.end,
        }])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gonio_process::{Grid, Table};

    const RHO: [f64; 4] = [0.12, 0.3, 0.55, 0.81];

    fn lambert() -> Model {
        Model::from_toml(
            "kind = \"lambert\"\nchannels = [\"400nm\", \"500nm\", \"600nm\", \"700nm\"]\n\
             rho = [0.12, 0.3, 0.55, 0.81]\n",
            None,
        )
        .expect("model")
    }

    #[test]
    fn a_lambertian_spectrum_is_its_own_albedo_at_every_wavelength() {
        let m = lambert();
        let theta = [0.0, 35.0, 65.0];
        let opts = AlbedoOptions::default();
        let v = spectral(&Source::Model(&m), None, &theta, &opts).expect("values");
        assert_eq!(v.wavelengths_nm, vec![400.0, 500.0, 600.0, 700.0]);
        assert_eq!(v.theta_i_deg, theta.to_vec());
        for row in &v.data {
            for (a, r) in row.iter().zip(RHO) {
                assert!((a - r).abs() < 1e-9, "{a} vs {r}");
            }
        }
        // The same spectrum tabulated on a 5° grid: the table's albedo is a quadrature
        // of its interpolation, within 0.5% of ρ(λ); the fit (the model) exactly ρ(λ).
        let t = Table::from_brdf(&m, Grid::hemisphere(18, 72)).expect("table");
        let v = spectral(&Source::Brdf(&t), Some(&m), &theta, &opts).expect("values");
        let fit = v.fit.as_ref().expect("fit");
        for (row, frow) in v.data.iter().zip(fit) {
            for ((a, f), r) in row.iter().zip(frow).zip(RHO) {
                assert!((a / r - 1.0).abs() < 5e-3, "{a} vs {r}");
                assert!((f - r).abs() < 1e-9, "{f} vs {r}");
            }
        }
    }

    #[test]
    fn needs_wavelengths_and_valid_angles() {
        let rgb = Model::from_toml(
            "kind = \"lambert\"\nchannels = [\"R\", \"G\", \"B\"]\nrho = [0.1, 0.2, 0.3]\n",
            None,
        )
        .expect("model");
        let opts = AlbedoOptions::default();
        let Err(e) = spectral(&Source::Model(&rgb), None, &[0.0], &opts) else {
            panic!("refused")
        };
        assert!(e.to_string().contains("wavelength channels"), "{e}");
        let m = lambert();
        assert!(spectral(&Source::Model(&m), None, &[90.0], &opts).is_err());
        assert!(spectral(&Source::Model(&m), None, &[], &opts).is_err());
        let other = Model::from_toml(
            "kind = \"lambert\"\nchannels = [\"400nm\", \"500nm\"]\nrho = [0.1, 0.2]\n",
            None,
        )
        .expect("model");
        assert!(spectral(&Source::Model(&m), Some(other.as_brdf()), &[0.0], &opts).is_err());
    }
}
