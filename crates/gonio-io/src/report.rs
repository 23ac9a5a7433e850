//! The run report: one self-contained HTML page (inline SVG figures and styles, no
//! network fetches) with a run's metadata, calibration, the plausibility measures, the
//! fit table with errors, and the plots. It is what a lab attaches to a sample.

use std::fmt::Write as _;

use gonio_fit::LobeFit;
use gonio_fit::compare::Compared;
use gonio_process::measure::Report as Measures;
use gonio_process::reduction::Report as Reduction;

/// A figure of the report.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Its title.
    pub title: String,
    /// What it shows, one or two sentences.
    pub caption: String,
    /// The image.
    pub image: Image,
}

/// A figure's image, inlined into the page.
#[derive(Clone, Debug, PartialEq)]
pub enum Image {
    /// An SVG document (line plots: small and sharp).
    Svg(String),
    /// PNG bytes, inlined as a `data:` URI (colour maps and renderings, which are far
    /// smaller as PNG than as SVG rectangles).
    Png(Vec<u8>),
}

/// Standard base64 (RFC 4648) of bytes, for `data:` URIs.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut o = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= c.len() {
                o.push(A[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                o.push('=');
            }
        }
    }
    o
}

/// One decision of an adaptive run: a batch of points chosen during the run.
#[derive(Clone, Debug, PartialEq)]
pub struct DecisionRow {
    /// The batch's number (1, 2, …; the coarse pass is 0).
    pub batch: i64,
    /// Sample points it chose.
    pub points: u32,
    /// Steps it appended (its points, and the drift references and moves between).
    pub steps: u32,
    /// How it chose them (`variation`, `value`).
    pub method: String,
    /// Readings committed when it was decided: the data it was decided from.
    pub readings: u64,
    /// Its schedule's estimated instrument time, s; `None` when the run file's
    /// decision does not record one.
    pub estimate_s: Option<f64>,
}

/// Where an adaptive run's points went: the budget, the coarse pass, each batch, and
/// the figure of the sample directions.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Adaptive {
    /// The budget in points, as the decisions record it; `None` when they do not.
    pub budget_points: Option<u64>,
    /// Points of the coarse pass (batch 0).
    pub coarse_points: usize,
    /// The decisions, in order.
    pub decisions: Vec<DecisionRow>,
    /// The sample directions by batch; `None` when it could not be drawn (the
    /// report's notes say why).
    pub figure: Option<Figure>,
}

/// Everything a report shows; each part is optional.
#[derive(Clone, Debug, Default)]
pub struct Contents {
    /// The page title (the run's name).
    pub title: String,
    /// Key–value metadata, in order (file, status, software, seed, notes, times…).
    pub metadata: Vec<(String, String)>,
    /// The instrument and plan configs, verbatim.
    pub configs: Vec<(String, String)>,
    /// The reduction's account (calibration, drift, rejections).
    pub reduction: Option<Reduction>,
    /// DeYoung's measures of the data.
    pub measures: Option<Measures>,
    /// The lobe fit.
    pub fit: Option<LobeFit>,
    /// The comparison models on the same data.
    pub comparison: Vec<Compared>,
    /// Notes on parts left out (why a measure or a plot is absent).
    pub notes: Vec<String>,
    /// The figures.
    pub figures: Vec<Figure>,
    /// An adaptive run's decisions and the figure of where its points went; `None`
    /// for a run whose schedule was all fixed at creation.
    pub adaptive: Option<Adaptive>,
}

impl Contents {
    /// The figures the page shows: [`Contents::figures`] and the adaptive run's.
    pub fn figure_count(&self) -> usize {
        self.figures.len()
            + self
                .adaptive
                .as_ref()
                .map_or(0, |a| usize::from(a.figure.is_some()))
    }
}

/// Escapes text for HTML.
pub fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            _ => o.push(c),
        }
    }
    o
}

/// An SVG document made safe to inline: its XML declaration dropped (it is not
/// allowed inside HTML) and any script removed (the report runs none).
fn inline_svg(svg: &str) -> String {
    let body = match svg.find("<svg") {
        Some(i) => &svg[i..],
        None => return format!("<pre>{}</pre>", escape(svg)),
    };
    let mut out = String::with_capacity(body.len());
    let mut rest = body;
    while let Some(i) = rest.find("<script") {
        out.push_str(&rest[..i]);
        match rest[i..].find("</script>") {
            Some(j) => rest = &rest[i + j + "</script>".len()..],
            None => {
                rest = "";
                break;
            }
        }
    }
    out.push_str(rest);
    out
}

