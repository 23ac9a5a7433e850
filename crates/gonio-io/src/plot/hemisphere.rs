//! Hemisphere maps of f_r · cos θo for one incident direction (Lafortune et al. 1997,
//! Figs. 12, 14), or of each direction's own colour: with
//! [`HemisphereOptions::true_colour`], the encoded sRGB of π · f_r — the reflectance
//! factor against a perfect diffuser, so a white Lambertian surface is white — of a
//! spectral or RGB BRDF (`crate::rgb`, `docs/colour.md`).

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

use gonio_brdf::Brdf;
use gonio_core::{Dir, Vec3};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::draw::{self, Area, Cells, INK, MUTED, NO_DATA, Sizes};
use super::eval::Evaluator;
use super::font::FAMILY;
use super::output::Figure;
use super::{
    ChannelChoice, HemisphereOptions, PanelRect, PlotErrorKind, Source, check_size, check_theta_i,
    same_channels, select,
};

/// How the outgoing hemisphere is flattened onto the page. Both put φo = 0 (the
/// sample's +x) to the right and φo = 90° up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Projection {
    /// The hemisphere projected orthographically onto the unit disk, and the disk
    /// mapped to the square [−1, 1]² by Shirley and Chiu's concentric map (the
    /// "uniform parametrization"): equal areas of the square are equal projected solid
    /// angles (∫ cos θo dωo), so the map's mean is the albedo / π. Circles of constant
    /// θo are squares of half-side sin θo.
    #[default]
    Concentric,
    /// The orthographic disk: x = sin θo cos φo, y = sin θo sin φo.
    Orthographic,
}

impl Projection {
    /// The name written on the plot.
    pub fn name(self) -> &'static str {
        match self {
            Projection::Concentric => {
                "concentric square (Shirley–Chiu) of the projected hemisphere"
            }
            Projection::Orthographic => "orthographic disk",
        }
    }

    /// The outgoing direction at a point of the map's [−1, 1]² square; `None` off the
    /// hemisphere.
    pub fn to_dir(self, u: f64, v: f64) -> Option<Dir> {
        let (x, y) = match self {
            Projection::Concentric => {
                if u.abs() > 1.0 || v.abs() > 1.0 {
                    return None;
                }
                concentric(u, v)
            }
            Projection::Orthographic => (u, v),
        };
        let r2 = x * x + y * y;
        if r2 >= 1.0 {
            return None;
        }
        Dir::new(Vec3::new(x, y, (1.0 - r2).sqrt()))
    }

    /// The point of the map where a direction of the upper hemisphere lies.
    pub fn to_map(self, d: Dir) -> (f64, f64) {
        match self {
            Projection::Concentric => concentric_inverse(d.x, d.y),
            Projection::Orthographic => (d.x, d.y),
        }
    }
}

/// Shirley and Chiu's concentric map of the square [−1, 1]² onto the unit disk (in
/// the form of Cline's note, as in PBRT).
fn concentric(a: f64, b: f64) -> (f64, f64) {
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, FRAC_PI_2 - FRAC_PI_4 * (a / b))
    };
    (r * phi.cos(), r * phi.sin())
}

/// The inverse of [`concentric`].
fn concentric_inverse(x: f64, y: f64) -> (f64, f64) {
    let r = x.hypot(y);
    if r == 0.0 {
        return (0.0, 0.0);
    }
    let mut phi = y.atan2(x);
    if phi < -FRAC_PI_4 {
        phi += TAU;
    }
    if phi < FRAC_PI_4 {
        (r, r * phi / FRAC_PI_4)
    } else if phi < 3.0 * FRAC_PI_4 {
        (r * (FRAC_PI_2 - phi) / FRAC_PI_4, r)
    } else if phi < 5.0 * FRAC_PI_4 {
        (-r, -r * (phi - PI) / FRAC_PI_4)
    } else {
        (-r * (3.0 * FRAC_PI_2 - phi) / FRAC_PI_4, -r)
    }
}

