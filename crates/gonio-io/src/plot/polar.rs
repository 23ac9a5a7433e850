//! Polar plots of f_r in the plane of incidence (Lafortune et al. 1997, Figs. 11, 13).

use gonio_brdf::Brdf;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::draw::{self, Area, Entry, GRID, INK, MUTED, Mark, Sizes};
use super::eval::{in_plane, in_plane_dirs};
use super::output::Figure;
use super::{
    PanelRect, PlotErrorKind, PolarOptions, Source, check_size, check_theta_i, same_channels,
    select,
};

/// How f_r maps to the radius of a polar plot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RadialScale {
    /// The radius is f_r, from 0 at the centre.
    Linear,
    /// The radius is log₁₀ f_r over this many decades below the decade of the largest
    /// value; smaller values sit at the centre.
    Log {
        /// Decades shown (at least 1).
        decades: u32,
    },
}

/// The most θi one plot takes (one colour each).
const MAX_THETA_I: usize = 10;
/// Spacing of the lines drawn for models, degrees of θo.
const LINE_STEP_DEG: f64 = 0.5;

/// One channel: per θi, (signed θo in degrees, f_r).
struct Panel {
    name: String,
    data: Vec<Vec<(f64, f64)>>,
    fit: Option<Vec<Vec<(f64, f64)>>>,
}

pub(crate) struct PolarFig {
    panels: Vec<Panel>,
    theta_i: Vec<f64>,
    title: String,
    data_label: String,
    fit_label: String,
    /// The data drawn as lines (an analytic or tabulated BRDF shown alone).
    data_as_lines: bool,
    scale: RadialScale,
    phi_i: f64,
}

/// Signed outgoing angles from −89.5° to 89.5° (lines) or in steps of `step` within
/// ±89° (points).
fn angles(step: f64, lines: bool) -> Vec<f64> {
    if lines {
        let n = (89.5 / LINE_STEP_DEG).round() as i64;
        (-n..=n).map(|k| k as f64 * LINE_STEP_DEG).collect()
    } else {
        let n = (89.0 / step).floor() as i64;
        (-n..=n).map(|k| k as f64 * step).collect()
    }
}

fn curve(b: &dyn Brdf, theta_i: f64, phi_i: f64, ch: usize, at: &[f64]) -> Vec<(f64, f64)> {
    let mut v = vec![0.0; b.channels().len()];
    at.iter()
        .map(|&s| {
            let (wi, wo) = in_plane_dirs(theta_i, phi_i, s);
            b.eval(wi, wo, &mut v);
            (s, v[ch])
        })
        .collect()
}

