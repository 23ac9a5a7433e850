//! Every kind of plot rendered to PNG (file, bytes, raw buffer) and SVG, with checks
//! that the data regions are drawn; and the example images of `docs/images/`
//! (`cargo test --release -p gonio-io --test it -- --ignored plot::gallery`).

use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Diffuse, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::rng::splitmix64;
use gonio_core::{Channels, SphericalDeg};
use gonio_io::plot::{
    self, AlbedoOptions, ChannelChoice, ColorScale, Drawn, HemisphereOptions, Output, PanelRect,
    PlotErrorKind, PolarOptions, Projection, RadialScale, SeparabilityOptions, Source,
    SphereOptions,
};
use gonio_process::{Grid, Sample, Samples, Table};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Blue paint at 550 nm, Lafortune et al. 1997 Table 1 (three lobes and a diffuse term).
fn paint() -> Model {
    Model::load(&repo().join("config/models/blue-paint-550nm.toml")).expect("the blue paint model")
}

/// The RGB model of docs/CONVENTIONS.md.
const RGB_MODEL: &str = r#"
kind = "lafortune"
channels = ["R", "G", "B"]
[diffuse]
rho = [0.3094, 0.39667, 0.70837]
[[lobes]]
cx = [0.870567, 0.857255, 0.670982]
cy = [0.870567, 0.857255, 0.670982]
cz = [0.803624, 0.774290, 0.586674]
n  = [21.820103, 18.597755, 7.472717]
"#;

fn rgb() -> Model {
    Model::from_toml(RGB_MODEL, None).expect("the RGB model of docs/CONVENTIONS.md")
}

/// A black 550 nm surface: the negative control.
fn black() -> Model {
    let ch = Channels::from_names(&["550nm"]).expect("550nm");
    Model::Lambert(Diffuse::lambert(ch, vec![0.0]).expect("rho = 0"))
}

/// A deterministic number in [−1, 1) from an index (splitmix64).
fn noise(i: u64) -> f64 {
    (splitmix64(i) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// A simulated isotropic measurement of `m`: θi and θo from 0° to 85° and φo − φi over
/// a full turn in steps of `step`°, each value times (1 + `rel` · uniform noise).
fn measured(m: &dyn Brdf, step: f64, rel: f64) -> Samples {
    let n_t = (85.0 / step).floor() as usize + 1;
    let n_p = (360.0 / step).round() as usize;
    let nc = m.channels().len();
    let mut samples = Vec::new();
    for a in 0..n_t {
        for b in 0..n_p {
            for c in 0..n_t {
                let pair = PairDeg {
                    incident: SphericalDeg::new(a as f64 * step, 0.0),
                    outgoing: SphericalDeg::new(c as f64 * step, b as f64 * step),
                };
                let d = pair.to_dirs();
                let mut v = vec![0.0; nc];
                m.eval(d.wi, d.wo, &mut v);
                for (k, x) in v.iter_mut().enumerate() {
                    *x *= 1.0 + rel * noise((samples.len() * nc + k) as u64);
                }
                samples.push(Sample {
                    pair,
                    value: v,
                    sigma: None,
                    flags: 0,
                });
            }
        }
    }
    Samples {
        channels: m.channels().clone(),
        samples,
        isotropic: true,
    }
}

/// A scratch directory under the system's temporary directory, removed on drop.
struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(
            tempfile::Builder::new()
                .prefix(&format!("gonio-io-plot-{name}-"))
                .tempdir()
                .expect("create a scratch directory"),
        )
    }
    fn path(&self, f: &str) -> PathBuf {
        self.0.path().join(f)
    }
}

/// Width and height from a PNG's IHDR chunk (no decoding needed).
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.len() > 24, "too short for a PNG");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// An RGB image drawn in memory.
struct Image {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

impl Image {
    fn at(&self, x: i32, y: i32) -> [u8; 3] {
        let i = (y as usize * self.w + x as usize) * 3;
        [self.px[i], self.px[i + 1], self.px[i + 2]]
    }