/// A duration in seconds, in the unit that reads best.
fn duration(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.1} min", s / 60.0)
    } else {
        format!("{:.2} h", s / 3600.0)
    }
}

/// A figure as HTML: its title, the image inlined, the caption.
fn figure_html(h: &mut String, f: &Figure) {
    let img = match &f.image {
        Image::Svg(s) => inline_svg(s),
        Image::Png(b) => format!(
            "<img alt=\"{}\" src=\"data:image/png;base64,{}\">",
            escape(&f.title),
            base64(b)
        ),
    };
    let _ = writeln!(
        h,
        "<figure><h3>{}</h3>{img}<figcaption>{}</figcaption></figure>",
        escape(&f.title),
        escape(&f.caption)
    );
}

/// The adaptive run's section: the budget and what each stage took, the decisions'
/// table, the figure.
fn adaptive_html(h: &mut String, a: &Adaptive) {
    h.push_str("<h2>Adaptive sampling</h2>\n");
    let chosen: u64 = a.decisions.iter().map(|d| u64::from(d.points)).sum();
    let total = a.coarse_points as u64 + chosen;
    let budget = match a.budget_points {
        Some(b) => format!("The budget was {b} points"),
        None => "The decisions record no budget".into(),
    };
    let stages: Vec<String> = a
        .decisions
        .iter()
        .map(|d| format!("batch {} took {}", d.batch, d.points))
        .collect();
    let _ = writeln!(
        h,
        "<p>{budget}: the coarse pass took {} points, {}; {total} points in all, {chosen} of \
         them chosen during the run.</p>",
        a.coarse_points,
        if stages.is_empty() {
            "no batch followed".to_string()
        } else {
            stages.join(", ")
        }
    );
    h.push_str(
        "<table><tr><th>batch</th><th>points</th><th>steps</th><th class=\"k\">method</th>\
         <th>decided from (readings)</th><th>estimated time</th></tr>\n",
    );
    for d in &a.decisions {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"k\">{}</td><td>{}</td><td>{}</td></tr>",
            d.batch,
            d.points,
            d.steps,
            escape(&d.method),
            d.readings,
            d.estimate_s.map_or_else(|| "—".to_string(), duration)
        );
    }
    h.push_str("</table>\n");
    if let Some(f) = &a.figure {
        figure_html(h, f);
    }
}

fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x.abs() >= 1e-3 && x.abs() < 1e4 {
        format!("{x:.5}")
    } else {
        format!("{x:.4e}")
    }
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}\
table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #bbb;padding:3px 8px;\
text-align:right}th{background:#eee}td.k,th.k{text-align:left}figure{margin:1.5em 0}\
figcaption{color:#555;font-size:0.9em}pre{background:#f6f6f6;padding:0.6em;overflow:auto;\
font-size:0.85em}h2{border-bottom:1px solid #ccc;padding-bottom:0.2em}.note{color:#a40}";

/// Renders the page.
pub fn html(c: &Contents) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\
         <style>{STYLE}</style></head><body>\n<h1>{}</h1>\n",
        escape(&c.title),
        escape(&c.title)
    );
    if !c.metadata.is_empty() {
        h.push_str("<h2>Run</h2>\n<table>\n");
        for (k, v) in &c.metadata {
            let _ = writeln!(
                h,
                "<tr><th class=\"k\">{}</th><td class=\"k\">{}</td></tr>",
                escape(k),
                escape(v)
            );
        }
        h.push_str("</table>\n");
    }
    if let Some(a) = &c.adaptive {
        adaptive_html(&mut h, a);
    }
    if let Some(r) = &c.reduction {
        reduction_html(&mut h, r);
    }
    if let Some(m) = &c.measures {
        measures_html(&mut h, m);
    }
    if let Some(f) = &c.fit {
        fit_html(&mut h, f, &c.comparison);
    }
    if !c.figures.is_empty() {
        h.push_str("<h2>Figures</h2>\n");
        for f in &c.figures {
            figure_html(&mut h, f);
        }
    }
    if !c.notes.is_empty() {
        h.push_str("<h2>Notes</h2>\n<ul>\n");
        for n in &c.notes {
            let _ = writeln!(h, "<li class=\"note\">{}</li>", escape(n));
        }
        h.push_str("</ul>\n");
    }
    if !c.configs.is_empty() {
        h.push_str("<h2>Configuration</h2>\n");
        for (name, text) in &c.configs {
            let _ = writeln!(
                h,
                "<details><summary>{}</summary><pre>{}</pre></details>",
                escape(name),
                escape(text)
            );
        }
    }
    h.push_str("</body></html>\n");
    h
}

