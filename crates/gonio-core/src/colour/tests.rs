use super::*;

const BABEL: &str = include_str!("testdata/colorchecker_babelcolor_avg.csv");
const BABEL_XYY: &str = include_str!("testdata/colorchecker_babelcolor_xyY_d50.csv");
const COLOUR_SCIENCE: &str = include_str!("testdata/colorchecker_colour_science_xyz.csv");

/// The data lines of a test file: `#` comments and the header left out.
fn data_lines(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .skip(1)
}

/// The BabelColor spectra: wavelengths, then (name, values) per patch.
fn babel() -> (Vec<f64>, Vec<(String, Vec<f64>)>) {
    let header = BABEL.lines().find(|l| !l.starts_with('#')).unwrap();
    let names: Vec<String> = header.split(',').skip(1).map(str::to_string).collect();
    let mut wl = Vec::new();
    let mut cols = vec![Vec::new(); names.len()];
    for line in data_lines(BABEL) {
        let mut f = line.split(',').map(|x| x.parse::<f64>().unwrap());
        wl.push(f.next().unwrap());
        for c in &mut cols {
            c.push(f.next().unwrap());
        }
    }
    (wl, names.into_iter().zip(cols).collect())
}

fn wl(first: f64, step: f64, n: usize) -> Vec<f64> {
    (0..n).map(|i| first + step * i as f64).collect()
}

#[test]
fn the_shipped_tables_parse() {
    let t = tables::parse_all().unwrap();
    assert_eq!(t.cmf_1931.len(), 471);
    assert_eq!(t.cmf_1964.len(), 471);
    // The sums of the 1 nm tables (360–830 nm), which a second transcription of the
    // CIE tables (cvrl.org's, as luxpy 1.12.5 ships them) gives to 1e-12.
    let sum = |c: &[[f64; 3]], k: usize| c.iter().map(|r| r[k]).sum::<f64>();
    assert!((sum(&t.cmf_1931, 0) - 106.865469).abs() < 1e-5);
    assert!((sum(&t.cmf_1931, 1) - 106.856917).abs() < 1e-5);
    assert!((sum(&t.cmf_1931, 2) - 106.892251).abs() < 1e-5);
    assert!((sum(&t.cmf_1964, 1) - 116.661877).abs() < 1e-5);
    // V(λ) = ȳ(λ) of the 1931 observer peaks at 555 nm with the value 1 (CIE 018:2019).
    assert_eq!(t.cmf_1931[555 - 360][1], 1.0);
    // Every relative SPD is normalised to 100 at 560 nm.
    for ill in Illuminant::ALL {
        let p = ill.relative_power(560.0).unwrap();
        let expect = if ill == Illuminant::E { 1.0 } else { 100.0 };
        assert!((p - expect).abs() < 1e-12, "{ill}: {p}");
    }
    assert_eq!(Illuminant::D65.relative_power(359.0), None);
    assert_eq!(Illuminant::D65.relative_power(500.5), None);
    // D65 at 300 nm is outside the grid; at 830 nm the CIE 1 nm table's last row.
    assert_eq!(Illuminant::D65.relative_power(830.0), Some(60.3125));
}

#[test]
fn illuminant_a_from_its_definition_matches_the_cie_table() {
    let rows = tables::parse_rows::<1>("illuminant_a.csv", tables::A_TABLE).unwrap();
    assert_eq!(rows.len(), 471);
    for (w, [v]) in rows {
        // The table has 6 significant figures.
        let a = illuminant_a(w);
        assert!((a - v).abs() <= 5e-6 * v + 1e-9, "{w} nm: {a} vs {v}");
    }
}