    /// Pixels of a panel that satisfy `pred`.
    fn count(&self, r: &PanelRect, pred: impl Fn([u8; 3]) -> bool) -> usize {
        assert!(r.x0 >= 0 && r.y0 >= 0 && r.x1 as usize <= self.w && r.y1 as usize <= self.h);
        let mut n = 0;
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                if pred(self.at(x, y)) {
                    n += 1;
                }
            }
        }
        n
    }

    /// Distinct colours in a panel.
    fn distinct(&self, r: &PanelRect) -> usize {
        let mut seen = std::collections::HashSet::new();
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                seen.insert(self.at(x, y));
            }
        }
        seen.len()
    }
}

fn area(r: &PanelRect) -> usize {
    ((r.x1 - r.x0) * (r.y1 - r.y0)) as usize
}

/// A saturated colour: a curve or point of the categorical palette, not the white
/// background, the grey grid or black text.
fn coloured(p: [u8; 3]) -> bool {
    let (mx, mn) = (p.iter().max().copied(), p.iter().min().copied());
    mx.zip(mn).is_some_and(|(a, b)| a - b >= 60)
}

fn not_black(p: [u8; 3]) -> bool {
    p.iter().any(|&c| c > 8)
}

fn render(f: impl FnOnce(Output<'_>) -> Result<Drawn, plot::PlotError>) -> (Drawn, Image) {
    let mut buf = Vec::new();
    let drawn = f(Output::Rgb(&mut buf)).expect("render to a buffer");
    let (w, h) = (drawn.size.0 as usize, drawn.size.1 as usize);
    assert_eq!(buf.len(), w * h * 3);
    (drawn, Image { w, h, px: buf })
}

/// The texts of an SVG document's `<text>` elements, trimmed.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = &t[t.find('>')? + 1..];
            Some(body[..body.find("</text>")?].trim().to_string())
        })
        .collect()
}

/// Whether an SVG document has a text element that is exactly `want`.
fn has_text(svg: &str, want: &str) -> bool {
    texts(svg).iter().any(|t| t == want)
}