/// The reduction's section: the equation and solid angle, each channel's
/// calibration and drift, the uncertainty budget, and what was left out.
fn reduction_html(h: &mut String, r: &Reduction) {
    h.push_str("<h2>Calibration and reduction</h2>\n");
    let _ = writeln!(
        h,
        "<p>f<sub>r</sub> = (S − S<sub>dark</sub>) / (Φ(t) Ω cos θ<sub>o</sub>) (DeYoung Eq. A.15); \
         detector solid angle Ω = {} sr; largest read-back position error {:.4}°.</p>",
        num(r.solid_angle_sr),
        r.max_position_error_deg
    );
    // A lock-in's volts, or a picoammeter's amps (every channel of a run alike).
    let unit = r.channels.first().map_or("V", |c| c.unit);
    let _ = writeln!(
        h,
        "<table><tr><th class=\"k\">channel</th><th>calibration</th><th>readings</th>\
         <th>incident flux ({unit})</th><th>its rel. σ</th><th>dark X, Y ({unit})</th>\
         <th>drift references</th><th>max |g − 1|</th><th>samples</th></tr>",
    );
    for ch in &r.channels {
        let _ = writeln!(
            h,
            "<tr><td class=\"k\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}, {}</td><td>{}</td><td>{:.3}%</td><td>{}</td></tr>",
            escape(&ch.channel),
            ch.calibration,
            ch.calibration_readings,
            num(ch.incident_v),
            num(ch.incident_rel_sigma),
            num(ch.dark_v[0]),
            num(ch.dark_v[1]),
            ch.drift_readings,
            100.0 * ch.drift_max,
            ch.samples
        );
    }
    h.push_str("</table>\n");
    budget_html(h, r);
    if !r.rejected.is_empty() || r.unmeasured > 0 {
        let mut parts: Vec<String> = r.rejected.iter().map(|(k, v)| format!("{v} {k}")).collect();
        if r.unmeasured > 0 {
            parts.push(format!("{} not measured", r.unmeasured));
        }
        let _ = writeln!(h, "<p>Left out: {}.</p>", escape(&parts.join(", ")));
    }
}

/// The uncertainty budget's table, when a channel has one.
fn budget_html(h: &mut String, r: &Reduction) {
    if !r.channels.iter().any(|ch| !ch.budget.is_empty()) {
        return;
    }
    h.push_str(
        "<h3>Uncertainty budget</h3>\n<p>Each sample's σ is the quadrature sum of these \
         terms (relative standard uncertainties over the channel's samples).</p>\n\
         <table><tr><th class=\"k\">channel</th><th class=\"k\">term</th>\
         <th>median rel. σ</th><th>largest rel. σ</th><th class=\"k\">shared</th>\
         <th class=\"k\">source</th></tr>\n",
    );
    for ch in &r.channels {
        for t in &ch.budget {
            let _ = writeln!(
                h,
                "<tr><td class=\"k\">{}</td><td class=\"k\">{}</td><td>{}</td><td>{}</td>\
                 <td class=\"k\">{}</td><td class=\"k\">{}</td></tr>",
                escape(&ch.channel),
                escape(t.term),
                num(t.rel_median),
                num(t.rel_max),
                escape(t.correlation),
                escape(&t.source)
            );
        }
    }
    h.push_str("</table>\n");
}