pub(crate) fn build(
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: &[f64],
    opts: &PolarOptions,
) -> Result<PolarFig, PlotErrorKind> {
    check_size(opts.size, (320, 240))?;
    if theta_i_deg.is_empty() || theta_i_deg.len() > MAX_THETA_I {
        return Err(PlotErrorKind::Input(format!(
            "a polar plot takes 1 to {MAX_THETA_I} incident angles, got {}",
            theta_i_deg.len()
        )));
    }
    for &t in theta_i_deg {
        check_theta_i(t)?;
    }
    if !(opts.tolerance_deg > 0.0 && opts.tolerance_deg < 45.0) {
        return Err(PlotErrorKind::Input(format!(
            "the in-plane tolerance must lie in (0°, 45°), got {}°",
            opts.tolerance_deg
        )));
    }
    if !(opts.data_step_deg >= 0.5 && opts.data_step_deg <= 45.0) {
        return Err(PlotErrorKind::Input(format!(
            "the data point spacing must lie in [0.5°, 45°], got {}°",
            opts.data_step_deg
        )));
    }
    if let RadialScale::Log { decades } = opts.scale
        && !(1..=12).contains(&decades)
    {
        return Err(PlotErrorKind::Input(format!(
            "a logarithmic radius needs 1 to 12 decades, got {decades}"
        )));
    }
    if !opts.phi_i_deg.is_finite() {
        return Err(PlotErrorKind::Input("φi is not a finite number".into()));
    }
    same_channels(data.channels(), fit.map(|f| f.channels()))?;
    let chans = select(opts.channel, data.channels())?;
    let data_as_lines = fit.is_none() && !matches!(data, Source::Samples(_));
    let phi = opts.phi_i_deg;
    let data_at = angles(opts.data_step_deg, data_as_lines);
    let fit_at = angles(LINE_STEP_DEG, true);
    let mut panels = Vec::new();
    for &ch in &chans {
        let d: Vec<Vec<(f64, f64)>> = theta_i_deg
            .iter()
            .map(|&t| match *data {
                Source::Samples(s) => in_plane(s, t, phi, opts.tolerance_deg, ch),
                Source::Brdf(b) => curve(b, t, phi, ch, &data_at),
                Source::Model(m) => curve(m.as_brdf(), t, phi, ch, &data_at),
            })
            .collect();
        let f = fit.map(|b| {
            theta_i_deg
                .iter()
                .map(|&t| curve(b, t, phi, ch, &fit_at))
                .collect::<Vec<_>>()
        });
        panels.push(Panel {
            name: data.channels().name(ch),
            data: d,
            fit: f,
        });
    }
    if fit.is_none() && panels.iter().all(|p| p.data.iter().all(Vec::is_empty)) {
        return Err(PlotErrorKind::Input(format!(
            "no sample lies in the plane of incidence (φi = {phi}°) at the incident angles \
             asked, within {}°",
            opts.tolerance_deg
        )));
    }
    let title = opts
        .title
        .clone()
        .unwrap_or_else(|| "f_r in the plane of incidence".to_string());
    Ok(PolarFig {
        panels,
        theta_i: theta_i_deg.to_vec(),
        title,
        data_label: opts.data_label.clone(),
        fit_label: opts.fit_label.clone(),
        data_as_lines,
        scale: opts.scale,
        phi_i: phi,
    })
}

/// The radius of a value as a fraction of the outer ring, and the rings.
enum Radial {
    Linear {
        max: f64,
        step: f64,
    },
    /// log₁₀ of the outer ring's value, and the decades down to the centre.
    Log {
        top: f64,
        decades: u32,
    },
}

/// The smallest 1, 2 or 5 × 10^k not below `v` (> 0).
fn nice_ceil(v: f64) -> f64 {
    let k = v.log10().floor();
    let m = v / 10f64.powf(k);
    let n = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .find(|&n| n >= m * (1.0 - 1e-9))
        .unwrap_or(10.0);
    n * 10f64.powf(k)
}

impl Radial {
    fn new(scale: RadialScale, fmax: f64) -> Radial {
        let fmax = if fmax > 0.0 && fmax.is_finite() {
            fmax
        } else {
            1.0
        };
        match scale {
            RadialScale::Linear => {
                let step = draw::nice_step(fmax, 4);
                let max = step * (fmax / step - 1e-9).ceil().max(1.0);
                Radial::Linear { max, step }
            }
            RadialScale::Log { decades } => Radial::Log {
                top: nice_ceil(fmax).log10(),
                decades,
            },
        }
    }

    fn rho(&self, f: f64) -> f64 {
        match *self {
            Radial::Linear { max, .. } => (f / max).clamp(0.0, 1.0),
            Radial::Log { top, decades } => {
                if f > 0.0 {
                    ((f.log10() - top) / decades as f64 + 1.0).clamp(0.0, 1.0)
                } else {
                    0.0
                }
            }
        }
    }

    /// (fraction of the outer radius, label) of every ring: the linear steps, or
    /// 1, 2 and 5 × 10^k (only the powers of ten beyond three decades).
    fn rings(&self) -> Vec<(f64, String)> {
        match *self {
            Radial::Linear { max, step } => {
                let n = (max / step).round() as i64;
                (1..=n)
                    .map(|k| {
                        let v = k as f64 * step;
                        (v / max, draw::fmt_tick(v, step))
                    })
                    .collect()
            }
            Radial::Log { top, decades } => {
                let bottom = top - decades as f64;
                let ms: &[u32] = if decades <= 3 { &[1, 2, 5] } else { &[1] };
                let mut out = Vec::new();
                for k in (bottom.floor() as i32)..=(top.ceil() as i32) {
                    for &m in ms {
                        let lv = (m as f64).log10() + k as f64;
                        if lv > bottom + 1e-9 && lv <= top + 1e-9 {
                            out.push(((lv - bottom) / decades as f64, draw::fmt_125(m, k)));
                        }
                    }
                }
                out
            }
        }
    }