/// CIE 015:2018 Table T.3 (table number **UNCONFIRMED**): chromaticities of the CIE
/// illuminants for the 2° and 10° observers.
#[test]
fn illuminant_white_points_match_the_cie_published_chromaticities() {
    let published = [
        (Observer::Cie1931, Illuminant::D65, 0.31272, 0.32903),
        (Observer::Cie1964, Illuminant::D65, 0.31382, 0.33100),
        (Observer::Cie1931, Illuminant::A, 0.44757, 0.40745),
        (Observer::Cie1964, Illuminant::A, 0.45117, 0.40594),
        (Observer::Cie1931, Illuminant::D50, 0.34567, 0.35850),
        (Observer::Cie1964, Illuminant::D50, 0.34773, 0.35952),
        (Observer::Cie1931, Illuminant::E, 1.0 / 3.0, 1.0 / 3.0),
        (Observer::Cie1964, Illuminant::E, 1.0 / 3.0, 1.0 / 3.0),
    ];
    let w = wl(360.0, 5.0, 95);
    for (o, i, x, y) in published {
        let c = Colorimeter::new(o, i);
        let white = c.xyz(&w, &vec![1.0; w.len()]).unwrap();
        let (cx, cy) = white.chromaticity().unwrap();
        assert!(
            (cx - x).abs() < 1e-4 && (cy - y).abs() < 1e-4,
            "{o} {i}: ({cx}, {cy}) vs ({x}, {y})"
        );
        assert!((white.y - 1.0).abs() < 1e-12);
        assert!((c.white().x - white.x).abs() < 1e-12);
    }
}

#[test]
fn colorchecker_spectra_agree_with_colour_science_for_every_observer_and_illuminant() {
    let (w, patches) = babel();
    assert_eq!((w.len(), w[0], w[35]), (36, 380.0, 730.0));
    let mut n = 0;
    for line in data_lines(COLOUR_SCIENCE) {
        let f: Vec<&str> = line.split(',').collect();
        let (o, i, name) = (f[0].parse().unwrap(), f[1].parse().unwrap(), f[2]);
        let expect: Vec<f64> = f[3..].iter().map(|x| x.parse().unwrap()).collect();
        let values = &patches.iter().find(|p| p.0 == name).unwrap().1;
        let got = Colorimeter::new(o, i).xyz(&w, values).unwrap();
        for (g, e) in got.to_array().iter().zip(&expect) {
            assert!(
                (g - e).abs() < 1e-9,
                "{o} {i} {name}: {got:?} vs {expect:?}"
            );
        }
        n += 1;
    }
    assert_eq!(n, 2 * 4 * 24);
}

/// BabelColor's published xyY (D50, 2°) are averages over 30 measured charts, not the
/// colours of the average spectra, so they agree with those only to 8.1e-4 (mean 1.6e-4; the
/// darkest and most saturated patches differ most); colour-science's own ASTM E308
/// method misses them by as much (8.1e-4).
#[test]
fn colorchecker_spectra_agree_with_babelcolor_published_chromaticities() {
    let (w, patches) = babel();
    let c = Colorimeter::new(Observer::Cie1931, Illuminant::D50);
    let (mut max, mut sum) = (0.0f64, 0.0);
    let mut n = 0;
    for line in data_lines(BABEL_XYY) {
        let f: Vec<&str> = line.split(',').collect();
        let (x, y, big_y): (f64, f64, f64) = (
            f[1].parse().unwrap(),
            f[2].parse().unwrap(),
            f[3].parse().unwrap(),
        );
        let values = &patches.iter().find(|p| p.0 == f[0]).unwrap().1;
        let got = c.xyz(&w, values).unwrap();
        let (cx, cy) = got.chromaticity().unwrap();
        let d = (cx - x).abs().max((cy - y).abs());
        max = max.max(d);
        sum += d;
        assert!(
            (got.y - big_y).abs() < 1e-3,
            "{}: Y {} vs {big_y}",
            f[0],
            got.y
        );
        n += 1;
    }
    assert_eq!(n, 24);
    assert!(max < 9e-4, "max |Δxy| {max}");
    assert!(sum / 24.0 < 2e-4, "mean |Δxy| {}", sum / 24.0);
}

#[test]
fn xyz_is_linear_in_the_spectrum() {
    let (w, p) = babel();
    let c = Colorimeter::new(Observer::Cie1964, Illuminant::A);
    let (a, b) = (&p[3].1, &p[14].1);
    let mix: Vec<f64> = a.iter().zip(b).map(|(a, b)| 0.3 * a - 2.5 * b).collect();
    let (xa, xb, xm) = (
        c.xyz(&w, a).unwrap(),
        c.xyz(&w, b).unwrap(),
        c.xyz(&w, &mix).unwrap(),
    );
    for k in 0..3 {
        let e = 0.3 * xa.to_array()[k] - 2.5 * xb.to_array()[k];
        assert!((xm.to_array()[k] - e).abs() < 1e-12);
    }
}

