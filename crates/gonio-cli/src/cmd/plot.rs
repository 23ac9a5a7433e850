//! `gonio plot`: a run, table, samples, MERL file or model as a figure.

use std::path::PathBuf;

use gonio_brdf::{Brdf, Model};
use gonio_dataset::Dataset;
use gonio_io::plot::{self, ChannelChoice, Output, Source};

use crate::error::{CliError, CliResult};
use crate::flags::ReduceFlags;
use crate::output;

/// `gonio plot`: plot a run, table, samples, MERL file or model (PNG or SVG by the
/// extension).
#[derive(clap::Args)]
pub struct PlotArgs {
    /// The input.
    input: PathBuf,
    /// A fitted model file drawn against the data.
    #[arg(long)]
    fit: Option<PathBuf>,
    /// polar, hemisphere, albedo, separability or sphere. For two or more wavelength
    /// channels (and no --channel), albedo is drawn against wavelength, one curve per
    /// --theta-i.
    #[arg(long)]
    kind: String,
    /// The image to write (.png or .svg).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: output::ForceFlag,
    /// Incident polar angles, degrees (polar and spectral albedo: the curves;
    /// hemisphere: the first).
    #[arg(long, value_delimiter = ',', default_value = "0,35,65")]
    theta_i: Vec<f64>,
    /// Only this channel (by name).
    #[arg(long)]
    channel: Option<String>,
    /// Sphere: the light's angle from the view axis, degrees.
    #[arg(long, default_value_t = 45.0)]
    light_theta: f64,
    /// Sphere: the light's azimuth in the image, degrees from +x towards +y.
    #[arg(long, default_value_t = 135.0)]
    light_phi: f64,
    #[command(flatten)]
    reduction: ReduceFlags,
    /// Hemisphere: `srgb` draws each direction in its own colour (encoded sRGB of
    /// π · f_r of a spectral or RGB input) instead of a colour map of one channel.
    #[arg(long)]
    colour: Option<String>,
    /// How a spectrum becomes a colour with `--colour srgb` (`docs/colour.md`).
    #[command(flatten)]
    colour_conditions: crate::cmd::colour::ConditionFlags,
}

/// A plot failure: bad input (a channel, an angle) or a drawing failure.
pub fn plot_err(e: plot::PlotError) -> CliError {
    CliError::classify(e.is_input(), e)
}

/// `gonio plot INPUT [--fit FIT.toml] --kind … --out FILE.png|svg`.
pub fn run(a: PlotArgs) -> CliResult<()> {
    let target = output::Target::new(&a.out, a.force.force)?;
    let opened = gonio_dataset::open(&a.input, &a.reduction.open_options()?)?;
    let data = &opened.data;
    let fit = match &a.fit {
        Some(p) => Some(Model::load(p)?),
        None => None,
    };
    // A half turn of an isotropic material is unfolded (bilateral symmetry) so that
    // maps of the whole hemisphere show data on both sides, not extrapolation.
    let unfolded = match data {
        Dataset::Samples(s) => Some(gonio_process::hemisphere::unfold(s)),
        _ => None,
    };
    if let Some((_, sym)) = &unfolded {
        tracing::info!(symmetry = sym.name(), "symmetry assumed");
    }
    let src =
        match (data, &unfolded) {
            (Dataset::Model(m), _) => Source::Model(m),
            (_, Some((s, _))) => Source::Samples(s),
            (d, None) => Source::Brdf(d.brdf().ok_or_else(|| {
                CliError::Input(format!("{}: nothing to plot", a.input.display()))
            })?),
        };
    let channel = match &a.channel {
        None => ChannelChoice::All,
        Some(name) => ChannelChoice::One(src.channels().index_of(name).ok_or_else(|| {
            CliError::Input(format!(
                "--channel: {name:?} is not one of {}",
                src.channels().names().join(", ")
            ))
        })?),
    };
    let true_colour = match a.colour.as_deref() {
        None => None,
        Some("srgb") if a.kind == "hemisphere" => Some(a.colour_conditions.conversion()?),
        Some("srgb") => {
            return Err(CliError::Input(format!(
                "--colour srgb: only for --kind hemisphere, got {:?}",
                a.kind
            )));
        }
        Some(c) => return Err(CliError::Input(format!("--colour: srgb, got {c:?}"))),
    };
    let fit_brdf: Option<&dyn Brdf> = fit.as_ref().map(|m| m as &dyn Brdf);
    // Several wavelengths: the albedo is a spectrum, drawn against wavelength.
    let spectral = channel == ChannelChoice::All
        && matches!(src.channels(), gonio_core::Channels::Wavelengths(w) if w.len() > 1);
    target.write_with(|tmp| -> CliResult<()> {
        let out = Output::File(tmp);
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
                    true_colour,
                    ..plot::HemisphereOptions::default()
                },
            ),
            "albedo" if spectral => plot::spectral_albedo(
                out,
                &src,
                fit_brdf,
                &a.theta_i,
                &plot::AlbedoOptions::default(),
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
                // Measured data on their own grid (a half turn unfolded), analytic
                // data on their own grid or 10° × 10°.
                let table = data.to_table(None, &a.input)?;
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
    })
}