/// How values map to colours (viridis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ColorScale {
    /// Linear from 0 to the largest value.
    Linear,
    /// log₁₀ over this many decades below the largest value.
    Log {
        /// Decades shown (at least 1).
        decades: u32,
    },
}

pub(crate) struct HemiFig<'a> {
    data: Evaluator<'a>,
    fit: Option<&'a dyn Brdf>,
    ch: usize,
    channel_name: String,
    wi: Dir,
    theta_i: f64,
    phi_i: f64,
    projection: Projection,
    scale: ColorScale,
    levels: u32,
    max_gap: f64,
    title: String,
    data_label: String,
    fit_label: String,
    /// True colour: the matrix from the channels to linear sRGB, and the conditions.
    true_colour: Option<(Vec<[f64; 3]>, String)>,
}

pub(crate) fn build<'a>(
    data: &Source<'a>,
    fit: Option<&'a dyn Brdf>,
    theta_i_deg: f64,
    opts: &HemisphereOptions,
) -> Result<HemiFig<'a>, PlotErrorKind> {
    check_size(opts.size, (360, 240))?;
    check_theta_i(theta_i_deg)?;
    if !opts.phi_i_deg.is_finite() {
        return Err(PlotErrorKind::Input("φi is not a finite number".into()));
    }
    if let ColorScale::Log { decades } = opts.scale
        && !(1..=12).contains(&decades)
    {
        return Err(PlotErrorKind::Input(format!(
            "a logarithmic colour scale needs 1 to 12 decades, got {decades}"
        )));
    }
    if opts.levels == 1 || opts.levels > 256 {
        return Err(PlotErrorKind::Input(format!(
            "a banded colour map needs 2 to 256 levels (0 for a continuous one), got {}",
            opts.levels
        )));
    }
    if opts.max_gap_deg.is_nan() || opts.max_gap_deg <= 0.0 {
        return Err(PlotErrorKind::Input(format!(
            "the largest gap must be positive, got {}°",
            opts.max_gap_deg
        )));
    }
    same_channels(data.channels(), fit.map(|f| f.channels()))?;
    let chosen = match opts.channel {
        ChannelChoice::All => ChannelChoice::One(0),
        c => c,
    };
    let ch = select(chosen, data.channels())?[0];
    let true_colour = match &opts.true_colour {
        None => None,
        Some(conv) => Some((
            crate::rgb::rgb_matrix(data.channels(), conv)
                .map_err(|e| PlotErrorKind::Input(e.to_string()))?,
            conv.describe(),
        )),
    };
    let title = opts.title.clone().unwrap_or_else(|| {
        format!(
            "{} over the outgoing hemisphere, θi = {}, φi = {}",
            if true_colour.is_some() {
                "colour (sRGB of π · f_r)"
            } else {
                "f_r · cos θo"
            },
            draw::fmt_deg(theta_i_deg),
            draw::fmt_deg(opts.phi_i_deg)
        )
    });
    Ok(HemiFig {
        data: Evaluator::new(data, opts.kernel)?,
        fit,
        ch,
        channel_name: data.channels().name(ch),
        wi: Dir::from_angles(theta_i_deg.to_radians(), opts.phi_i_deg.to_radians()),
        theta_i: theta_i_deg,
        phi_i: opts.phi_i_deg,
        projection: opts.projection,
        scale: opts.scale,
        levels: opts.levels,
        max_gap: opts.max_gap_deg.to_radians(),
        title,
        data_label: opts.data_label.clone(),
        fit_label: opts.fit_label.clone(),
        true_colour,
    })
}

/// Maps values to [0, 1] for the colour map.
struct Scale {
    scale: ColorScale,
    vmax: f64,
}

impl Scale {
    fn t(&self, v: f64) -> f64 {
        match self.scale {
            ColorScale::Linear => v / self.vmax,
            ColorScale::Log { decades } => {
                if v > 0.0 {
                    1.0 + (v / self.vmax).log10() / decades as f64
                } else {
                    0.0
                }
            }
        }
    }

