//! A sphere rendered under a directional light, from the data and from the fit.

use gonio_brdf::Brdf;
use gonio_core::{Channels, Dir, Frame, Vec3};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::draw::{self, Area, Cells, INK, MUTED, Sizes};
use super::eval::Evaluator;
use super::output::Figure;
use super::{
    ChannelChoice, PanelRect, PlotErrorKind, Source, SphereOptions, check_size, same_channels,
    select,
};

/// The largest side of a sphere's square, in pixels at the figure's scale: larger
/// spheres show nothing more and make PNG files large.
const MAX_SIDE: f64 = 280.0;

/// The percentile of the data's lit pixels that the automatic exposure maps to white.
const AUTO_PERCENTILE: f64 = 0.99;

/// How channels become a displayed colour.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Display {
    /// R, G, B as they are.
    Rgb,
    /// One channel in grey.
    Grey(usize),
    /// The mean of all channels in grey.
    GreyMean,
}

pub(crate) struct SphereFig<'a> {
    data: Evaluator<'a>,
    fit: Option<&'a dyn Brdf>,
    display: Display,
    display_name: String,
    light: Vec3,
    exposure: Option<f64>,
    gamma: f64,
    theta_l: f64,
    phi_l: f64,
    title: String,
    data_label: String,
    fit_label: String,
}

pub(crate) fn build<'a>(
    data: &Source<'a>,
    fit: Option<&'a dyn Brdf>,
    opts: &SphereOptions,
) -> Result<SphereFig<'a>, PlotErrorKind> {
    check_size(opts.size, (240, 160))?;
    if !(0.0..180.0).contains(&opts.light_theta_deg) || !opts.light_phi_deg.is_finite() {
        return Err(PlotErrorKind::Input(format!(
            "the light must lie at θ in [0°, 180°) from the view axis with a finite azimuth, \
             got θ = {}°, φ = {}°",
            opts.light_theta_deg, opts.light_phi_deg
        )));
    }
    if let Some(e) = opts.exposure
        && !(e > 0.0 && e.is_finite())
    {
        return Err(PlotErrorKind::Input(format!(
            "the exposure must be positive, got {e}"
        )));
    }
    if !(opts.gamma > 0.0 && opts.gamma.is_finite()) {
        return Err(PlotErrorKind::Input(format!(
            "gamma must be positive, got {}",
            opts.gamma
        )));
    }
    let channels = data.channels();
    same_channels(channels, fit.map(|f| f.channels()))?;
    let chosen = select(opts.channel, channels)?;
    let (display, display_name) = match (opts.channel, channels) {
        (ChannelChoice::All, Channels::Rgb) => (Display::Rgb, "R, G, B in colour".to_string()),
        (ChannelChoice::All, c) if c.len() > 1 => {
            (Display::GreyMean, format!("mean of {c} in grey"))
        }
        _ => (
            Display::Grey(chosen[0]),
            format!("channel {} in grey", channels.name(chosen[0])),
        ),
    };
    let (t, p) = (
        opts.light_theta_deg.to_radians(),
        opts.light_phi_deg.to_radians(),
    );
    let light = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
    let title = opts
        .title
        .clone()
        .unwrap_or_else(|| "A sphere under a directional light".to_string());
    Ok(SphereFig {
        data: Evaluator::new(data, opts.kernel)?,
        fit,
        display,
        display_name,
        light,
        exposure: opts.exposure,
        gamma: opts.gamma,
        theta_l: opts.light_theta_deg,
        phi_l: opts.light_phi_deg,
        title,
        data_label: opts.data_label.clone(),
        fit_label: opts.fit_label.clone(),
    })
}

impl SphereFig<'_> {
    /// Outgoing radiance towards the camera at the image-plane point (nx, ny) of the
    /// unit sphere, for unit irradiance normal to the light, as a displayed RGB triple;
    /// zero off the sphere and where the light is below the local horizon.
    fn radiance(&self, b: &dyn Brdf, nx: f64, ny: f64, buf: &mut [f64]) -> [f64; 3] {
        let r2 = nx * nx + ny * ny;
        if r2 >= 1.0 {
            return [0.0; 3];
        }
        let Some(n) = Dir::new(Vec3::new(nx, ny, (1.0 - r2).sqrt())) else {
            return [0.0; 3];
        };
        let Some(frame) = Frame::from_normal_and_reference(n, Vec3::X) else {
            return [0.0; 3];
        };
        let (Some(wi), Some(wo)) = (
            Dir::new(frame.to_local(self.light)),
            Dir::new(frame.to_local(Vec3::Z)),
        ) else {
            return [0.0; 3];
        };
        if !wi.is_above() || !wo.is_above() {
            return [0.0; 3];
        }
        b.eval(wi, wo, buf);
        let c = wi.z;
        match self.display {
            Display::Rgb => [buf[0] * c, buf[1] * c, buf[2] * c],
            Display::Grey(k) => [buf[k] * c; 3],
            Display::GreyMean => [buf.iter().sum::<f64>() / buf.len() as f64 * c; 3],
        }
    }

    fn render(&self, b: &dyn Brdf, rect: (i32, i32, i32, i32), cell: u32) -> Cells<[f64; 3]> {
        let (x0, y0, s, _) = rect;
        let rad = 0.48 * s as f64;
        let (cx, cy) = (x0 as f64 + 0.5 * s as f64, y0 as f64 + 0.5 * s as f64);
        let nc = b.channels().len();
        Cells::sample(rect, cell, |px, py| {
            let mut buf = vec![0.0; nc];
            self.radiance(b, (px - cx) / rad, (cy - py) / rad, &mut buf)
        })
    }
}

