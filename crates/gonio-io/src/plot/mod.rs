//! Plots of BRDFs, drawn with plotters and the DejaVu Sans font shipped in
//! `assets/fonts` (embedded in the binary; no system font is ever looked up).
//!
//! Five kinds of figure, after Lafortune et al. 1997 and DeYoung's thesis:
//!
//! - [`polar`]: f_r in the plane of incidence for several θi (Lafortune Figs. 11, 13).
//!   The outgoing direction sits at the signed angle θo from the normal: negative
//!   towards the light (backward, the retro-reflection side, drawn on the left),
//!   positive away from it (forward, the specular side, on the right). The radius is
//!   f_r in 1/sr, linear or logarithmic.
//! - [`hemisphere`]: f_r · cos θo over the outgoing hemisphere for one θi as a colour
//!   map with a colour bar (Lafortune Figs. 12, 14), in a named [`Projection`].
//! - [`albedo`]: the directional albedo ρ(θi) = ∫ f_r cos θo dωo per channel, and for a
//!   Lafortune model per term (the diffuse term, each lobe, the mirror term;
//!   Lafortune Figs. 4b, 7b, 9b), from [`Brdf::albedo`].
//! - [`spectral_albedo`]: for wavelength channels, the directional albedo against
//!   wavelength, one curve per θi ([`spectral_albedo_values`] gives its numbers).
//! - [`separability`]: P_s^(k) against k (DeYoung Fig. 5.9) from
//!   [`gonio_process::measure::separability`].
//! - [`sphere`]: a sphere rendered under a directional light, for the data and the
//!   fit side by side (see [`SphereOptions`] for the camera, the local frames and the
//!   tone mapping).
//! - [`sample_points`]: where an adaptive run's points went — the sample directions
//!   on the outgoing hemisphere, a panel per incidence, coloured by the stage that
//!   chose them ([`batch_colour`]).
//!
//! **Inputs.** The data is a [`Source`]: any [`Brdf`] (a model, a table, a MERL file),
//! an analytic [`Model`] (whose terms the albedo plot can split), or scattered
//! [`Samples`]. Samples are drawn as points where they lie in the plane of incidence
//! (polar plot) and interpolated with the nearest-j Gaussian kernel of
//! [`Samples::interpolator`] elsewhere. The optional fit is any [`Brdf`] (a [`Model`]
//! for the albedo plot, so that its terms can be drawn).
//!
//! **Style.** Data are points and models are lines: the data is drawn as points when a
//! fit is given or when it is scattered samples, and as lines when it is an analytic
//! or tabulated BRDF shown alone.
//!
//! **Outputs.** An [`Output`]: a file whose extension (`.png` or `.svg`) picks the
//! format, an SVG string or PNG bytes in memory (for the HTML report), or a raw RGB
//! buffer (for tests). Every function returns the pixel rectangles of its data
//! regions ([`Drawn`]). In SVG the colour maps and spheres are drawn as rectangles of
//! at least [`SVG_CELL`] pixels (at most 72 across a map or sphere), merged along
//! rows where the colour repeats; PNG has one sample per pixel. A continuous colour
//! map still makes a large SVG (several hundred kB): for embedding, prefer the PNG,
//! or a banded map ([`HemisphereOptions::levels`]).

mod albedo;
mod draw;
mod eval;
mod font;
pub use font::dejavu_sans;
mod hemisphere;
mod output;
mod points;
mod polar;
mod separability;
mod sphere;

use std::path::Path;

use gonio_brdf::{Brdf, Model};
use gonio_core::Channels;
use gonio_process::samples::Kernel;
use gonio_process::{ProcessError, Samples, Table};

pub use albedo::SpectralAlbedo;
pub use hemisphere::{ColorScale, Projection};
pub use polar::RadialScale;

/// Smallest side, in pixels, of the cells colour maps and rendered spheres are drawn
/// with in SVG output (PNG output samples every pixel).
pub const SVG_CELL: u32 = 4;

/// What a plot shows as "data".
#[derive(Clone, Copy)]
pub enum Source<'a> {
    /// Any BRDF: a table, a MERL file, a model behind a trait object.
    Brdf(&'a dyn Brdf),
    /// An analytic model; for a Lafortune model the albedo plot also draws each term.
    Model(&'a Model),
    /// Scattered samples: points in the polar plot, the nearest-j kernel elsewhere.
    Samples(&'a Samples),
}

impl Source<'_> {
    /// The channels of the data.
    pub fn channels(&self) -> &Channels {
        match self {
            Source::Brdf(b) => b.channels(),
            Source::Model(m) => m.channels(),
            Source::Samples(s) => &s.channels,
        }
    }
}

/// Which channels a plot shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ChannelChoice {
    /// Every channel (one panel a channel for the polar and albedo plots, one series a
    /// channel for separability, colour for an RGB sphere). The hemisphere map, which
    /// needs one channel, shows the first.
    #[default]
    All,
    /// Only the channel of this index.
    One(usize),
}