    fn centre_label(&self) -> String {
        match *self {
            Radial::Linear { .. } => "0".into(),
            Radial::Log { top, decades } => {
                let b = top - decades as f64;
                let k = b.floor() as i32;
                let m = 10f64.powf(b - k as f64).round() as u32;
                format!("≤{}", draw::fmt_125(m, k))
            }
        }
    }
}

/// A panel's half disc on the image: its centre and radius, in pixels.
#[derive(Clone, Copy)]
struct Disc {
    cx: i32,
    cy: i32,
    r: i32,
}

impl Disc {
    /// The pixel at `deg` from the normal (negative towards the light) and `frac`
    /// of the radius.
    fn at(&self, deg: f64, frac: f64) -> (i32, i32) {
        let rf = self.r as f64;
        let a = deg.to_radians();
        (
            self.cx + (rf * frac * a.sin()).round() as i32,
            self.cy - (rf * frac * a.cos()).round() as i32,
        )
    }
}

impl PolarFig {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &Area<DB>,
        panel: &Panel,
        rect: (i32, i32, i32, i32),
        caption: bool,
        sz: &Sizes,
    ) -> Result<PanelRect, String> {
        let (disc, cap) = self.disc(rect, caption, sz)?;
        let Disc { cx, cy, r } = disc;
        if caption {
            draw::text(
                area,
                &format!("channel {}", panel.name),
                (cx, rect.1 + cap / 2),
                sz.label,
                INK,
                (HPos::Center, VPos::Center),
            )?;
        }
        let fmax = panel
            .data
            .iter()
            .chain(panel.fit.iter().flatten())
            .flatten()
            .map(|p| p.1)
            .fold(0.0f64, f64::max);
        let radial = Radial::new(self.scale, fmax);
        spokes(area, disc, sz)?;
        rings(area, disc, &radial, sz)?;
        self.lights(area, disc, sz)?;
        self.curves(area, panel, disc, &radial, sz)?;
        axis_notes(area, disc, sz)?;
        Ok(PanelRect {
            label: panel.name.clone(),
            x0: cx - r,
            y0: cy - r,
            x1: cx + r + 1,
            y1: cy + 1,
        })
    }

    /// Where a panel's disc goes in its rectangle, below its caption's height
    /// (also returned) and above the axis descriptions; an error when the image is
    /// too small for it.
    fn disc(
        &self,
        rect: (i32, i32, i32, i32),
        caption: bool,
        sz: &Sizes,
    ) -> Result<(Disc, i32), String> {
        let (x, y, w, h) = rect;
        let cap = if caption {
            (sz.label * 1.7).round() as i32
        } else {
            0
        };
        let m_side = (sz.tick * 3.3).round() as i32;
        let m_top = (sz.tick * 1.9).round() as i32;
        let m_bottom = (sz.tick * 1.6 + sz.tick * 1.6 + sz.label * 1.8).round() as i32;
        let r = ((w - 2 * m_side) / 2).min(h - cap - m_top - m_bottom);
        if r < 40 {
            return Err(format!(
                "the image is too small for {} polar panel(s)",
                self.panels.len()
            ));
        }
        let cx = x + w / 2;
        let block = m_top + r + m_bottom;
        let cy = y + cap + (h - cap - block) / 2 + m_top + r;
        Ok((Disc { cx, cy, r }, cap))
    }

    /// The directions of the light, as arrowheads inside the outer ring.
    fn lights<DB: DrawingBackend>(
        &self,
        area: &Area<DB>,
        disc: Disc,
        sz: &Sizes,
    ) -> Result<(), String> {
        let hw = sz.px(6.0) as f64;
        for (j, &t) in self.theta_i.iter().enumerate() {
            let a = (-t).to_radians();
            let tip = disc.at(-t, 0.9);
            let base = disc.at(-t, 0.995);
            let (px, py) = ((hw * a.cos()).round() as i32, (hw * a.sin()).round() as i32);
            draw::triangle(
                area,
                [tip, (base.0 + px, base.1 + py), (base.0 - px, base.1 - py)],
                draw::series_color(j),
            )?;
        }
        Ok(())
    }

    /// The curves: the fit's lines, then the data as lines or dots.
    fn curves<DB: DrawingBackend>(
        &self,
        area: &Area<DB>,
        panel: &Panel,
        disc: Disc,
        radial: &Radial,
        sz: &Sizes,
    ) -> Result<(), String> {
        let lw = sz.px(2.0).max(1) as u32;
        let to_px = |&(s, f): &(f64, f64)| disc.at(s, radial.rho(f));
        if let Some(fit) = &panel.fit {
            for (j, c) in fit.iter().enumerate() {
                draw::line(
                    area,
                    c.iter().map(to_px).collect(),
                    draw::series_color(j),
                    lw,
                )?;
            }
        }
        for (j, c) in panel.data.iter().enumerate() {
            let color = draw::series_color(j);
            if self.data_as_lines {
                draw::line(area, c.iter().map(to_px).collect(), color, lw)?;
            } else {
                for p in c {
                    draw::dot(area, to_px(p), sz.px(3.5), color)?;
                }
            }
        }
        Ok(())
    }
}