/// The automatic exposure: the reciprocal of the given percentile of the brightest
/// channel of the lit pixels (1 when nothing is lit).
fn auto_exposure(cells: &Cells<[f64; 3]>) -> f64 {
    let mut lit: Vec<f64> = cells
        .v
        .iter()
        .map(|c| c[0].max(c[1]).max(c[2]))
        .filter(|v| *v > 0.0 && v.is_finite())
        .collect();
    if lit.is_empty() {
        return 1.0;
    }
    lit.sort_by(f64::total_cmp);
    let k = ((lit.len() - 1) as f64 * AUTO_PERCENTILE).round() as usize;
    1.0 / lit[k.min(lit.len() - 1)]
}

impl Figure for SphereFig<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &Area<DB>,
        cell: u32,
    ) -> Result<Vec<PanelRect>, String> {
        root.fill(&WHITE).map_err(draw::de)?;
        let sz = Sizes::for_area(root);
        let (w, h) = root.dim_in_pixel();
        let (w, h) = (w as i32, h as i32);
        let top = draw::title(root, &self.title, &sz)?;
        let cap = (sz.label * 1.7).round() as i32;
        let note = (sz.tick * 1.45).round() as i32 * 4 + sz.px(10.0);
        let gap = sz.px(24.0);
        let mut names = vec![self.data_label.as_str()];
        if self.fit.is_some() {
            names.push(self.fit_label.as_str());
        }
        let n = names.len() as i32;
        let side = ((w - sz.px(16.0) - (n - 1) * gap) / n)
            .min(h - top - cap - note - sz.px(6.0))
            .min(sz.px(MAX_SIDE));
        if side < 40 {
            return Err("the image is too small for the spheres".into());
        }
        let x_start = (w - n * side - (n - 1) * gap) / 2;
        let y0 = top + cap + (h - top - cap - note - sz.px(6.0) - side).max(0) / 2;
        let rects: Vec<(i32, i32, i32, i32)> = (0..n)
            .map(|k| (x_start + k * (side + gap), y0, side, side))
            .collect();
        let sources: Vec<&dyn Brdf> = std::iter::once(self.data.brdf()).chain(self.fit).collect();
        let images: Vec<Cells<[f64; 3]>> = sources
            .iter()
            .zip(&rects)
            .map(|(b, r)| self.render(*b, *r, cell))
            .collect();
        let exposure = self.exposure.unwrap_or_else(|| auto_exposure(&images[0]));
        let inv_gamma = 1.0 / self.gamma;
        let tone = |v: f64| -> u8 {
            let x = (exposure * v).clamp(0.0, 1.0).powf(inv_gamma);
            (255.0 * x).round() as u8
        };
        let mut out = Vec::new();
        for ((name, rect), img) in names.iter().zip(&rects).zip(&images) {
            let (x0, y0, s, _) = *rect;
            root.draw(&Rectangle::new(
                [(x0, y0), (x0 + s, y0 + s)],
                BLACK.filled(),
            ))
            .map_err(draw::de)?;
            let colours = img.map(|c| {
                let rgb = RGBColor(tone(c[0]), tone(c[1]), tone(c[2]));
                (rgb != RGBColor(0, 0, 0)).then_some(rgb)
            });
            draw::paint(root, &colours)?;
            out.push(draw::caption_square(
                root,
                name,
                (x0, y0),
                s,
                cap,
                sz.label,
                INK,
            )?);
        }
        let lines = [
            format!(
                "orthographic view · directional light at {} from the view axis, azimuth {} \
                 (from image +x towards +y)",
                draw::fmt_deg(self.theta_l),
                draw::fmt_deg(self.phi_l)
            ),
            "local frame: z = the normal, x = image x projected on the tangent plane · \
             L = f_r(wi, wo) · cos θi"
                .to_string(),
            format!(
                "pixel = 255 · clamp(exposure · L, 0, 1)^(1/{}), exposure = {} sr{}",
                trim(self.gamma),
                sig3(exposure),
                if self.exposure.is_none() {
                    " (auto)"
                } else {
                    ""
                },
            ),
            if self.exposure.is_none() {
                format!(
                    "auto exposure: the data's 99th-percentile pixel maps to white · {}",
                    self.display_name
                )
            } else {
                self.display_name.clone()
            },
        ];
        let line_h = (sz.tick * 1.45).round() as i32;
        let y_note = y0 + side + sz.px(8.0);
        for (k, l) in lines.iter().enumerate() {
            draw::text(
                root,
                l,
                (w / 2, y_note + k as i32 * line_h),
                sz.tick,
                MUTED,
                (HPos::Center, VPos::Top),
            )?;
        }
        Ok(out)
    }
}

/// A number with three significant digits.
fn sig3(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let d = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.d$}")
}

/// A number without trailing zeros.
fn trim(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}