/// Where a plot goes.
pub enum Output<'a> {
    /// A file; its extension (`.png` or `.svg`, any case) picks the format.
    File(&'a Path),
    /// An SVG document, written to the string (replacing its content).
    Svg(&'a mut String),
    /// A PNG file's bytes, written to the vector (replacing its content).
    Png(&'a mut Vec<u8>),
    /// Raw 8-bit RGB pixels, row by row from the top left, `width × height × 3` bytes
    /// (the vector is resized to that).
    Rgb(&'a mut Vec<u8>),
}

impl Output<'_> {
    /// How errors name this output: the file's path, or what is in memory.
    pub fn target(&self) -> String {
        match self {
            Output::File(p) => p.display().to_string(),
            Output::Svg(_) => "<SVG in memory>".into(),
            Output::Png(_) => "<PNG in memory>".into(),
            Output::Rgb(_) => "<RGB buffer>".into(),
        }
    }
}

/// The pixel rectangle of one data region of a drawn figure: `x0..x1` × `y0..y1`,
/// from the top left of the image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PanelRect {
    /// What the region shows (`"550nm"`, `"data"`, `"fit"`, …).
    pub label: String,
    /// First column.
    pub x0: i32,
    /// First row.
    pub y0: i32,
    /// One past the last column.
    pub x1: i32,
    /// One past the last row.
    pub y1: i32,
}

/// What a plot function drew: the image size and its data regions.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Drawn {
    /// Width and height in pixels.
    pub size: (u32, u32),
    /// The data regions (plot areas, maps, spheres), in drawing order.
    pub panels: Vec<PanelRect>,
}

/// Why a plot was not made; names the output it was for.
#[derive(Debug, thiserror::Error)]
#[error("{target}: {kind}")]
pub struct PlotError {
    /// The output: a file's path, or `<SVG in memory>` and the like.
    pub target: String,
    /// What went wrong.
    pub kind: PlotErrorKind,
}

impl PlotError {
    /// True when the request itself was wrong (an extension, a channel, an angle, data
    /// that cannot be plotted), false for a failure while drawing or writing.
    pub fn is_input(&self) -> bool {
        matches!(
            self.kind,
            PlotErrorKind::Extension | PlotErrorKind::Input(_) | PlotErrorKind::Process(_)
        )
    }
}