/// Radial lines every 15°, labelled every 30°.
fn spokes<DB: DrawingBackend>(area: &Area<DB>, disc: Disc, sz: &Sizes) -> Result<(), String> {
    let (cx, cy, rf) = (disc.cx, disc.cy, disc.r as f64);
    let thin = sz.px(1.0).max(1) as u32;
    for k in -6i32..=6 {
        let deg = k as f64 * 15.0;
        draw::line(area, vec![(cx, cy), disc.at(deg, 1.0)], GRID, thin)?;
        if k % 2 == 0 {
            let gap = 1.0 + sz.tick * 0.45 / rf;
            let hp = match k {
                ..0 => HPos::Right,
                0 => HPos::Center,
                _ => HPos::Left,
            };
            let vp = if k.abs() == 6 {
                VPos::Center
            } else {
                VPos::Bottom
            };
            draw::text(
                area,
                &draw::fmt_deg(deg),
                disc.at(deg, gap),
                sz.tick,
                MUTED,
                (hp, vp),
            )?;
        }
    }
    Ok(())
}

/// The rings, labelled on the baseline on both sides: from the outer ring
/// inwards, each label that clears the one outside it and the centre's; then the
/// centre's label and the baseline.
fn rings<DB: DrawingBackend>(
    area: &Area<DB>,
    disc: Disc,
    radial: &Radial,
    sz: &Sizes,
) -> Result<(), String> {
    let Disc { cx, cy, r } = disc;
    let rf = r as f64;
    let thin = sz.px(1.0).max(1) as u32;
    let half = |frac: f64| {
        (-90..=90)
            .map(|d| disc.at(d as f64, frac))
            .collect::<Vec<_>>()
    };
    let rings = radial.rings();
    let label_w = |s: &str| (s.chars().count() as f64 * 0.62 * sz.tick).round() as i32;
    let centre = radial.centre_label();
    let centre_edge = label_w(&centre) / 2 + sz.px(6.0);
    let mut inner_edge = i32::MAX;
    for (i, (frac, label)) in rings.iter().enumerate().rev() {
        let outer = i + 1 == rings.len();
        let color = if outer { MUTED } else { GRID };
        draw::line(area, half(*frac), color, thin)?;
        let dx = (rf * frac).round() as i32;
        let hw = label_w(label) / 2;
        if dx + hw + sz.px(6.0) > inner_edge || dx - hw < centre_edge {
            continue;
        }
        inner_edge = dx - hw;
        for sx in [cx - dx, cx + dx] {
            draw::text(
                area,
                label,
                (sx, cy + sz.px(4.0)),
                sz.tick,
                MUTED,
                (HPos::Center, VPos::Top),
            )?;
        }
    }
    draw::text(
        area,
        &centre,
        (cx, cy + sz.px(4.0)),
        sz.tick,
        MUTED,
        (HPos::Center, VPos::Top),
    )?;
    draw::line(area, vec![(cx - r, cy), (cx + r, cy)], INK, thin)
}