    /// (value, position in [0, 1]) of the colour bar's ticks.
    fn ticks(&self) -> Vec<(String, f64)> {
        match self.scale {
            ColorScale::Linear => {
                let step = draw::nice_step(self.vmax, 5);
                let n = (self.vmax / step + 1e-9).floor() as i64;
                (0..=n)
                    .map(|k| {
                        let v = k as f64 * step;
                        (draw::fmt_tick(v, step), v / self.vmax)
                    })
                    .collect()
            }
            ColorScale::Log { decades } => {
                let top = self.vmax.log10();
                let lo = top - decades as f64;
                let ms: &[u32] = if decades <= 3 { &[1, 2, 5] } else { &[1] };
                let mut out = Vec::new();
                for k in (lo.floor() as i32)..=(top.ceil() as i32) {
                    for &m in ms {
                        let lv = (m as f64).log10() + k as f64;
                        if lv >= lo - 1e-9 && lv <= top + 1e-9 {
                            out.push((draw::fmt_125(m, k), (lv - lo) / decades as f64));
                        }
                    }
                }
                out
            }
        }
    }
}

impl HemiFig<'_> {
    /// f_r · cos θo of one source over a map's plot rectangle; NaN where there is no
    /// data, `None` off the hemisphere.
    fn values(
        &self,
        b: &dyn Brdf,
        gaps: bool,
        rect: (i32, i32, i32, i32),
        cell: u32,
    ) -> Cells<Option<f64>> {
        let (x0, y0, w, h) = rect;
        let nc = b.channels().len();
        let sampled = if gaps { self.data.sampled() } else { None };
        Cells::sample(rect, cell, |px, py| {
            let u = 2.0 * (px - x0 as f64) / w as f64 - 1.0;
            let v = 1.0 - 2.0 * (py - y0 as f64) / h as f64;
            let wo = self.projection.to_dir(u, v)?;
            if let Some(s) = sampled
                && s.gap(self.wi, wo) > self.max_gap
            {
                return Some(f64::NAN);
            }
            let mut out = vec![0.0; nc];
            b.eval(self.wi, wo, &mut out);
            Some(out[self.ch] * wo.z)
        })
    }

    /// Each direction's encoded sRGB colour of π · f_r (linear sRGB through `m`,
    /// clipped to [0, 1], IEC 61966-2-1 encoding); [`NO_DATA`] where there is no data,
    /// `None` off the hemisphere.
    fn colours(
        &self,
        b: &dyn Brdf,
        gaps: bool,
        rect: (i32, i32, i32, i32),
        cell: u32,
        m: &[[f64; 3]],
    ) -> Cells<Option<RGBColor>> {
        let (x0, y0, w, h) = rect;
        let nc = b.channels().len();
        let sampled = if gaps { self.data.sampled() } else { None };
        Cells::sample(rect, cell, |px, py| {
            let u = 2.0 * (px - x0 as f64) / w as f64 - 1.0;
            let v = 1.0 - 2.0 * (py - y0 as f64) / h as f64;
            let wo = self.projection.to_dir(u, v)?;
            if let Some(s) = sampled
                && s.gap(self.wi, wo) > self.max_gap
            {
                return Some(NO_DATA);
            }
            let mut out = vec![0.0; nc];
            b.eval(self.wi, wo, &mut out);
            let linear = crate::rgb::apply(m, &out).map(|c| c * PI);
            let [r, g, bl] =
                gonio_core::colour::srgb::to_8bit(gonio_core::colour::srgb::encode_clipped(linear));
            Some(RGBColor(r, g, bl))
        })
    }

    fn overlays<DB: DrawingBackend>(
        &self,
        area: &Area<DB>,
        rect: (i32, i32, i32, i32),
        sz: &Sizes,
    ) -> Result<(), String> {
        let (x0, y0, w, h) = rect;
        let to_px = |u: f64, v: f64| {
            (
                x0 + ((u + 1.0) * 0.5 * w as f64).round() as i32,
                y0 + ((1.0 - v) * 0.5 * h as f64).round() as i32,
            )
        };
        let contour = RGBColor(255, 255, 255).mix(0.55);
        let thin = sz.px(1.0).max(1) as u32;
        let thetas: &[f64] = match self.projection {
            Projection::Concentric => &[30.0, 60.0],
            Projection::Orthographic => &[30.0, 60.0, 90.0],
        };
        for &t in thetas {
            let r = t.to_radians().sin();
            let pts: Vec<(i32, i32)> = match self.projection {
                Projection::Concentric => [(-r, -r), (r, -r), (r, r), (-r, r), (-r, -r)]
                    .iter()
                    .map(|&(u, v)| to_px(u, v))
                    .collect(),
                Projection::Orthographic => (0..=120)
                    .map(|k| {
                        let a = TAU * k as f64 / 120.0;
                        to_px(r * a.cos(), r * a.sin())
                    })
                    .collect(),
            };
            area.draw(&PathElement::new(pts, contour.stroke_width(thin)))
                .map_err(draw::de)?;
            if t < 90.0 {
                // Labelled across the plane of incidence, away from the markers.
                let a = (self.phi_i + 90.0).to_radians();
                let (u, v) = self.projection.to_map(Dir::from_angles(t.to_radians(), a));
                let at = to_px(u, v);
                draw::text(
                    area,
                    &format!("θo = {}", draw::fmt_deg(t)),
                    (at.0, at.1 - sz.px(3.0)),
                    sz.tick * 0.85,
                    WHITE,
                    (HPos::Center, VPos::Bottom),
                )?;
            }
        }
        // The light's direction (retro-reflection) and the mirror direction.
        let r = sz.px(7.0);
        let light = self.projection.to_map(self.wi);
        let mirror = self.projection.to_map(self.wi.mirror());
        let (lx, ly) = to_px(light.0, light.1);
        let (mx, my) = to_px(mirror.0, mirror.1);
        draw::light_and_mirror(
            area,
            (lx, ly),
            (mx, my),
            r,
            [(BLACK, sz.px(4.0)), (WHITE, sz.px(2.0))],
        )
    }
}