#[test]
fn a_constant_spectrum_under_e_is_neutral() {
    let c = Colorimeter::new(Observer::Cie1931, Illuminant::E);
    let w = wl(400.0, 10.0, 31);
    let v = c.colour(&w, &vec![0.4; w.len()]).unwrap();
    let (x, y) = v.xy.unwrap();
    assert!((x - 1.0 / 3.0).abs() < 1e-4 && (y - 1.0 / 3.0).abs() < 1e-4);
    assert!((v.xyz.y - 0.4).abs() < 1e-12);
    // Adapted to the sRGB white: grey, to the 4 decimals of the IEC matrix.
    let [r, g, b] = v.srgb_linear;
    assert!((r - 0.4).abs() < 2e-4 && (g - 0.4).abs() < 2e-4 && (b - 0.4).abs() < 2e-4);
    assert_eq!(v.srgb8[0], v.srgb8[1]);
    assert_eq!(v.srgb8[1], v.srgb8[2]);
    // Without adaptation E's white is pinkish in sRGB: red above blue.
    let raw = c.clone().with_adaptation(Adaptation::None);
    let [r, _, b] = raw.srgb_linear(v.xyz);
    assert!(r - b > 0.02, "{r} {b}");
}

#[test]
fn a_perfect_white_is_srgb_white_under_every_illuminant_when_adapted() {
    let w = wl(380.0, 5.0, 81);
    for o in [Observer::Cie1931, Observer::Cie1964] {
        for i in Illuminant::ALL {
            let c = Colorimeter::new(o, i);
            let v = c.colour(&w, &vec![1.0; w.len()]).unwrap();
            for ch in v.srgb_linear {
                assert!((ch - 1.0).abs() < 2.5e-4, "{o} {i}: {:?}", v.srgb_linear);
            }
            assert_eq!(v.srgb8, [255, 255, 255]);
        }
    }
    // Under A without adaptation a white is orange: R > G > B.
    let c = Colorimeter::new(Observer::Cie1931, Illuminant::A).with_adaptation(Adaptation::None);
    let [r, g, b] = c.srgb_linear(c.white());
    assert!(r > g && g > b && b < 0.5, "{r} {g} {b}");
}

/// The Bradford D65 → D50 matrix as B. Lindbloom publishes it ("Chromatic Adaptation",
/// brucelindbloom.com, whites X 0.95047, Z 1.08883 and X 0.96422, Z 0.82521).
#[test]
fn bradford_reproduces_the_published_d65_to_d50_matrix() {
    let m = srgb::bradford(
        Xyz::from_array([0.95047, 1.0, 1.08883]),
        Xyz::from_array([0.96422, 1.0, 0.82521]),
    )
    .unwrap();
    let published = [
        [1.0478112, 0.0228866, -0.0501270],
        [0.0295424, 0.9904844, -0.0170491],
        [-0.0092345, 0.0150436, 0.7521316],
    ];
    for (r, p) in m.iter().zip(&published) {
        for (a, b) in r.iter().zip(p) {
            assert!((a - b).abs() < 1e-7, "{m:?}");
        }
    }
    let inv = srgb::inverse(&m).unwrap();
    let id = srgb::mat_mul(&m, &inv);
    for (i, r) in id.iter().enumerate() {
        for (j, v) in r.iter().enumerate() {
            assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
        }
    }
    assert_eq!(
        srgb::inverse(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]),
        None
    );
}

