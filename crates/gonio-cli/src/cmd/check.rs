//! `gonio check`: DeYoung's measures (Ch. 4) of any input — reciprocity, energy
//! conservation, isotropy, separability.

use std::io::Write;
use std::path::PathBuf;

use gonio_dataset::Dataset;
use gonio_process::measure;

use crate::error::{CliError, CliResult};
use crate::flags::{GridFlag, JsonFlag, ReduceFlags};
use crate::output;

/// `gonio check`: measure reciprocity, energy conservation, isotropy and
/// separability of a run, a table, a separable or harmonics file, or a model file.
#[derive(clap::Args)]
pub struct CheckArgs {
    /// The input.
    input: PathBuf,
    /// The k of P_s^(k), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    k: Vec<usize>,
    #[command(flatten)]
    grid: GridFlag,
    #[command(flatten)]
    reduction: ReduceFlags,
    #[command(flatten)]
    json: JsonFlag,
}

impl CheckArgs {
    /// Checks every flag's value without reading the input: what a batch does
    /// before it starts any task.
    pub(crate) fn check_values(&self) -> CliResult<()> {
        self.reduction.options().map(drop)
    }
}

/// What `gonio check` measures, and the table it measured.
pub(crate) struct Checked {
    /// The table made from the input.
    pub tab: gonio_dataset::Tabulated,
    /// DeYoung's measures.
    pub report: measure::Report,
    /// The k of P_s^(k).
    pub ks: Vec<usize>,
}

impl Checked {
    /// The `--json` object.
    pub fn json(&self) -> serde_json::Value {
        let mut v = serde_json::to_value(&self.report).unwrap_or_default();
        if let Some(o) = v.as_object_mut() {
            o.insert("symmetry".into(), self.tab.symmetry.name().into());
            // The channels' wavelengths (nm), in the order of `channels`; only for
            // wavelength channels, so that other data's output stays as it was.
            if let gonio_core::Channels::Wavelengths(w) = &self.tab.table.channels {
                o.insert("wavelengths_nm".into(), serde_json::json!(w.to_vec()));
            }
            o.insert(
                "grid".into(),
                serde_json::to_value(super::grid_json(&self.tab.table, &self.tab))
                    .unwrap_or_default(),
            );
        }
        v
    }
}

/// Measures the input (or `given`, data already in memory that `a.input` names).
pub(crate) fn compute(a: &CheckArgs, given: Option<Dataset>) -> CliResult<Checked> {
    let (path, ks) = (a.input.as_path(), a.k.as_slice());
    if ks.contains(&0) {
        return Err(CliError::Input("--k: every k must be at least 1".into()));
    }
    let data = super::open_data(path, &a.reduction, given)?;
    let tab = data.into_tabulated(a.grid.grid, path)?;
    let ks = if ks.is_empty() { vec![1] } else { ks.to_vec() };
    let report = measure::report_with(&tab.table, tab.measured.as_ref(), &ks, 5)
        .map_err(|e| CliError::process(path, e))?;
    Ok(Checked { tab, report, ks })
}

/// `gonio check INPUT [--k 1,2,5] [--json]`.
pub fn run(a: CheckArgs) -> CliResult<()> {
    let checked = compute(&a, None)?;
    if a.json.json {
        return output::json(&checked.json());
    }
    let Checked { tab, report: r, ks } = &checked;
    let (path, table) = (a.input.as_path(), &tab.table);
    let mut w = output::stdout();
    output::finish((|| {
        let g = &table.grid;
        writeln!(
            w,
            "{}: {} nodes ({}{} φi × {} θi × {} φo × {} θo), channels {}",
            path.display(),
            r.nodes,
            if g.isotropic { "isotropic: " } else { "" },
            g.phi_i.n,
            g.theta_i.n,
            g.phi_o.n,
            g.theta_o.n,
            r.channels.join(",")
        )?;
        super::write_provenance(&mut w, tab)?;
        write_measures(&mut w, r, g.isotropic, ks)?;
        if let Some(f) = &r.floor {
            write_floors(&mut w, r, f, ks)?;
        }
        write_energy(&mut w, r)?;
        w.flush()
    })())
}

/// The measures' block: a row per measure, a column per channel.
fn write_measures(
    w: &mut dyn Write,
    r: &measure::Report,
    isotropic: bool,
    ks: &[usize],
) -> std::io::Result<()> {
    writeln!(
        w,
        "{:<28}{}",
        "measure",
        r.channels
            .iter()
            .map(|c| format!("{c:>14}"))
            .collect::<String>()
    )?;
    let row = |w: &mut dyn Write, name: &str, v: &[f64]| {
        writeln!(
            w,
            "{name:<28}{}",
            v.iter().map(|x| format!("{x:>14.6e}")).collect::<String>()
        )
    };
    row(
        w,
        if r.paired {
            "P_r (Eq. 4.1)"
        } else {
            "P_r (Eq. 4.1, interpolated)"
        },
        &r.reciprocity,
    )?;
    row(w, "P_ec (Eq. 4.5)", &r.energy.p_ec)?;
    if isotropic {
        writeln!(
            w,
            "{:<28}not measurable: isotropic data (one φi)",
            "P_i (Eq. 4.10)"
        )?;
    } else {
        row(w, "P_i (Eq. 4.10)", &r.isotropy)?;
    }
    if let Some(sep) = &r.separability {
        for (j, k) in ks.iter().enumerate() {
            let v: Vec<f64> = sep.iter().map(|s| s.p_s[j].1).collect();
            row(w, &format!("P_s^({k}) (Eq. 4.20)"), &v)?;
        }
    } else {
        writeln!(
            w,
            "P_s: not available (an isotropic table whose φ+ axis is not a full turn)"
        )?;
    }
    Ok(())
}