impl Figure for HemiFig<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        cell: u32,
    ) -> Result<Vec<PanelRect>, String> {
        root.fill(&WHITE).map_err(draw::de)?;
        let sz = Sizes::for_area(root);
        let (w, h) = root.dim_in_pixel();
        let (w, h) = (w as i32, h as i32);
        let mut top = draw::title(root, &self.title, &sz)?;
        top += draw::subtitle(root, &self.subtitle(), top, &sz)?;
        let mut names = vec![self.data_label.as_str()];
        if self.fit.is_some() {
            names.push(self.fit_label.as_str());
        }
        let n = names.len() as i32;
        let l = Layout::new(n, (w, h), top, &sz)?;
        let sources: Vec<(&dyn Brdf, bool)> = std::iter::once((self.data.brdf(), true))
            .chain(self.fit.map(|f| (f, false)))
            .collect();
        let rects: Vec<(i32, i32, i32, i32)> = (0..n)
            .map(|k| (l.x_plot + k * (l.side + l.gap), l.y_plot, l.side, l.side))
            .collect();
        let values: Vec<Cells<Option<f64>>> = match self.true_colour {
            Some(_) => Vec::new(),
            None => sources
                .iter()
                .zip(&rects)
                .map(|(&(b, gaps), &r)| self.values(b, gaps, r, cell))
                .collect(),
        };
        let true_colours: Option<Vec<Cells<Option<RGBColor>>>> =
            self.true_colour.as_ref().map(|(m, _)| {
                sources
                    .iter()
                    .zip(&rects)
                    .map(|(&(b, gaps), &r)| self.colours(b, gaps, r, cell, m))
                    .collect()
            });
        let vmax = values
            .iter()
            .flat_map(|c| c.v.iter().flatten())
            .filter(|v| v.is_finite())
            .fold(0.0f64, |a, &v| a.max(v));
        let scale = Scale {
            scale: self.scale,
            vmax: if vmax > 0.0 { vmax } else { 1.0 },
        };
        let colour = |t: f64| draw::viridis(band(t, self.levels));
        let mut out = Vec::new();
        for (k, (name, rect)) in names.iter().zip(&rects).enumerate() {
            let (x0, y0, s, _) = *rect;
            let left = if k == 0 { l.ylab } else { 0 };
            self.axes(root, *rect, left, l.xlab, &sz)?;
            match &true_colours {
                Some(c) => draw::paint(root, &c[k])?,
                None => {
                    let colours = values[k].map(|v| {
                        v.map(|v| {
                            if v.is_nan() {
                                NO_DATA
                            } else {
                                colour(scale.t(v))
                            }
                        })
                    });
                    draw::paint(root, &colours)?;
                }
            }
            self.overlays(root, *rect, &sz)?;
            out.push(draw::caption_square(
                root,
                name,
                (x0, y0),
                s,
                l.cap,
                sz.label,
                INK,
            )?);
        }
        if self.true_colour.is_none() {
            self.colour_bar(root, (w, l.y_plot, l.side, l.cbw), cell, &scale, &sz)?;
        }
        self.marks_note(root, &l, &sz)?;
        Ok(out)
    }
}