fn svg(f: impl FnOnce(Output<'_>) -> Result<Drawn, plot::PlotError>) -> String {
    let mut s = String::new();
    f(Output::Svg(&mut s)).expect("render to SVG");
    assert!(s.starts_with("<svg"), "an SVG document");
    assert!(s.trim_end().ends_with("</svg>"));
    println!("SVG of {} bytes", s.len());
    s
}

fn png_file(
    path: &Path,
    f: impl FnOnce(Output<'_>) -> Result<Drawn, plot::PlotError>,
) -> (u32, u32) {
    let drawn = f(Output::File(path)).expect("render to a PNG file");
    let bytes = std::fs::read(path).expect("read the PNG back");
    let size = png_size(&bytes);
    assert_eq!(size, drawn.size);
    size
}

const THETAS: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

#[test]
fn polar_draws_curves_in_the_plot_area() {
    let (m, dir) = (paint(), Scratch::new("polar"));
    let opts = PolarOptions {
        scale: RadialScale::Log { decades: 2 },
        ..PolarOptions::default()
    };
    let data = Source::Model(&m);
    let draw = |o: Output<'_>| plot::polar(o, &data, Some(&m), &THETAS, &opts);
    assert_eq!(png_file(&dir.path("polar.png"), draw), (900, 700));

    let (drawn, img) = render(draw);
    assert_eq!(drawn.panels.len(), 1);
    let p = &drawn.panels[0];
    // The half disk of radius R spans 2R × R pixels.
    let r = p.y1 - p.y0 - 1;
    assert_eq!(p.x1 - p.x0, 2 * r + 1);
    assert!(r > 250, "radius {r} px");
    let lit = img.count(p, coloured);
    let k = black();
    let (dz, iz) = render(|o| plot::polar(o, &Source::Model(&k), Some(&k), &THETAS, &opts));
    let lit_zero = iz.count(&dz.panels[0], coloured);
    println!(
        "polar: {lit} coloured pixels ({} px area), {lit_zero} for a black surface",
        area(p)
    );
    // Four fitted curves (≈ 2 px wide, each longer than the radius) and the points.
    assert!(lit > 4 * 2 * r as usize, "{lit}");
    // A black surface leaves the four light-direction markers and every point and
    // line collapsed on the centre.
    assert!(lit_zero < 1500 && lit > 4 * lit_zero, "{lit} vs {lit_zero}");

    let s = svg(draw);
    assert!(
        has_text(&s, "radius: f_r (1/sr)   angle: θo (degrees)"),
        "{:?}",
        texts(&s)
    );
    assert!(
        has_text(&s, "θi = 75°") && has_text(&s, "data (points)") && has_text(&s, "fit (lines)")
    );
    assert!(s.contains("<polyline") && s.contains("<circle"));
}

#[test]
fn polar_draws_samples_in_the_plane_of_incidence() {
    let m = paint();
    let s = measured(&m, 5.0, 0.03);
    let opts = PolarOptions {
        scale: RadialScale::Log { decades: 2 },
        ..PolarOptions::default()
    };
    let (drawn, img) = render(|o| plot::polar(o, &Source::Samples(&s), None, &THETAS, &opts));
    // 35 in-plane samples per θi (θo = 0°..85° on both sides), as points.
    let lit = img.count(&drawn.panels[0], coloured);
    println!("polar of samples: {lit} coloured pixels");
    assert!(lit > 4 * 35 * 25, "{lit}");
    // No sample at θi = 33° within 1°, and no fit: nothing to draw.
    let tight = PolarOptions {
        tolerance_deg: 1.0,
        ..PolarOptions::default()
    };
    let e = plot::polar(
        Output::Rgb(&mut Vec::new()),
        &Source::Samples(&s),
        None,
        &[33.0],
        &tight,
    )
    .expect_err("no in-plane samples");
    assert!(
        matches!(e.kind, PlotErrorKind::Input(_)) && e.is_input(),
        "{e}"
    );
}

#[test]
fn hemisphere_maps_fill_their_panels() {
    let (m, dir) = (paint(), Scratch::new("hemisphere"));
    let tweaked = Model::from_toml(&m.to_toml().replace("n = [63.8]", "n = [55.0]"), None)
        .expect("a tweaked paint");
    assert_ne!(tweaked, m);
    for projection in [Projection::Concentric, Projection::Orthographic] {
        let opts = HemisphereOptions {
            projection,
            ..HemisphereOptions::default()
        };
        let data = Source::Model(&m);
        let draw = |o: Output<'_>| plot::hemisphere(o, &data, Some(tweaked.as_brdf()), 60.0, &opts);
        let (drawn, img) = render(draw);
        assert_eq!(drawn.panels.len(), 2);
        for p in &drawn.panels {
            let side = p.x1 - p.x0;
            assert_eq!(side, p.y1 - p.y0, "square panels");
            assert!(side > 250, "{side} px");
            let filled = img.count(p, |c| c != [255, 255, 255]) as f64 / area(p) as f64;
            let colours = img.distinct(p);
            println!(
                "{projection:?} {}: {filled:.3} filled, {colours} colours",
                p.label
            );
            match projection {
                // The whole square is the hemisphere.
                Projection::Concentric => assert!(filled > 0.97, "{filled}"),
                // The disk is π/4 of its square.
                Projection::Orthographic => assert!((0.72..0.86).contains(&filled), "{filled}"),
            }
            assert!(
                colours > 150,
                "{colours} colours: a smooth map, not a flat fill"
            );
        }
        let s = svg(draw);
        assert!(has_text(&s, "f_r · cos θo (1/sr)"), "{:?}", texts(&s));
        assert!(texts(&s).iter().any(|t| t.contains(projection.name())));
        assert!(has_text(&s, "data") && has_text(&s, "fit"));
        assert!(s.contains("<rect") && s.contains("<polyline"));
    }
    let opts = HemisphereOptions {
        scale: ColorScale::Log { decades: 2 },
        ..HemisphereOptions::default()
    };
    let draw = |o: Output<'_>| plot::hemisphere(o, &Source::Model(&m), None, 75.0, &opts);
    assert_eq!(png_file(&dir.path("hemisphere.png"), draw), (900, 560));
}

#[test]
fn hemisphere_of_samples_marks_what_they_do_not_cover() {
    let m = paint();
    let s = measured(&m, 5.0, 0.0);
    // Keep the backward half only (φo − φi within ±90°).
    let half = Samples {
        samples: s
            .samples
            .iter()
            .filter(|x| {
                let d = x.pair.outgoing.phi_deg;
                !(90.0..=270.0).contains(&d)
            })
            .cloned()
            .collect(),
        ..s.clone()
    };
    let opts = HemisphereOptions {
        projection: Projection::Orthographic,
        ..HemisphereOptions::default()
    };
    let (drawn, img) = render(|o| plot::hemisphere(o, &Source::Samples(&half), None, 45.0, &opts));
    let p = &drawn.panels[0];
    let grey = img.count(p, |c| c == [190, 190, 190]) as f64 / area(p) as f64;
    println!("half coverage: {grey:.3} of the panel grey");
    // About half of the disk (π/8 of the square), less a band of kernel reach.
    assert!((0.25..0.40).contains(&grey), "{grey}");
}

#[test]
fn albedo_draws_totals_and_terms() {
    let (m, dir) = (paint(), Scratch::new("albedo"));
    let opts = AlbedoOptions::default();
    let data = Source::Model(&m);
    let draw = |o: Output<'_>| plot::albedo(o, &data, Some(&m), &opts);
    assert_eq!(png_file(&dir.path("albedo.png"), draw), (900, 700));
    let (drawn, img) = render(draw);
    assert_eq!(drawn.panels.len(), 1);
    let p = &drawn.panels[0];
    let lit = img.count(p, coloured);
    let dark = img.count(p, |c| c.iter().all(|&v| v < 60));
    println!(
        "albedo: {lit} coloured, {dark} dark pixels in {} px",
        area(p)
    );
    // Four term curves across the width, and the black total (line and points).
    assert!(lit > 4 * (p.x1 - p.x0) as usize, "{lit}");
    assert!(dark > 2 * (p.x1 - p.x0) as usize, "{dark}");
    let s = svg(draw);
    assert!(has_text(&s, "θi (degrees)"), "{:?}", texts(&s));
    assert!(has_text(&s, "directional albedo ρ (dimensionless)"));
    assert!(
        has_text(&s, "diffuse (Lambert)") && has_text(&s, "lobe 3") && has_text(&s, "fit (total)")
    );
    assert!(s.contains("<polyline"));

    // RGB: one panel a channel.
    let c = rgb();
    let (drawn, img) = render(|o| plot::albedo(o, &Source::Model(&c), None, &opts));
    assert_eq!(drawn.panels.len(), 3);
    for p in &drawn.panels {
        assert!(
            img.count(p, coloured) > (p.x1 - p.x0) as usize,
            "{}",
            p.label
        );
    }
}

#[test]
fn separability_draws_p_s_against_k() {
    let (m, dir) = (paint(), Scratch::new("separability"));
    let grid = Grid::hemisphere(9, 18);
    let t = Table::from_brdf(m.as_brdf(), grid).expect("a table of the paint");
    let noisy = measured(&m, 10.0, 0.05)
        .to_table()
        .expect("a complete grid");
    let tables = [("paint", &t), ("noisy", &noisy)];
    let opts = SeparabilityOptions::default();
    let draw = |o: Output<'_>| plot::separability(o, &tables, &[], &opts);
    assert_eq!(png_file(&dir.path("separability.png"), draw), (900, 700));
    let (drawn, img) = render(draw);
    let p = &drawn.panels[0];
    let lit = img.count(p, coloured);
    println!("separability: {lit} coloured pixels");
    // Two series of ten points joined by lines.
    assert!(lit > 2 * 10 * 40, "{lit}");
    let s = svg(draw);
    assert!(has_text(&s, "P_s^(k) (1/sr)"), "{:?}", texts(&s));
    assert!(has_text(&s, "k (number of separable terms)") && has_text(&s, "noisy"));
    assert!(s.contains("<polyline"));
    let e = plot::separability(Output::Svg(&mut String::new()), &tables, &[0], &opts)
        .expect_err("k = 0");
    assert!(e.is_input());
}

#[test]
fn sphere_is_lit_where_the_light_reaches() {
    let (m, dir) = (rgb(), Scratch::new("sphere"));
    let opts = SphereOptions::default();
    let data = Source::Model(&m);
    let draw = |o: Output<'_>| plot::sphere(o, &data, Some(m.as_brdf()), &opts);
    assert_eq!(png_file(&dir.path("sphere.png"), draw), (900, 520));
    let (drawn, img) = render(draw);
    assert_eq!(drawn.panels.len(), 2);
    for p in &drawn.panels {
        let side = p.x1 - p.x0;
        let lit = img.count(p, not_black) as f64 / area(p) as f64;
        println!("sphere {}: {side} px, {lit:.3} lit", p.label);
        // The sphere covers 0.96² π/4 = 0.72 of its square; the light at 45° from the
        // view reaches (1 + cos 45°)/2 = 0.85 of the visible disk: 0.62.
        assert!((0.55..0.66).contains(&lit), "{lit}");
        for (x, y) in [
            (p.x0, p.y0),
            (p.x1 - 1, p.y0),
            (p.x0, p.y1 - 1),
            (p.x1 - 1, p.y1 - 1),
        ] {
            assert_eq!(img.at(x, y), [0, 0, 0], "black off the sphere");
        }
        // Coloured: the blue channel is the brightest at the centre of the lit side.
        let c = img.at((p.x0 + p.x1) / 2 - side / 8, (p.y0 + p.y1) / 2 - side / 8);
        assert!(c[2] > c[0] && c[2] > 60, "{c:?}");
    }
    // Both spheres are the same model under the same exposure.
    let (a, b) = (&drawn.panels[0], &drawn.panels[1]);
    for (dx, dy) in [(0.3, 0.3), (0.5, 0.5), (0.7, 0.4)] {
        let at = |p: &PanelRect| {
            img.at(
                p.x0 + ((p.x1 - p.x0) as f64 * dx) as i32,
                p.y0 + ((p.y1 - p.y0) as f64 * dy) as i32,
            )
        };
        assert_eq!(at(a), at(b));
    }
    // A black surface renders black.
    let k = black();
    let (dz, iz) = render(|o| plot::sphere(o, &Source::Model(&k), None, &opts));
    assert_eq!(iz.count(&dz.panels[0], not_black), 0);
    // Light from behind at 120° from the view reaches (1 + cos 120°)/2 = 1/4 of the
    // visible disk: 0.18 of the square.
    let behind = SphereOptions {
        light_theta_deg: 120.0,
        ..SphereOptions::default()
    };
    let (db, ib) = render(|o| plot::sphere(o, &Source::Model(&m), None, &behind));
    let p = &db.panels[0];
    let lit = ib.count(p, not_black) as f64 / area(p) as f64;
    println!("sphere lit from behind: {lit:.3}");
    assert!((0.14..0.20).contains(&lit), "{lit}");
    // Lit on the side of the light: upper left, not lower right.
    let (cx, cy, q) = ((p.x0 + p.x1) / 2, (p.y0 + p.y1) / 2, (p.x1 - p.x0) / 3);
    assert!(not_black(ib.at(cx - q, cy - q)) && !not_black(ib.at(cx + q / 2, cy + q / 2)));
    let s = svg(draw);
    assert!(
        has_text(&s, "data") && has_text(&s, "fit"),
        "{:?}",
        texts(&s)
    );
    assert!(texts(&s).iter().any(|t| t.contains("exposure = ")));
    assert!(s.contains("<rect"));
}

#[test]
fn png_bytes_in_memory() {
    let m = paint();
    let mut bytes = Vec::new();
    let drawn = plot::polar(
        Output::Png(&mut bytes),
        &Source::Model(&m),
        None,
        &[45.0],
        &PolarOptions {
            size: (640, 480),
            ..PolarOptions::default()
        },
    )
    .expect("PNG bytes");
    assert_eq!(png_size(&bytes), (640, 480));
    assert_eq!(drawn.size, (640, 480));
}

#[test]
fn errors_name_the_output_and_the_problem() {
    let m = paint();
    let p = Path::new("/nonexistent/plot.jpg");
    let e = plot::polar(
        Output::File(p),
        &Source::Model(&m),
        None,
        &[0.0],
        &PolarOptions::default(),
    )
    .expect_err("jpg");
    assert!(matches!(e.kind, PlotErrorKind::Extension));
    assert!(e.to_string().starts_with("/nonexistent/plot.jpg: "), "{e}");
    let p = Path::new("out.svg");
    let e = plot::polar(
        Output::File(p),
        &Source::Model(&m),
        None,
        &[0.0],
        &PolarOptions {
            channel: ChannelChoice::One(1),
            ..PolarOptions::default()
        },
    )
    .expect_err("one channel only");
    assert!(
        e.is_input() && e.to_string().contains("out.svg: channel index 1"),
        "{e}"
    );
    let e = plot::hemisphere(
        Output::Svg(&mut String::new()),
        &Source::Model(&m),
        None,
        90.0,
        &HemisphereOptions::default(),
    )
    .expect_err("grazing");
    assert!(e.to_string().contains("θi = 90°"), "{e}");
    let c = rgb();
    let e = plot::sphere(
        Output::Svg(&mut String::new()),
        &Source::Model(&m),
        Some(c.as_brdf()),
        &SphereOptions::default(),
    )
    .expect_err("channels differ");
    assert!(e.to_string().contains("channels"), "{e}");
    let e = plot::polar(
        Output::File(Path::new("/nonexistent-dir/x.png")),
        &Source::Model(&m),
        None,
        &[0.0],
        &PolarOptions::default(),
    )
    .expect_err("no such directory");
    assert!(!e.is_input() && e.target == "/nonexistent-dir/x.png", "{e}");
}

/// Writes the example images of `docs/images/`: blue paint at 550 nm (Lafortune et
/// al. 1997, Table 1) measured in simulation on a 5° isotropic grid with ±3 % noise,
/// against the model itself; the sphere from the RGB model of docs/CONVENTIONS.md.
#[test]
#[ignore = "writes docs/images; run by hand"]
fn gallery() {
    let out = repo().join("docs/images");
    std::fs::create_dir_all(&out).expect("docs/images");
    let m = paint();
    let s = measured(&m, 5.0, 0.03);
    let data = Source::Samples(&s);
    let (dl, fl) = ("simulated data", "Lafortune model");
    let title = |t: &str| Some(format!("Blue paint, 550 nm: {t}"));

    let opts = PolarOptions {
        title: title("f_r in the plane of incidence"),
        data_label: dl.into(),
        fit_label: fl.into(),
        scale: RadialScale::Log { decades: 2 },
        ..PolarOptions::default()
    };
    plot::polar(
        Output::File(&out.join("polar.png")),
        &data,
        Some(&m),
        &THETAS,
        &opts,
    )
    .expect("polar.png");

    let opts = HemisphereOptions {
        title: title("f_r · cos θo over the hemisphere, θi = 60°"),
        data_label: dl.into(),
        fit_label: fl.into(),
        levels: 24,
        ..HemisphereOptions::default()
    };
    plot::hemisphere(
        Output::File(&out.join("hemisphere.png")),
        &data,
        Some(&m),
        60.0,
        &opts,
    )
    .expect("hemisphere.png");

    let opts = AlbedoOptions {
        title: title("directional albedo ρ(θi)"),
        data_label: dl.into(),
        fit_label: fl.into(),
        ..AlbedoOptions::default()
    };
    plot::albedo(
        Output::File(&out.join("albedo.png")),
        &data,
        Some(&m),
        &opts,
    )
    .expect("albedo.png");

    let measured_table = s.to_table().expect("the simulated grid is complete");
    let model_table = Table::from_brdf(m.as_brdf(), measured_table.grid).expect("model table");
    let opts = SeparabilityOptions {
        title: title("separability P_s^(k)"),
        ..SeparabilityOptions::default()
    };
    plot::separability(
        Output::File(&out.join("separability.png")),
        &[(dl, &measured_table), (fl, &model_table)],
        &(1..=60).collect::<Vec<_>>(),
        &opts,
    )
    .expect("separability.png");

    let c = rgb();
    let cs = measured(&c, 5.0, 0.03);
    let opts = SphereOptions {
        title: Some("RGB paint model of docs/CONVENTIONS.md on a sphere".into()),
        data_label: dl.into(),
        fit_label: fl.into(),
        ..SphereOptions::default()
    };
    plot::sphere(
        Output::File(&out.join("sphere.png")),
        &Source::Samples(&cs),
        Some(c.as_brdf()),
        &opts,
    )
    .expect("sphere.png");
}
