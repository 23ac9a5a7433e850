//! P_s^(k) against k (DeYoung Eq. 4.20, Fig. 5.9).

use gonio_process::Table;
use gonio_process::measure;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::draw::{self, Area, Entry, Mark, Sizes};
use super::font::FAMILY;
use super::output::Figure;
use super::{PanelRect, PlotErrorKind, SeparabilityOptions, check_size, select};

/// The most series one plot takes.
const MAX_SERIES: usize = 10;
/// The k drawn when none are asked: 1 to this (capped by the rank).
const DEFAULT_K: usize = 20;
/// Values below this fraction of a series' largest are numerical zeros.
const ZERO: f64 = 1e-12;

struct Series {
    label: String,
    points: Vec<(usize, f64)>,
}

pub(crate) struct SepFig {
    series: Vec<Series>,
    kmax: usize,
    title: String,
}

/// Rows and columns of DeYoung's matrix A for a table (its 4D form).
fn matrix_shape(t: &Table) -> (usize, usize) {
    let g = &t.grid;
    if g.isotropic {
        (g.phi_o.n * g.theta_i.n, g.n_out())
    } else {
        (g.n_in(), g.n_out())
    }
}

pub(crate) fn build(
    tables: &[(&str, &Table)],
    ks: &[usize],
    opts: &SeparabilityOptions,
) -> Result<SepFig, PlotErrorKind> {
    check_size(opts.size, (320, 240))?;
    if tables.is_empty() {
        return Err(PlotErrorKind::Input("no table to measure".into()));
    }
    if ks.contains(&0) {
        return Err(PlotErrorKind::Input("k starts at 1".into()));
    }
    let mut series = Vec::new();
    let mut kmax = 1;
    for (name, t) in tables {
        let chans = select(opts.channel, &t.channels)?;
        let (p, q) = matrix_shape(t);
        let rank = p.min(q).max(1);
        let mut k_list: Vec<usize> = if ks.is_empty() {
            (1..=DEFAULT_K.min(rank)).collect()
        } else {
            ks.to_vec()
        };
        k_list.sort_unstable();
        k_list.dedup();
        let seps = measure::separability(t, &k_list)?;
        for ch in chans {
            let p_s = &seps[ch].p_s;
            let top = p_s.iter().fold(0.0f64, |a, p| a.max(p.1));
            let points: Vec<(usize, f64)> = p_s
                .iter()
                .copied()
                .filter(|&(_, v)| v > top * ZERO && v > 0.0)
                .collect();
            kmax = kmax.max(k_list.last().copied().unwrap_or(1));
            let label = if t.channels.len() > 1 {
                format!("{name}, {}", t.channels.name(ch))
            } else {
                name.to_string()
            };
            series.push(Series { label, points });
        }
    }
    if series.len() > MAX_SERIES {
        return Err(PlotErrorKind::Input(format!(
            "{} series (tables × channels) are too many for one plot (at most {MAX_SERIES}); \
             choose one channel",
            series.len()
        )));
    }
    let title = opts.title.clone().unwrap_or_else(|| {
        "Separability: P_s^(k), the RMS residual of the best rank-k approximation".to_string()
    });
    Ok(SepFig {
        series,
        kmax,
        title,
    })
}

impl Figure for SepFig {
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
        let sub = root.clone().shrink(
            (sz.px(4.0), top),
            (
                (w - lw - sz.px(8.0)).max(1) as u32,
                (h - top - sz.px(4.0)).max(1) as u32,
            ),
        );
        let all = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1));
        let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        // The y axis is log₁₀ P_s on a linear scale, with ticks drawn here (1, 2, 5 ×
        // 10^k up to three decades, powers of ten beyond).
        let (lo, hi) = if hi > 0.0 && lo.is_finite() {
            let lo = (lo.log10() - 0.05).floor();
            let hi = (hi.log10() + 0.05).ceil();
            (lo, hi.max(lo + 1.0))
        } else {
            (-3.0, 0.0)
        };
        let kmax = self.kmax as f64;
        let mut chart = ChartBuilder::on(&sub)
            .margin(sz.px(12.0))
            .x_label_area_size(sz.px(52.0))
            .y_label_area_size(sz.px(76.0))
            .build_cartesian_2d(0.5f64..kmax + 0.5, lo..hi)
            .map_err(draw::de)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .bold_line_style(draw::GRID)
            .disable_y_mesh()
            .y_labels(0)
            .x_labels(self.kmax.min(12))
            .x_label_formatter(&|v| format!("{}", v.round() as i64))
            .label_style((FAMILY, sz.tick))
            .axis_desc_style((FAMILY, sz.label))
            .x_desc("k (number of separable terms)")
            .y_desc("P_s^(k) (1/sr)")
            .draw()
            .map_err(draw::de)?;
        let (xr, _) = chart.plotting_area().get_pixel_range();
        let decades = (hi - lo).round() as i32;
        let ms: &[u32] = if decades <= 3 { &[1, 2, 5] } else { &[1] };
        for k in (lo as i32)..=(hi as i32) {
            for &m in ms {
                let lv = k as f64 + (m as f64).log10();
                if lv > hi + 1e-9 {
                    continue;
                }
                let y = chart.backend_coord(&(0.5, lv)).1;
                let color = if m == 1 {
                    draw::MUTED.mix(0.45)
                } else {
                    draw::GRID.mix(0.7)
                };
                root.draw(&PathElement::new(vec![(xr.start, y), (xr.end, y)], color))
                    .map_err(draw::de)?;
                draw::line(
                    root,
                    vec![(xr.start - sz.px(5.0), y), (xr.start, y)],
                    draw::INK,
                    1,
                )?;
                draw::text(
                    root,
                    &draw::fmt_125(m, k),
                    (xr.start - sz.px(8.0), y),
                    sz.tick,
                    draw::INK,
                    (HPos::Right, VPos::Center),
                )?;
            }
        }
        let lwidth = sz.px(2.0).max(1) as u32;
        let mut entries = Vec::new();
        for (i, s) in self.series.iter().enumerate() {
            let color = draw::series_color(i);
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .map(|&(k, v)| (k as f64, v.log10()))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(lwidth)))
                .map_err(draw::de)?;
            for p in &pts {
                draw::dot(root, chart.backend_coord(p), sz.px(4.0), color)?;
            }
            let label = if s.points.is_empty() {
                format!("{} (all zero)", s.label)
            } else {
                s.label.clone()
            };
            entries.push(Entry::new(Mark::LinePoint(color), label));
        }
        draw::legend(
            root,
            &entries,
            (w - lw - sz.px(2.0), top + sz.px(12.0)),
            lw - sz.px(8.0),
            &sz,
        )?;
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        Ok(vec![PanelRect {
            label: "P_s".into(),
            x0: xr.start,
            y0: yr.start,
            x1: xr.end,
            y1: yr.end,
        }])
    }
}