/// DeYoung's measures' section: one row a measure, one column a channel, and how
/// the albedos were found.
fn measures_html(h: &mut String, m: &Measures) {
    h.push_str("<h2>Physical plausibility and compressibility (DeYoung Ch. 4)</h2>\n");
    let _ = write!(h, "<table><tr><th class=\"k\">measure</th>");
    for ch in &m.channels {
        let _ = write!(h, "<th>{}</th>", escape(ch));
    }
    h.push_str("</tr>\n");
    let row = |h: &mut String, name: &str, v: &[f64]| {
        let _ = write!(h, "<tr><td class=\"k\">{name}</td>");
        for x in v {
            let _ = write!(h, "<td>{}</td>", num(*x));
        }
        h.push_str("</tr>\n");
    };
    row(h, "P<sub>r</sub> reciprocity (Eq. 4.1)", &m.reciprocity);
    row(h, "P<sub>ec</sub> energy (Eq. 4.5)", &m.energy.p_ec);
    row(h, "P<sub>i</sub> isotropy (Eq. 4.10)", &m.isotropy);
    if let Some(sep) = &m.separability
        && let Some(first) = sep.first()
    {
        for (j, (k, _)) in first.p_s.iter().enumerate() {
            let v: Vec<f64> = sep.iter().map(|s| s.p_s[j].1).collect();
            row(
                h,
                &format!("P<sub>s</sub><sup>({k})</sup> separability (Eq. 4.20)"),
                &v,
            );
        }
    }
    let max_alb: Vec<f64> = m
        .energy
        .albedo
        .iter()
        .map(|a| a.iter().copied().fold(0.0, f64::max))
        .collect();
    row(h, "largest directional albedo", &max_alb);
    h.push_str("</table>\n");
    let _ = writeln!(
        h,
        "<p>{} nodes; reciprocal values {}; {}.</p>",
        m.nodes,
        if m.paired {
            "looked up (paired grid)"
        } else {
            "interpolated"
        },
        match m.energy.method {
            gonio_process::measure::EnergyMethod::Sum => format!(
                "albedos by DeYoung's sum (Eq. 4.4); the outgoing nodes cover {:.1}% of \
                 the projected hemisphere",
                100.0 * m.energy.coverage
            ),
            gonio_process::measure::EnergyMethod::Triangulated => format!(
                "albedos over the triangulated hemisphere of the samples (Sec. 4.2.2); \
                 the data cover at least {:.1}% of the projected hemisphere, and at most \
                 {:.1}% (the band to the horizon) is held from the data's edge",
                100.0 * m.energy.coverage,
                100.0 * m.energy.extrapolated
            ),
        }
    );
}

/// The lobe fit's section: the fit's account, its parameters with their standard
/// errors, the comparison with the other models, and the model file.
fn fit_html(h: &mut String, f: &LobeFit, comparison: &[Compared]) {
    h.push_str("<h2>Lobe fit (Lafortune et al. 1997)</h2>\n");
    let _ = writeln!(
        h,
        // No wall time: the same run gives the same report, byte for byte (an
        // archive reprocessed twice, a retried batch task).
        "<p>{} lobe(s), {:?} diffuse, {} pairs; objective {} (minimised: {}; {}); {} \
         evaluations; largest directional albedo {:.4}{}.</p>",
        f.shape.lobes,
        f.shape.diffuse,
        f.samples,
        escape(&f.objective.name),
        escape(&f.objective.formula),
        escape(&f.objective.chosen),
        f.evaluations,
        f.max_albedo,
        if f.energy_scale < 1.0 {
            format!(", scaled by {:.4} to conserve energy", f.energy_scale)
        } else {
            String::new()
        }
    );
    h.push_str(
        "<table><tr><th class=\"k\">channel</th><th class=\"k\">term</th><th>C<sub>x</sub></th>\
         <th>C<sub>y</sub></th><th>C<sub>z</sub></th><th>n</th><th>ρ<sub>d</sub></th></tr>\n",
    );
    for ch in &f.channels {
        let _ = writeln!(
            h,
            "<tr><td class=\"k\">{}</td><td class=\"k\">diffuse</td><td></td><td></td><td></td>\
             <td>{}</td><td>{} ± {}</td></tr>",
            escape(&ch.channel),
            if ch.params.m > 0.0 {
                num(ch.params.m)
            } else {
                String::new()
            },
            num(ch.params.rho_d),
            num(ch.std_err.rho_d)
        );
        for (j, (l, s)) in ch.params.lobes.iter().zip(&ch.std_err.lobes).enumerate() {
            let _ = write!(
                h,
                "<tr><td class=\"k\">{}</td><td class=\"k\">lobe {}</td>",
                escape(&ch.channel),
                j + 1
            );
            for q in 0..4 {
                let _ = write!(h, "<td>{} ± {}</td>", num(l[q]), num(s[q]));
            }
            h.push_str("<td></td></tr>\n");
        }
    }
    h.push_str("</table>\n");
    comparison_html(h, f, comparison);
    let _ = writeln!(
        h,
        "<details><summary>Model file</summary><pre>{}</pre></details>",
        escape(&f.model_toml)
    );
}