/// Where the maps go: the sizes of the colour bar, captions, axis labels, gaps
/// and note, the maps' common side, and the block's place.
struct Layout {
    cbw: i32,
    cap: i32,
    ylab: i32,
    xlab: i32,
    gap: i32,
    side: i32,
    block_w: i32,
    x_plot: i32,
    y_plot: i32,
}

impl Layout {
    /// The layout of `n` square maps side by side in an image `w` by `h` below
    /// `top`; the maps share the y axis, labelled on the first. An error when the
    /// image is too small for them.
    fn new(n: i32, (w, h): (i32, i32), top: i32, sz: &Sizes) -> Result<Layout, String> {
        let cbw = sz.px(130.0);
        let cap = (sz.label * 1.7).round() as i32;
        let ylab = sz.px(62.0);
        let xlab = sz.px(56.0);
        let gap = sz.px(40.0);
        let note = (sz.tick * 1.8).round() as i32;
        let avail_w = w - cbw - sz.px(12.0);
        let avail_h = h - top - sz.px(6.0);
        // The maps share the y axis, labelled on the first.
        let side = ((avail_w - ylab - (n - 1) * gap) / n).min(avail_h - cap - xlab - note);
        if side < 60 {
            return Err("the image is too small for the hemisphere map".into());
        }
        let block_w = ylab + n * side + (n - 1) * gap;
        let x_plot = (avail_w - block_w).max(0) / 2 + sz.px(6.0) + ylab;
        let y_plot = top + cap + (avail_h - cap - xlab - note - side).max(0) / 2;
        Ok(Layout {
            cbw,
            cap,
            ylab,
            xlab,
            gap,
            side,
            block_w,
            x_plot,
            y_plot,
        })
    }
}