/// The axis descriptions below the disc: which side faces the light, and what
/// the radius and angle are.
fn axis_notes<DB: DrawingBackend>(area: &Area<DB>, disc: Disc, sz: &Sizes) -> Result<(), String> {
    let Disc { cx, cy, r } = disc;
    let y1 = cy + (sz.tick * 1.6).round() as i32;
    draw::text(
        area,
        "← towards the light",
        (cx - r, y1),
        sz.tick,
        MUTED,
        (HPos::Left, VPos::Top),
    )?;
    draw::text(
        area,
        "forward →",
        (cx + r, y1),
        sz.tick,
        MUTED,
        (HPos::Right, VPos::Top),
    )?;
    draw::text(
        area,
        "radius: f_r (1/sr)   angle: θo (degrees)",
        (cx, y1 + (sz.tick * 1.6).round() as i32),
        sz.label,
        INK,
        (HPos::Center, VPos::Top),
    )
}

impl PolarFig {
    /// The legend: the incident angles (five a row), then how things are drawn.
    fn legend_rows(&self) -> Vec<Vec<Entry>> {
        let has_fit = self.panels.iter().any(|p| p.fit.is_some());
        let mut angles = Vec::new();
        for (j, t) in self.theta_i.iter().enumerate() {
            let c = draw::series_color(j);
            let mark = match (has_fit, self.data_as_lines) {
                (true, _) => Mark::LinePoint(c),
                (false, true) => Mark::Line(c),
                (false, false) => Mark::Point(c),
            };
            let empty = !self.data_as_lines && self.panels.iter().all(|p| p.data[j].is_empty());
            let suffix = if empty { " (no data)" } else { "" };
            angles.push(Entry::new(
                mark,
                format!("θi = {}{suffix}", draw::fmt_deg(*t)),
            ));
        }
        let mut rows: Vec<Vec<Entry>> = angles.chunks(5).map(<[Entry]>::to_vec).collect();
        let mut styles = Vec::new();
        if self.data_as_lines {
            styles.push(Entry::new(Mark::Line(MUTED), self.data_label.clone()));
        } else {
            styles.push(Entry::new(
                Mark::Point(MUTED),
                format!("{} (points)", self.data_label),
            ));
        }
        if has_fit {
            styles.push(Entry::new(
                Mark::Line(MUTED),
                format!("{} (lines)", self.fit_label),
            ));
        }
        styles.push(Entry::new(Mark::Triangle(MUTED), "light direction"));
        rows.push(styles);
        rows
    }
}

impl Figure for PolarFig {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        _cell: u32,
    ) -> Result<Vec<PanelRect>, String> {
        root.fill(&WHITE).map_err(draw::de)?;
        let sz = Sizes::for_area(root);
        let (w, h) = root.dim_in_pixel();
        let (w, h) = (w as i32, h as i32);
        let n = self.panels.len();
        let mut top = draw::title(root, &self.title, &sz)?;
        let phi = format!("plane of incidence at φi = {}", draw::fmt_deg(self.phi_i));
        let sub = if n == 1 {
            format!("channel {} · {phi}", self.panels[0].name)
        } else {
            phi
        };
        top += draw::subtitle(root, &sub, top, &sz)?;
        let rows = self.legend_rows();
        let leg_h = (sz.legend * 1.6).round() as i32 * rows.len() as i32 + sz.px(10.0);
        let region = (sz.px(8.0), top, w - sz.px(16.0), h - top - leg_h);
        let (r, c) = draw::grid_for(n, region.2 as f64, region.3 as f64, 2.0);
        let rects = draw::split(region, r, c, n);
        let mut out = Vec::new();
        for (p, rect) in self.panels.iter().zip(rects) {
            out.push(self.draw_panel(root, p, rect, n > 1, &sz)?);
        }
        draw::legend_rows(root, &rows, (w / 2, h - leg_h), &sz)?;
        Ok(out)
    }
}