#[test]
fn the_srgb_transfer_function_round_trips_and_meets_at_its_breakpoints() {
    use srgb::{SRGB_ENCODED_BREAK, SRGB_LINEAR_BREAK, decode, encode};
    // The two pieces meet at the published breakpoints (0.0031308 ↔ 0.04045).
    let below = 12.92 * SRGB_LINEAR_BREAK;
    let above = 1.055 * SRGB_LINEAR_BREAK.powf(1.0 / 2.4) - 0.055;
    assert!((below - above).abs() < 1e-7, "{below} {above}");
    assert!((encode(SRGB_LINEAR_BREAK) - SRGB_ENCODED_BREAK).abs() < 1e-6);
    assert!((decode(SRGB_ENCODED_BREAK) - SRGB_LINEAR_BREAK).abs() < 1e-6);
    assert_eq!(encode(0.0), 0.0);
    assert!((encode(1.0) - 1.0).abs() < 1e-15);
    assert!((encode(0.001) - 0.01292).abs() < 1e-15);
    // 18 % grey is code value 118.
    assert_eq!(srgb::to_8bit([encode(0.18); 3]), [118; 3]);
    for i in 0..=1000 {
        let v = i as f64 / 1000.0;
        assert!((decode(encode(v)) - v).abs() < 1e-14, "{v}");
        assert!((encode(decode(v)) - v).abs() < 1e-14, "{v}");
        assert!(encode(v) >= v - 1e-15);
    }
    assert_eq!(encode(-0.5), -encode(0.5));
    let [a, b, c] = srgb::encode_clipped([-0.2, 1.7, f64::NAN]);
    assert!(a == 0.0 && (b - 1.0).abs() < 1e-15 && c == 0.0);
    assert_eq!(srgb::to_8bit([0.0, 1.0, 0.5]), [0, 255, 128]);
}

/// The IEC 61966-2-1 matrix maps the sRGB white (D65, x 0.3127, y 0.3290) to 1, 1, 1
/// to its four decimals.
#[test]
fn the_iec_matrix_maps_its_white_to_one() {
    let (x, y) = srgb::SRGB_WHITE_XY;
    let rgb = srgb::mul(&srgb::XYZ_TO_SRGB, srgb::xyz_of_xy(x, y).to_array());
    for v in rgb {
        assert!((v - 1.0).abs() < 2e-4, "{rgb:?}");
    }
}

#[test]
fn sprague_passes_through_the_samples_and_reproduces_quartics_inside() {
    // Samples every 10 nm from 380 nm; a quartic in λ.
    let w = wl(380.0, 10.0, 36);
    let q = |l: f64| {
        let t = (l - 500.0) / 100.0;
        0.3 + 0.2 * t - 0.7 * t * t + 0.1 * t.powi(3) + 0.05 * t.powi(4)
    };
    let v: Vec<f64> = w.iter().map(|&l| q(l)).collect();
    let mut got = vec![f64::NAN; tables::GRID_LEN];
    interp::uniform_onto_grid(380.0, 10.0, &v, Interpolation::Sprague, |g, x| got[g] = x);
    for (g, x) in got.iter().enumerate() {
        let l = (360 + g) as f64;
        if l <= 380.0 {
            assert_eq!(*x, v[0]);
        } else if l >= 730.0 {
            assert_eq!(*x, v[35]);
        } else if (l - 380.0) % 10.0 == 0.0 {
            assert!((x - q(l)).abs() < 1e-14, "{l}");
        } else if (400.0..=710.0).contains(&l) {
            assert!((x - q(l)).abs() < 1e-12, "{l}: {x} vs {}", q(l));
        }
    }
}