impl HemiFig<'_> {
    /// The line below the title: the true-colour conditions or the channel, and
    /// the projection.
    fn subtitle(&self) -> String {
        match &self.true_colour {
            Some((_, conditions)) => format!(
                "encoded sRGB, {conditions} · projection: {}",
                self.projection.name()
            ),
            None => format!(
                "channel {} · projection: {}",
                self.channel_name,
                self.projection.name()
            ),
        }
    }

    /// A map's axes, in the projection's coordinates, with `left` pixels for the
    /// y axis's labels (none after the first map).
    fn axes<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        (x0, y0, s, _): (i32, i32, i32, i32),
        left: i32,
        xlab: i32,
        sz: &Sizes,
    ) -> Result<(), String> {
        let (xd, yd) = match self.projection {
            Projection::Concentric => ("u (concentric square)", "v (concentric square)"),
            Projection::Orthographic => ("x = sin θo cos φo", "y = sin θo sin φo"),
        };
        let sub = root
            .clone()
            .shrink((x0 - left, y0), ((left + s + 1) as u32, (s + xlab) as u32));
        let mut chart = ChartBuilder::on(&sub)
            .x_label_area_size(xlab)
            .y_label_area_size(left)
            .build_cartesian_2d(-1.0f64..1.0f64, -1.0f64..1.0f64)
            .map_err(draw::de)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(5)
            .y_labels(5)
            .x_label_formatter(&|v| draw::fmt_tick(*v, 0.5))
            .y_label_formatter(&|v| draw::fmt_tick(*v, 0.5))
            .label_style((FAMILY, sz.tick))
            .axis_desc_style((FAMILY, sz.label))
            .x_desc(xd)
            .y_desc(yd)
            .draw()
            .map_err(draw::de)
    }

    /// The note below the maps: what the markers mean, and the incident direction.
    fn marks_note<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        l: &Layout,
        sz: &Sizes,
    ) -> Result<(), String> {
        let marks = if self.data.sampled().is_some() {
            "○ towards the light   × mirror direction   grey: no sample nearby"
        } else {
            "○ towards the light   × mirror direction"
        };
        draw::text(
            root,
            &format!(
                "{marks}   (θi = {}, φi = {})",
                draw::fmt_deg(self.theta_i),
                draw::fmt_deg(self.phi_i)
            ),
            (
                l.x_plot - l.ylab + l.block_w / 2,
                l.y_plot + l.side + l.xlab + sz.px(4.0),
            ),
            sz.tick,
            MUTED,
            (HPos::Center, VPos::Top),
        )
    }

    /// The colour bar of the colour map, at the right of the image.
    fn colour_bar<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        (w, y_plot, side, cbw): (i32, i32, i32, i32),
        cell: u32,
        scale: &Scale,
        sz: &Sizes,
    ) -> Result<(), String> {
        let colour = |t: f64| draw::viridis(band(t, self.levels));
        let bx = w - cbw + sz.px(8.0);
        let bw = sz.px(22.0);
        let bar = (bx, y_plot, bw, side);
        let grad = Cells::sample(bar, cell, |_, py| {
            Some(colour(1.0 - (py - bar.1 as f64) / bar.3 as f64))
        });
        draw::paint(root, &grad)?;
        root.draw(&Rectangle::new(
            [(bx, bar.1), (bx + bw, bar.1 + bar.3)],
            INK.stroke_width(1),
        ))
        .map_err(draw::de)?;
        for (label, t) in scale.ticks() {
            let ty = bar.1 + ((1.0 - t) * bar.3 as f64).round() as i32;
            draw::line(
                root,
                vec![(bx + bw, ty), (bx + bw + sz.px(5.0), ty)],
                INK,
                1,
            )?;
            draw::text(
                root,
                &label,
                (bx + bw + sz.px(8.0), ty),
                sz.tick,
                INK,
                (HPos::Left, VPos::Center),
            )?;
        }
        draw::vtext(
            root,
            "f_r · cos θo (1/sr)",
            (w - sz.px(14.0), bar.1 + bar.3 / 2),
            sz.label,
            INK,
        )?;
        Ok(())
    }
}