/// The energy block: how the albedos were formed, the highest, and where the
/// sampling does not resolve them.
fn write_energy(w: &mut dyn Write, r: &measure::Report) -> std::io::Result<()> {
    match r.energy.method {
        measure::EnergyMethod::Sum => {
            if r.energy.coverage < 0.999 {
                writeln!(
                    w,
                    "note: the outgoing nodes cover {:.1}% of the projected hemisphere; albedos undercount",
                    100.0 * r.energy.coverage
                )?;
            }
        }
        measure::EnergyMethod::Triangulated => writeln!(
            w,
            "albedos: triangulated hemisphere (DeYoung Sec. 4.2.2) over {} incident \
             directions; the data cover at least {:.1}% of the projected hemisphere, \
             at most {:.1}% held from the data's edge to the horizon",
            r.energy.incident.len(),
            100.0 * r.energy.coverage,
            100.0 * r.energy.extrapolated
        )?,
    }
    writeln!(
        w,
        "highest directional albedo (θi, φi: per channel; ± the noise's and the \
         quadrature's standard uncertainties):"
    )?;
    for (th, ph, a) in &r.energy.worst {
        let row = r.energy.incident.iter().position(|i| *i == (*th, *ph));
        let sigma = row.and_then(|k| {
            r.energy
                .albedo_sigma
                .as_ref()
                .map(|s| s.iter().map(|c| c[k]).collect::<Vec<_>>())
        });
        let quad: Option<Vec<f64>> = row.map(|k| {
            r.energy
                .albedo_quadrature_sigma
                .iter()
                .map(|c| c[k])
                .collect()
        });
        let cell = |(ch, x): (usize, &f64)| {
            let mut c = format!("{x:.4}");
            if let Some(s) = &sigma {
                c += &format!(" ± {:.1e} (noise)", s[ch]);
            }
            if let Some(q) = &quad {
                c += &format!(" ± {:.1e} (quadrature)", q[ch]);
            }
            c
        };
        writeln!(
            w,
            "  {th:>6.2}° {ph:>7.2}°: {}",
            a.iter().enumerate().map(cell).collect::<Vec<_>>().join(" ")
        )?;
    }
    let large: Vec<String> = r
        .energy
        .incident
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            r.energy
                .albedo
                .iter()
                .zip(&r.energy.albedo_quadrature_sigma)
                .any(|(a, q)| q[*k] > 0.1 * a[*k].abs())
        })
        .map(|(_, (th, ph))| format!("θi {th}° φi {ph}°"))
        .collect();
    if !large.is_empty() {
        writeln!(
            w,
            "note: the sampling does not resolve the albedo to 10% at {}: its quadrature \
             uncertainty is larger; finer outgoing steps there would narrow it",
            large.join(", ")
        )?;
    }
    Ok(())
}

/// The floors' block of the text output: each measure against what a BRDF with the
/// property reads under the same sampling and noise.
fn write_floors(
    w: &mut dyn Write,
    r: &measure::Report,
    f: &gonio_process::floor::Floors,
    ks: &[usize],
) -> std::io::Result<()> {
    let how = if f.draws == 0 {
        "no σ in the data: interpolation alone".to_string()
    } else {
        format!("{} noise draws of the data's σ", f.draws)
    };
    writeln!(
        w,
        "floors (what a BRDF with the property reads under the same sampling and noise; {how}):"
    )?;
    let multi = r.channels.len() > 1;
    let line = |w: &mut dyn Write,
                name: &str,
                ch: usize,
                value: String,
                fl: &gonio_process::floor::Floor,
                property: &str|
     -> std::io::Result<()> {
        let channel = if multi {
            format!(" [{}]", r.channels[ch])
        } else {
            String::new()
        };
        let verdict = if fl.consistent {
            format!("consistent with {property}")
        } else {
            "exceeds the floor".to_string()
        };
        writeln!(
            w,
            "  {name}{channel} {value}  (floor {:.2e}, 95% {:.2e}: {verdict})",
            fl.mean, fl.p95
        )
    };
    for (ch, fl) in f.reciprocity.iter().enumerate() {
        line(
            w,
            "P_r",
            ch,
            format!("{:.2e}", r.reciprocity[ch]),
            fl,
            "reciprocal",
        )?;
    }
    for (ch, fl) in f.energy.iter().enumerate() {
        let mut v = format!("{:.2e}", r.energy.p_ec[ch]);
        if let Some(n) = &r.energy.p_ec_noise_sigma {
            v += &format!(" ± {:.1e} (noise)", n[ch]);
        }
        v += &format!(" ± {:.1e} (quadrature)", r.energy.p_ec_quadrature_sigma[ch]);
        line(w, "P_ec", ch, v, fl, "energy conservation")?;
    }
    if let Some(iso) = &f.isotropy {
        for (ch, fl) in iso.iter().enumerate() {
            line(
                w,
                "P_i",
                ch,
                format!("{:.2e}", r.isotropy[ch]),
                fl,
                "isotropic",
            )?;
        }
    }
    if let (Some(sep), Some(fs)) = (&r.separability, &f.separability) {
        for (ch, per_k) in fs.iter().enumerate() {
            for (j, (k, fl)) in per_k.iter().enumerate() {
                line(
                    w,
                    &format!("P_s^({k})"),
                    ch,
                    format!("{:.2e}", sep[ch].p_s[j].1),
                    fl,
                    &format!("{k}-separable"),
                )?;
            }
        }
    } else if r.separability.is_some() && !ks.is_empty() {
        writeln!(w, "  P_s: no floor (A is too large for a full SVD a draw)")?;
    }
    Ok(())
}