/// The kinds of [`PlotError`].
#[derive(Debug, thiserror::Error)]
pub enum PlotErrorKind {
    /// The file extension is neither `.png` nor `.svg`.
    #[error("unsupported output extension (expected .png or .svg)")]
    Extension,
    /// A request that cannot be drawn: a channel out of range, an angle outside
    /// [0°, 90°), a size too small, nothing to plot.
    #[error("{0}")]
    Input(String),
    /// Processing refused the data (separability of a table, the sample kernel).
    #[error("{0}")]
    Process(#[from] ProcessError),
    /// The drawing backend failed.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// Writing or reading the output failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The embedded font was refused by the font engine.
    #[error("the embedded font DejaVu Sans could not be registered")]
    Font,
}

/// Options of [`polar`].
#[derive(Clone, Debug, PartialEq)]
pub struct PolarOptions {
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Channels: one panel a channel.
    pub channel: ChannelChoice,
    /// Azimuth of the plane of incidence, degrees (the light at φi, the forward side at
    /// φi + 180°).
    pub phi_i_deg: f64,
    /// Radius: linear in f_r, or logarithmic over some decades.
    pub scale: RadialScale,
    /// Spacing of the points drawn for data that is a BRDF, degrees of θo.
    pub data_step_deg: f64,
    /// How far, in degrees, a sample may lie from the plane of incidence (in azimuth)
    /// and from a requested θi to be drawn.
    pub tolerance_deg: f64,
    /// The title; `None` for the default one.
    pub title: Option<String>,
    /// The name of the data in the legend.
    pub data_label: String,
    /// The name of the fit in the legend.
    pub fit_label: String,
}

impl Default for PolarOptions {
    fn default() -> Self {
        PolarOptions {
            size: (900, 700),
            channel: ChannelChoice::All,
            phi_i_deg: 0.0,
            scale: RadialScale::Linear,
            data_step_deg: 5.0,
            tolerance_deg: 2.5,
            title: None,
            data_label: "data".into(),
            fit_label: "fit".into(),
        }
    }
}

/// Options of [`hemisphere`].
#[derive(Clone, Debug, PartialEq)]
pub struct HemisphereOptions {
    /// Image size in pixels.
    pub size: (u32, u32),
    /// The channel mapped (a colour map shows one; `All` shows the first).
    pub channel: ChannelChoice,
    /// Azimuth of the incident direction, degrees.
    pub phi_i_deg: f64,
    /// How the outgoing hemisphere is flattened.
    pub projection: Projection,
    /// Colour scale of f_r · cos θo.
    pub scale: ColorScale,
    /// Number of discrete colour bands (filled contours, which also keep PNG files
    /// small), or 0 for a continuous colour map.
    pub levels: u32,
    /// The kernel that interpolates [`Source::Samples`].
    pub kernel: Kernel,
    /// For samples: directions farther than this (degrees, in the kernel's distance
    /// over both directions) from every sample are shown grey, as "no data".
    pub max_gap_deg: f64,
    /// The title; `None` for the default one.
    pub title: Option<String>,
    /// The name of the data panel.
    pub data_label: String,
    /// The name of the fit panel.
    pub fit_label: String,
    /// Draw each direction in its own colour (encoded sRGB of π · f_r under these
    /// conditions, `crate::rgb`) instead of a colour map of one channel.
    pub true_colour: Option<crate::rgb::Conversion>,
}

impl Default for HemisphereOptions {
    fn default() -> Self {
        HemisphereOptions {
            size: (900, 560),
            channel: ChannelChoice::All,
            phi_i_deg: 0.0,
            projection: Projection::Concentric,
            scale: ColorScale::Linear,
            levels: 0,
            kernel: Kernel::default(),
            max_gap_deg: 10.0,
            title: None,
            data_label: "data".into(),
            fit_label: "fit".into(),
            true_colour: None,
        }
    }
}

/// Options of [`albedo`].
#[derive(Clone, Debug, PartialEq)]
pub struct AlbedoOptions {
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Channels: one panel a channel.
    pub channel: ChannelChoice,
    /// Azimuth of the incident directions, degrees (matters for anisotropic data).
    pub phi_i_deg: f64,
    /// Spacing of θi, degrees (from 0° to 89°).
    pub step_deg: f64,
    /// Whether the terms of a Lafortune model are drawn besides its total.
    pub terms: bool,
    /// The kernel that interpolates [`Source::Samples`] (whose albedo is integrated
    /// over the interpolated hemisphere: meaningful only for samples that cover it).
    pub kernel: Kernel,
    /// The title; `None` for the default one.
    pub title: Option<String>,
    /// The name of the data in the legend.
    pub data_label: String,
    /// The name of the fit in the legend.
    pub fit_label: String,
}

impl Default for AlbedoOptions {
    fn default() -> Self {
        AlbedoOptions {
            size: (900, 700),
            channel: ChannelChoice::All,
            phi_i_deg: 0.0,
            step_deg: 2.5,
            terms: true,
            kernel: Kernel::default(),
            title: None,
            data_label: "data".into(),
            fit_label: "fit".into(),
        }
    }
}

/// Options of [`separability`].
#[derive(Clone, Debug, PartialEq)]
pub struct SeparabilityOptions {
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Channels: one series a table and channel.
    pub channel: ChannelChoice,
    /// The title; `None` for the default one.
    pub title: Option<String>,
}

impl Default for SeparabilityOptions {
    fn default() -> Self {
        SeparabilityOptions {
            size: (900, 700),
            channel: ChannelChoice::All,
            title: None,
        }
    }
}

/// Options of [`sphere`].
///
/// **Camera and light.** The view is orthographic along the camera axis: image x to
/// the right, y up, the camera looking down −z onto a unit sphere. The light is
/// directional, at `light_theta_deg` from the view axis and `light_phi_deg` from the
/// image's +x towards +y (135° puts it at the upper left).
///
/// **Local frames.** At each visible point the normal is the local z; the local x is
/// the image's x axis projected onto the tangent plane (so the sample's reference
/// direction runs left to right across the sphere). With `wi` the light direction and
/// `wo` the view direction in that frame, the outgoing radiance for unit irradiance
/// normal to the light is `L = f_r(wi, wo) · cos θi` per channel; points where the
/// light is below the local horizon are black, and so is everything off the sphere.
/// Any mirror (delta) term is not drawn.
///
/// **Tone mapping.** Pixel value = `255 · clamp(exposure · L, 0, 1)^(1/gamma)`. The
/// exposure is the option's, or by default the reciprocal of the 99th percentile of
/// the data's lit pixels (their brightest channel), so the data fills the range with
/// only its sharpest highlights clipped; the same exposure is applied to the fit, so
/// the two spheres compare. R/G/B data are shown in colour; other channels in grey
/// (the chosen channel, or the mean of all).
#[derive(Clone, Debug, PartialEq)]
pub struct SphereOptions {
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Channels shown.
    pub channel: ChannelChoice,
    /// Light direction: angle from the view axis, degrees, in [0°, 180°).
    pub light_theta_deg: f64,
    /// Light direction: azimuth from the image's +x towards +y, degrees.
    pub light_phi_deg: f64,
    /// Exposure (multiplies the radiance, in sr); `None` for automatic.
    pub exposure: Option<f64>,
    /// Display gamma (2.2 for a typical screen).
    pub gamma: f64,
    /// The kernel that interpolates [`Source::Samples`].
    pub kernel: Kernel,
    /// The title; `None` for the default one.
    pub title: Option<String>,
    /// The name of the data sphere.
    pub data_label: String,
    /// The name of the fit sphere.
    pub fit_label: String,
}

impl Default for SphereOptions {
    fn default() -> Self {
        SphereOptions {
            size: (900, 520),
            channel: ChannelChoice::All,
            light_theta_deg: 45.0,
            light_phi_deg: 135.0,
            exposure: None,
            gamma: 2.2,
            kernel: Kernel::default(),
            title: None,
            data_label: "data".into(),
            fit_label: "fit".into(),
        }
    }
}

/// Options of [`sample_points`].
#[derive(Clone, Debug, PartialEq)]
pub struct PointsOptions {
    /// Image size in pixels ([`PointsOptions::size_for`] fits it to the incidences).
    pub size: (u32, u32),
    /// The title; `None` for the default one.
    pub title: Option<String>,
}

impl Default for PointsOptions {
    fn default() -> Self {
        PointsOptions {
            size: (900, 560),
            title: None,
        }
    }
}

impl PointsOptions {
    /// An image size that gives each of `incidences` panels room (two a row past two).
    pub fn size_for(incidences: usize) -> (u32, u32) {
        if incidences <= 2 {
            (900, 560)
        } else {
            let rows = incidences.div_ceil(2).min(16) as u32;
            (900, 160 + 400 * rows)
        }
    }
}

/// Sample directions on the outgoing hemisphere, one panel per incidence (θi, φi):
/// each `(batch, pair)` is a point at radius ∝ θo and angle φo (azimuthal
/// equidistant), coloured by its batch ([`batch_colour`]; 0 is the coarse pass,
/// `batches` the last batch), with the light's direction (○) and the mirror
/// direction (×) marked, a colour bar of the batches and a legend. The panels are
/// labelled `θi = …, φi = …: N points`.
pub fn sample_points(
    out: Output<'_>,
    points: &[(usize, gonio_core::dirfile::PairDeg)],
    batches: usize,
    opts: &PointsOptions,
) -> Result<Drawn, PlotError> {
    let fig = points::build(points, batches, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

/// The colour [`sample_points`] draws `batch` in (0 = the coarse pass) when the run
/// has `batches` batches after it, as 8-bit sRGB: grey for the coarse pass, viridis
/// from its dark end (batch 1) towards its light end (the last batch).
pub fn batch_colour(batch: usize, batches: usize) -> [u8; 3] {
    let c = points::colour(batch, batches);
    [c.0, c.1, c.2]
}

/// Polar plot of f_r in the plane of incidence, one curve per θi (degrees, in
/// [0°, 90°)): data as points, the fit as lines, one panel a channel. Samples are
/// drawn where they lie within [`PolarOptions::tolerance_deg`] of the plane and of a
/// requested θi.
pub fn polar(
    out: Output<'_>,
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: &[f64],
    opts: &PolarOptions,
) -> Result<Drawn, PlotError> {
    let fig = polar::build(data, fit, theta_i_deg, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

/// Hemisphere map of f_r · cos θo for the incident direction at `theta_i_deg`: the
/// data, and the fit beside it when given, with one colour bar.
pub fn hemisphere(
    out: Output<'_>,
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: f64,
    opts: &HemisphereOptions,
) -> Result<Drawn, PlotError> {
    let fig = hemisphere::build(data, fit, theta_i_deg, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

/// Directional albedo against θi, one panel a channel: the data's total, the fit's
/// total, and (with [`AlbedoOptions::terms`]) each term of a Lafortune model drawn
/// as lines (the fit's, or the data's when it is a model shown alone).
pub fn albedo(
    out: Output<'_>,
    data: &Source<'_>,
    fit: Option<&Model>,
    opts: &AlbedoOptions,
) -> Result<Drawn, PlotError> {
    let fig = albedo::build(data, fit, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

/// Directional albedo against wavelength for data with wavelength channels: one
/// curve per θi in `theta_i_deg` (degrees, in [0°, 90°)), at
/// [`AlbedoOptions::phi_i_deg`]; the data as lines when shown alone, as points when a
/// fit (drawn as lines, the same colour per θi) is given or the data are samples.
/// [`AlbedoOptions::channel`], `step_deg` and `terms` do not apply.
pub fn spectral_albedo(
    out: Output<'_>,
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: &[f64],
    opts: &AlbedoOptions,
) -> Result<Drawn, PlotError> {
    let fig = albedo::build_spectral(data, fit, theta_i_deg, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

/// The numbers [`spectral_albedo`] draws, without drawing them; errors name
/// `<spectral albedo>` as their target.
pub fn spectral_albedo_values(
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    theta_i_deg: &[f64],
    opts: &AlbedoOptions,
) -> Result<SpectralAlbedo, PlotError> {
    albedo::build_spectral(data, fit, theta_i_deg, opts)
        .map(|f| f.values().clone())
        .map_err(|kind| PlotError {
            target: "<spectral albedo>".into(),
            kind,
        })
}

/// P_s^(k) against k for each named table (DeYoung Eq. 4.20, Fig. 5.9), on a log
/// scale. `ks` empty means 1 to 20 (capped by the matrix's rank). Values below 1e-12
/// of a series' largest are numerical zeros and are not drawn.
pub fn separability(
    out: Output<'_>,
    tables: &[(&str, &Table)],
    ks: &[usize],
    opts: &SeparabilityOptions,
) -> Result<Drawn, PlotError> {
    let fig = separability::build(tables, ks, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

/// A sphere lit by a directional light, rendered from the data and (beside it) from
/// the fit; see [`SphereOptions`].
pub fn sphere(
    out: Output<'_>,
    data: &Source<'_>,
    fit: Option<&dyn Brdf>,
    opts: &SphereOptions,
) -> Result<Drawn, PlotError> {
    let fig = sphere::build(data, fit, opts).map_err(|k| err(&out, k))?;
    output::emit(out, opts.size, &fig)
}

fn err(out: &Output<'_>, kind: PlotErrorKind) -> PlotError {
    PlotError {
        target: out.target(),
        kind,
    }
}

/// The channel indices a choice selects, checked against `channels`.
fn select(choice: ChannelChoice, channels: &Channels) -> Result<Vec<usize>, PlotErrorKind> {
    match choice {
        ChannelChoice::All => Ok((0..channels.len()).collect()),
        ChannelChoice::One(c) if c < channels.len() => Ok(vec![c]),
        ChannelChoice::One(c) => Err(PlotErrorKind::Input(format!(
            "channel index {c} is out of range: the data has {} channel(s) ({channels})",
            channels.len()
        ))),
    }
}

/// Checks that a fit has the data's channels.
fn same_channels(data: &Channels, fit: Option<&Channels>) -> Result<(), PlotErrorKind> {
    match fit {
        Some(f) if f != data => Err(PlotErrorKind::Input(format!(
            "the fit's channels ({f}) differ from the data's ({data})"
        ))),
        _ => Ok(()),
    }
}

/// Checks an image size.
fn check_size(size: (u32, u32), min: (u32, u32)) -> Result<(), PlotErrorKind> {
    if size.0 < min.0 || size.1 < min.1 || size.0 > 8192 || size.1 > 8192 {
        return Err(PlotErrorKind::Input(format!(
            "image size {}×{} is outside {}×{} ..= 8192×8192",
            size.0, size.1, min.0, min.1
        )));
    }
    Ok(())
}

/// Checks an incident polar angle in degrees.
fn check_theta_i(t: f64) -> Result<(), PlotErrorKind> {
    if !(0.0..90.0).contains(&t) {
        return Err(PlotErrorKind::Input(format!(
            "θi = {t}° is outside [0°, 90°)"
        )));
    }
    Ok(())
}