/// The table of relative RMS errors: the lobe fit's, then each comparison model's,
/// a column a channel.
fn comparison_html(h: &mut String, f: &LobeFit, comparison: &[Compared]) {
    h.push_str("<table><tr><th class=\"k\">model (same data, same metric)</th>");
    for ch in &f.channels {
        let _ = write!(h, "<th>{} rel. RMS</th>", escape(&ch.channel));
    }
    h.push_str("</tr>\n");
    let _ = write!(
        h,
        "<tr><td class=\"k\">Lafortune, {} lobe(s)</td>",
        f.shape.lobes
    );
    for ch in &f.channels {
        let _ = write!(h, "<td>{:.3}%</td>", 100.0 * ch.relative_rms);
    }
    h.push_str("</tr>\n");
    let mut models: Vec<&str> = Vec::new();
    for r in comparison {
        if !models.contains(&r.model) {
            models.push(r.model);
        }
    }
    for m in models {
        let _ = write!(h, "<tr><td class=\"k\">{}</td>", escape(m));
        for r in comparison.iter().filter(|r| r.model == m) {
            let _ = write!(h, "<td>{:.3}%</td>", 100.0 * r.relative_rms);
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648() {
        // RFC 4648, Sec. 10.
        for (i, o) in [
            "", "Zg==", "Zm8=", "Zm9v", "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy",
        ]
        .iter()
        .enumerate()
        {
            assert_eq!(base64(&b"foobar"[..i]), *o);
        }
    }

    #[test]
    fn the_page_is_self_contained_and_escaped() {
        let c = Contents {
            title: "run <1> & co".into(),
            metadata: vec![("notes".into(), "<script>alert(1)</script>".into())],
            figures: vec![Figure {
                title: "t".into(),
                caption: "c".into(),
                image: Image::Svg("<?xml version=\"1.0\"?><svg xmlns=\"http://www.w3.org/2000/svg\"><script>x()</script><path d=\"M0 0\"/></svg>".into()),
            }],
            ..Contents::default()
        };
        let h = html(&c);
        assert!(h.contains("run &lt;1&gt; &amp; co"));
        assert!(h.contains("&lt;script&gt;alert(1)&lt;/script&gt;"));
        assert!(!h.contains("<script"), "{h}");
        assert!(!h.contains("<?xml"));
        assert!(h.contains("<path d=\"M0 0\"/>"));
        // Nothing is fetched: no external references at all.
        for bad in ["http://", "https://", "src=", "<link"] {
            let outside_svg_ns = h.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
            assert!(!outside_svg_ns.contains(bad), "{bad}");
        }
    }

    /// The adaptive section, byte for byte: the sentence states the budget and what
    /// each stage took, the table has a row a decision, and times read in their unit.
    #[test]
    fn the_adaptive_section_states_the_budget_and_each_decision() {
        let row = |batch, points, steps, readings, estimate_s| DecisionRow {
            batch,
            points,
            steps,
            method: "variation".into(),
            readings,
            estimate_s,
        };
        let c = Contents {
            adaptive: Some(Adaptive {
                budget_points: Some(120),
                coarse_points: 36,
                decisions: vec![
                    row(1, 12, 14, 80, Some(95.4)),
                    row(2, 12, 13, 96, Some(430.0)),
                    row(3, 9, 10, 111, None),
                ],
                figure: Some(Figure {
                    title: "Where the points went".into(),
                    caption: "θo & φo".into(),
                    image: Image::Svg("<svg><circle/></svg>".into()),
                }),
            }),
            ..Contents::default()
        };
        assert_eq!(c.figure_count(), 1);
        let h = html(&c);
        let want = "<h2>Adaptive sampling</h2>\n\
<p>The budget was 120 points: the coarse pass took 36 points, batch 1 took 12, batch 2 took 12, \
batch 3 took 9; 69 points in all, 33 of them chosen during the run.</p>\n\
<table><tr><th>batch</th><th>points</th><th>steps</th><th class=\"k\">method</th>\
<th>decided from (readings)</th><th>estimated time</th></tr>\n\
<tr><td>1</td><td>12</td><td>14</td><td class=\"k\">variation</td><td>80</td><td>95 s</td></tr>\n\
<tr><td>2</td><td>12</td><td>13</td><td class=\"k\">variation</td><td>96</td><td>7.2 min</td></tr>\n\
<tr><td>3</td><td>9</td><td>10</td><td class=\"k\">variation</td><td>111</td><td>—</td></tr>\n\
</table>\n\
<figure><h3>Where the points went</h3><svg><circle/></svg><figcaption>θo &amp; φo</figcaption></figure>\n\
</body></html>\n";
        assert!(h.ends_with(want), "{h}");
        // Without an adaptive part, no trace of it.
        let plain = html(&Contents {
            title: "t".into(),
            ..Contents::default()
        });
        assert!(!plain.contains("Adaptive"));
        assert_eq!(Contents::default().figure_count(), 0);
        assert_eq!(duration(7200.0), "2.00 h");
    }
}