/// `t` in [0, 1] snapped to the middle of one of `levels` bands (unchanged for 0).
fn band(t: f64, levels: u32) -> f64 {
    if levels == 0 {
        return t;
    }
    let n = levels as f64;
    (((t.clamp(0.0, 1.0) * n).floor().min(n - 1.0)) + 0.5) / n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concentric_round_trips() {
        for i in -10..=10 {
            for j in -10..=10 {
                let (a, b) = (i as f64 / 10.0, j as f64 / 10.0);
                let (x, y) = concentric(a, b);
                assert!(x.hypot(y) <= 1.0 + 1e-12);
                assert!((x.hypot(y) - a.abs().max(b.abs())).abs() < 1e-12);
                let (a2, b2) = concentric_inverse(x, y);
                assert!(
                    (a - a2).abs() < 1e-12 && (b - b2).abs() < 1e-12,
                    "{a} {b} → {a2} {b2}"
                );
            }
        }
    }

    /// A spectral Lambertian surface is drawn in its own colour everywhere: the
    /// encoded sRGB of its reflectance (π · f_r = ρ).
    #[test]
    fn true_colour_of_a_spectral_lambertian_surface_is_its_reflectance_colour() {
        let wl: Vec<f64> = (0..31).map(|i| 400.0 + 10.0 * i as f64).collect();
        // An orange: low in the blue, rising through the green into the red.
        let rho: Vec<f64> = wl
            .iter()
            .map(|l| 0.05 + 0.55 / (1.0 + (-(l - 580.0) / 20.0).exp()))
            .collect();
        let names: Vec<String> = wl.iter().map(|l| format!("\"{l}nm\"")).collect();
        let values: Vec<String> = rho.iter().map(|r| r.to_string()).collect();
        let toml = format!(
            "kind = \"lambert\"\nchannels = [{}]\nrho = [{}]\n",
            names.join(", "),
            values.join(", ")
        );
        let m = gonio_brdf::Model::from_toml(&toml, None).unwrap();
        let opts = HemisphereOptions {
            true_colour: Some(crate::rgb::Conversion::default()),
            ..HemisphereOptions::default()
        };
        let mut buf = Vec::new();
        let drawn = crate::plot::hemisphere(
            crate::plot::Output::Rgb(&mut buf),
            &Source::Model(&m),
            None,
            30.0,
            &opts,
        )
        .unwrap();
        let c = gonio_core::colour::Colorimeter::new(
            gonio_core::colour::Observer::Cie1931,
            gonio_core::colour::Illuminant::D65,
        );
        let expect = c.colour(&wl, &rho).unwrap().srgb8;
        assert!(expect[0] > expect[1] && expect[1] > expect[2], "{expect:?}");
        let p = &drawn.panels[0];
        let w = drawn.size.0 as usize;
        let at = |x: i32, y: i32| {
            let i = (y as usize * w + x as usize) * 3;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        // The centre (the normal) and most of the panel: the reflectance's colour.
        assert_eq!(at((p.x0 + p.x1) / 2, (p.y0 + p.y1) / 2), expect);
        let same = (p.y0..p.y1)
            .flat_map(|y| (p.x0..p.x1).map(move |x| (x, y)))
            .filter(|&(x, y)| at(x, y) == expect)
            .count();
        let area = ((p.x1 - p.x0) * (p.y1 - p.y0)) as usize;
        assert!(same as f64 > 0.9 * area as f64, "{same} of {area}");
        // RGB input is taken as linear sRGB, and 3 wavelengths cannot make a colour.
        let short = gonio_brdf::Model::from_toml(
            "kind = \"lambert\"\nchannels = [\"450nm\", \"550nm\", \"650nm\"]\nrho = [0.1, 0.2, 0.3]\n",
            None,
        )
        .unwrap();
        let e = crate::plot::hemisphere(
            crate::plot::Output::Rgb(&mut buf),
            &Source::Model(&short),
            None,
            30.0,
            &opts,
        )
        .unwrap_err();
        assert!(e.is_input() && e.to_string().contains("450–650 nm"), "{e}");
    }

    #[test]
    fn projections_put_phi_zero_right() {
        for p in [Projection::Concentric, Projection::Orthographic] {
            let d = Dir::from_angles(0.5, 0.0);
            let (u, v) = p.to_map(d);
            assert!(u > 0.0 && v.abs() < 1e-12);
            let back = p.to_dir(u, v).expect("on the hemisphere");
            assert!(back.angle_to(d) < 1e-12);
        }
    }
}