#[test]
fn bad_spectra_are_refused_with_what_is_wrong() {
    let c = Colorimeter::new(Observer::Cie1931, Illuminant::D65);
    let w = wl(380.0, 2.0, 200);
    let e = c.xyz(&w, &vec![0.5; 200]).unwrap_err();
    assert_eq!(
        e,
        ColourError::Spacing {
            found_nm: 2.0,
            from_nm: 380.0,
            to_nm: 382.0
        }
    );
    assert!(e.to_string().contains("found 2 nm"), "{e}");
    let mut w = wl(380.0, 5.0, 81);
    w[40] += 1.0;
    assert!(matches!(
        c.xyz(&w, &vec![0.5; 81]),
        Err(ColourError::Spacing { from_nm: 575.0, .. })
    ));
    let w = wl(420.0, 10.0, 30);
    let e = c.xyz(&w, &[0.5; 30]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "the spectrum covers 420–710 nm; at least 400–700 nm is needed"
    );
    let w = wl(380.0, 10.0, 40);
    assert!(matches!(
        c.xyz(&w, &[0.5; 39]),
        Err(ColourError::Length {
            wavelengths: 40,
            values: 39
        })
    ));
    let mut v = vec![0.5; 40];
    v[3] = f64::NAN;
    assert!(matches!(
        c.xyz(&w, &v),
        Err(ColourError::NotFinite {
            wavelength_nm: 410.0,
            ..
        })
    ));
    let mut w2 = w.clone();
    w2.swap(4, 5);
    assert!(matches!(
        c.xyz(&w2, &[0.5; 40]),
        Err(ColourError::BadWavelength { index: 5, .. })
    ));
    assert!(matches!(
        c.xyz_of_channels(&Channels::Rgb, &[1.0, 1.0, 1.0]),
        Err(ColourError::NotSpectral(_))
    ));
}

#[test]
fn channel_wavelengths_may_be_uneven() {
    let c = Colorimeter::new(Observer::Cie1931, Illuminant::D65);
    // Uniform 10 nm channels are the same as the spectrum.
    let (w, p) = babel();
    let ch = Channels::wavelengths(&w).unwrap();
    assert_eq!(
        c.xyz_of_channels(&ch, &p[0].1).unwrap(),
        c.xyz(&w, &p[0].1).unwrap()
    );
    // Uneven: a constant is a constant, whatever the spacing.
    let w = [390.0, 420.0, 455.0, 500.0, 610.0, 700.0, 750.0];
    let ch = Channels::wavelengths(&w).unwrap();
    let got = c.xyz_of_channels(&ch, &[0.25; 7]).unwrap();
    let white = c.white();
    for (g, e) in got.to_array().iter().zip(white.to_array()) {
        assert!((g - 0.25 * e).abs() < 1e-12);
    }
    // Linear between channels: a ramp in λ gives the weights' first moment.
    let ramp: Vec<f64> = w.iter().map(|l| (l - 390.0) / 360.0).collect();
    let got = c.xyz_of_channels(&ch, &ramp).unwrap();
    let expect: f64 = (0..tables::GRID_LEN)
        .map(|g| {
            let l = (360 + g) as f64;
            c.weights[g][1] * ((l.clamp(390.0, 750.0) - 390.0) / 360.0)
        })
        .sum();
    assert!((got.y - expect).abs() < 1e-12);
}

#[test]
fn names_parse() {
    assert_eq!("D65".parse::<Illuminant>().unwrap(), Illuminant::D65);
    assert_eq!("d50".parse::<Illuminant>().unwrap(), Illuminant::D50);
    assert_eq!("A".parse::<Illuminant>().unwrap(), Illuminant::A);
    assert_eq!("E".parse::<Illuminant>().unwrap(), Illuminant::E);
    assert_eq!("1931".parse::<Observer>().unwrap(), Observer::Cie1931);
    assert_eq!("1964".parse::<Observer>().unwrap(), Observer::Cie1964);
    assert_eq!("none".parse::<Adaptation>().unwrap(), Adaptation::None);
    assert_eq!(
        "F2".parse::<Illuminant>().unwrap_err().to_string(),
        "unknown illuminant \"F2\" (expected D65, D50, A or E)"
    );
    assert!("2006".parse::<Observer>().is_err());
    for i in Illuminant::ALL {
        assert_eq!(i.name().parse::<Illuminant>().unwrap(), i);
    }
}

#[test]
fn linear_interpolation_can_be_chosen() {
    let (w, p) = babel();
    let s = Colorimeter::new(Observer::Cie1931, Illuminant::D65);
    let l = s.clone().with_interpolation(Interpolation::Linear);
    let (a, b) = (s.xyz(&w, &p[0].1).unwrap(), l.xyz(&w, &p[0].1).unwrap());
    // Different, but only a little for a smooth reflectance.
    assert!(a != b);
    assert!((a.y - b.y).abs() < 1e-3);
}
