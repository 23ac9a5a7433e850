//! The BRDF file formats: MERL binary, ASTM E1392-style text, CSV — round trips,
//! MERL files of known models at their bin centres, partial coverage left invalid,
//! damaged files refused with the place named, detection, and the fuzz bodies.
//!
//! A MERL write is 35 MB and 1.46 million evaluations: the tests make five.

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;
use std::sync::OnceLock;

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, Dir, SphericalDeg};
use gonio_io::formats::merl::{self, BINS, FILE_BYTES, SCALE};
use gonio_io::formats::{
    self, Bin, Data, Format, FromSamples, MerlBrdf, fuzz, read_astm, write_astm,
};
use gonio_process::{Axis, Grid, Sample, Samples, Table};
use proptest::prelude::*;

/// The Lafortune RGB model of `docs/CONVENTIONS.md`.
const LAFORTUNE: &str = r#"
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

fn lafortune() -> Model {
    Model::from_toml(LAFORTUNE, None).expect("the CONVENTIONS model reads")
}

/// The Lafortune model's MERL file, written once for every test that needs it.
fn lafortune_merl() -> &'static (Vec<u8>, MerlBrdf) {
    static FILE: OnceLock<(Vec<u8>, MerlBrdf)> = OnceLock::new();
    FILE.get_or_init(|| {
        let m = MerlBrdf::from_brdf(&lafortune()).expect("RGB model");
        let bytes = formats::write_merl(&m);
        let back = formats::read_merl(&bytes, None).expect("reads back");
        (bytes, back)
    })
}

/// Two roundings (BRDF / scale when writing, file value × scale when reading).
const TWO_ULPS: f64 = 2.0 * f64::EPSILON;

fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(a.abs())
    }
}

/// A reproducible stream in [0, 1) (xorshift64*).
struct Stream(u64);

impl Stream {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A direction uniform over the projected hemisphere.
    fn dir(&mut self) -> Dir {
        let (u, v) = (self.next(), self.next());
        Dir::from_angles(u.sqrt().asin(), 2.0 * PI * v)
    }
}

fn quantiles(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p) as usize];
    (q(0.5), q(0.95), q(1.0))
}

// ---------------------------------------------------------------- MERL: bins

#[test]
fn bin_indices_follow_the_merl_reference() {
    // θh: the square-root map.
    assert_eq!(merl::theta_h_index(0.0), 0);
    assert_eq!(merl::theta_h_index(-1.0), 0);
    assert_eq!(merl::theta_h_index(f64::NAN), 0);
    assert_eq!(merl::theta_h_index(FRAC_PI_2 / 2.0), 63); // floor(√0.5 · 90) = 63
    assert_eq!(merl::theta_h_index(FRAC_PI_2), 89);
    assert_eq!(merl::theta_h_index(10.0), 89);
    for i in 1..90 {
        let edge = (i as f64 / 90.0).powi(2) * FRAC_PI_2;
        assert_eq!(
            merl::theta_h_index(edge * (1.0 + 1e-12)),
            i,
            "above edge {i}"
        );
        assert_eq!(
            merl::theta_h_index(edge * (1.0 - 1e-12)),
            i - 1,
            "below edge {i}"
        );
    }
    // θd linear, φd folded by reciprocity into [0, π).
    assert_eq!(merl::theta_d_index(FRAC_PI_2 / 2.0), 45);
    assert_eq!(merl::theta_d_index(FRAC_PI_2), 89);
    assert_eq!(merl::phi_d_index(PI / 2.0 + 1e-9), 90);
    assert_eq!(merl::phi_d_index(-PI / 2.0 + 1e-9), 90);
    assert_eq!(merl::phi_d_index(1.5 * PI + 1e-9), 90);
    assert_eq!(merl::phi_d_index(0.0), 0);
    assert_eq!(merl::phi_d_index(f64::INFINITY), 0);
    // File order: φd fastest, then θd, then θh.
    let b = Bin::new(2, 3, 4).expect("in range");
    assert_eq!(b.index(), 4 + 180 * (3 + 90 * 2));
    assert_eq!(Bin::from_index(b.index()), Some(b));
    assert_eq!(Bin::new(90, 0, 0), None);
    assert_eq!(Bin::from_index(BINS), None);
    // Centres: the inverse square-root map at i + ½, the linear ones at j + ½, k + ½.
    let c = Bin::new(0, 0, 0).expect("bin").centre();
    assert!(rel(c.theta_h, (0.5f64 / 90.0).powi(2) * FRAC_PI_2) < 1e-15);
    let c = Bin::new(89, 89, 179).expect("bin").centre();
    assert!(rel(c.theta_h, (89.5f64 / 90.0).powi(2) * FRAC_PI_2) < 1e-15);
    assert!(rel(c.theta_d.to_degrees(), 89.5) < 1e-15);
    assert!(rel(c.phi_d.to_degrees(), 179.5) < 1e-15);
    assert_eq!(c.phi_h, 0.0);
}

#[test]
fn every_bin_centre_falls_in_its_bin_and_pairs_are_reciprocal() {
    let mut above = 0;
    for bin in Bin::all() {
        let p = bin.centre_pair();
        assert_eq!(Bin::of(p.wi, p.wo), Some(bin), "{bin}");
        assert_eq!(Bin::of(p.wo, p.wi), Some(bin), "swapped {bin}");
        // φh = 0: the half vector lies in the xz plane.
        let h = (p.wi.vec() + p.wo.vec())
            .normalized()
            .expect("not opposite");
        assert!(h.y.abs() < 1e-12, "{bin}");
        above += usize::from(p.wi.is_above() && p.wo.is_above());
    }
    eprintln!("bin centres with both directions above the horizon: {above} of {BINS}");
    assert!(above > BINS / 2 && above < BINS);
}

// ------------------------------------------------------ MERL: a known model

#[test]
fn merl_of_a_model_holds_the_model_at_bin_centres() {
    let model = lafortune();
    let (bytes, m) = lafortune_merl();
    assert_eq!(bytes.len(), 34_992_012);
    assert_eq!(bytes.len(), FILE_BYTES);
    assert_eq!(&bytes[..12], &[90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0]);
    assert_eq!(m.valid_bins(), BINS, "a model fills every bin");
    assert_eq!(m.channels(), &Channels::Rgb);

    // Every bin holds the model at its centre pair, to the rounding of the scales.
    let mut worst = 0.0f64;
    let mut out = [0.0; 3];
    for bin in Bin::all() {
        let p = bin.centre_pair();
        model.eval(p.wi, p.wo, &mut out);
        for ch in 0..3 {
            let v = m.value(bin, ch).expect("valid");
            worst = worst.max(rel(v, out[ch]));
            // The file value is the BRDF over the channel's scale.
            let f = m.file_values()[ch * BINS + bin.index()];
            assert!(rel(f * SCALE[ch], out[ch]) <= TWO_ULPS);
        }
        if p.wi.is_above() && p.wo.is_above() {
            let mut e = [0.0; 3];
            m.eval(p.wi, p.wo, &mut e);
            assert_eq!(e, m.bin_values(bin).expect("valid"), "{bin}");
        }
    }
    eprintln!("MERL of the Lafortune model at all {BINS} bin centres: max rel. error {worst:.3e}");
    assert!(worst <= TWO_ULPS, "{worst}");

    // Anywhere else the lookup is the value of the bin the pair falls in (the
    // reference code's nearest-bin lookup): within bin resolution of the model.
    let mut s = Stream(0x5eed_0001);
    let mut errs = Vec::new();
    let (mut f, mut g) = ([0.0; 3], [0.0; 3]);
    for _ in 0..20_000 {
        let (wi, wo) = (s.dir(), s.dir());
        let bin = Bin::of(wi, wo).expect("upper hemisphere");
        let c = bin.centre_pair();
        model.eval(c.wi, c.wo, &mut g);
        m.eval(wi, wo, &mut f);
        assert!(m.valid(wi, wo));
        for ch in 0..3 {
            assert!(rel(f[ch], g[ch]) <= TWO_ULPS, "lookup is the bin's value");
        }
        model.eval(wi, wo, &mut g);
        errs.push(rel(f[1], g[1]));
    }
    let (median, p95, max) = quantiles(errs);
    eprintln!(
        "MERL lookup vs the model at 20000 random pairs (G): median rel. error {median:.2e}, \
         95% {p95:.2e}, max {max:.2e}"
    );
    assert!(median < 0.01 && p95 < 0.1, "{median} {p95}");

    // Outside the domain: zero and invalid.
    let below = Dir::from_angles(1.7, 0.3);
    let up = Dir::from_angles(0.3, 0.0);
    m.eval(below, up, &mut f);
    assert_eq!(f, [0.0; 3]);
    assert!(!m.valid(below, up));
}

#[test]
fn merl_files_re_encode_to_the_same_bytes() {
    let (bytes, m) = lafortune_merl();
    let again = m.to_bytes();
    assert!(again == *bytes, "read → write is byte for byte");
    let mut via_writer = Vec::new();
    m.write_to(&mut via_writer).expect("in memory");
    assert_eq!(via_writer.len(), FILE_BYTES);
    assert!(via_writer == *bytes);
}

#[test]
fn merl_samples_are_the_valid_bin_centres() {
    let (_, m) = lafortune_merl();
    let s = m.to_samples_strided(6);
    assert!(s.isotropic);
    assert_eq!(s.channels, Channels::Rgb);
    s.validate().expect("processing accepts them");
    // 15 · 15 · 30 lattice bins, minus those whose centre pair dips below the horizon.
    assert!(s.samples.len() < 15 * 15 * 30 && s.samples.len() > 15 * 15 * 30 / 2);
    eprintln!("stride 6: {} samples", s.samples.len());
    let model = lafortune();
    let mut v = [0.0; 3];
    for x in &s.samples {
        let d = x.pair.to_dirs();
        model.eval(d.wi, d.wo, &mut v);
        for (a, b) in x.value.iter().zip(v) {
            assert!(rel(*a, b) < 1e-9, "{:?}", x.pair);
        }
    }
    assert_eq!(MerlBrdf::stride_for(usize::MAX), 1);
    assert_eq!(MerlBrdf::stride_for(15 * 15 * 30), 6);
    assert_eq!(MerlBrdf::stride_for(1), 180);
}

// -------------------------------------------------- MERL: tables and samples

#[test]
fn merl_of_a_partial_table_leaves_uncovered_bins_invalid() {
    // A grey Lambertian measured only for θi ≤ 40°: 9 × 36 × 19 nodes.
    let grid = Grid::isotropic(
        Axis::from_deg(0.0, 5.0, 9),
        Axis::full_turn(36),
        Axis::from_deg(0.0, 5.0, 19),
    );
    let rho = 0.8;
    let table =
        Table::from_fn(Channels::Single, grid, |_, _, out| out[0] = rho / PI).expect("table");
    let m = formats::read_merl(
        &formats::write_merl(&MerlBrdf::from_table(&table).expect("grey table")),
        None,
    )
    .expect("reads");
    let lim = 40f64.to_radians() + 1e-9;
    let (mut valid, mut invalid_above) = (0, 0);
    let mut worst = 0.0f64;
    for bin in Bin::all() {
        let p = bin.centre_pair();
        let covered = p.wi.theta() <= lim && p.wo.theta() <= FRAC_PI_2 + 1e-9;
        assert_eq!(m.is_valid_bin(bin), covered, "{bin}");
        match m.bin_values(bin) {
            Some(v) => {
                valid += 1;
                for x in v {
                    worst = worst.max(rel(x, rho / PI));
                }
            }
            None => {
                // Invalid in every channel, and read as 0.
                assert!((0..3).all(|ch| m.value(bin, ch).is_none()));
                invalid_above += usize::from(p.wi.is_above() && p.wo.is_above());
            }
        }
    }
    eprintln!(
        "table θi ≤ 40°: {valid} valid bins, {} invalid ({invalid_above} of them with both \
         centre directions above the horizon); grey values max rel. error {worst:.3e}",
        BINS - valid
    );
    assert!(worst <= TWO_ULPS);
    assert!(valid > 100_000 && invalid_above > 100_000);
    // Lookups: inside the coverage ρ/π in R, G and B; outside invalid and 0.
    let mut f = [0.0; 3];
    let (wi, wo) = (
        Dir::from(SphericalDeg::new(20.0, 0.0)),
        Dir::from(SphericalDeg::new(30.0, 150.0)),
    );
    let c = Bin::of(wi, wo).expect("bin").centre_pair();
    assert!(c.wi.theta() < lim);
    assert!(m.valid(wi, wo));
    m.eval(wi, wo, &mut f);
    assert!(f.iter().all(|x| rel(*x, rho / PI) <= TWO_ULPS), "{f:?}");
    let (wi, wo) = (
        Dir::from(SphericalDeg::new(70.0, 0.0)),
        Dir::from(SphericalDeg::new(70.0, 180.0)),
    );
    assert!(!m.valid(wi, wo));
    m.eval(wi, wo, &mut f);
    assert_eq!(f, [0.0; 3]);
}

#[test]
fn merl_of_samples_interpolates_and_never_invents() {
    // Samples at every third bin centre of the model's MERL file, kept where θi ≤ 40°.
    let (_, full) = lafortune_merl();
    let mut samples = full.to_samples_strided(3);
    samples
        .samples
        .retain(|s| s.pair.incident.theta_deg <= 40.0);
    let n = samples.samples.len();
    let m = formats::read_merl(
        &formats::write_merl(
            &MerlBrdf::from_samples(&samples, &FromSamples::default()).expect("RGB samples"),
        ),
        None,
    )
    .expect("reads");
    let model = lafortune();
    let reach = 2.0 * (FromSamples::DEFAULT_MAX_DISTANCE / 2.0).asin();
    let (mut exact, mut valid) = (0, 0);
    let (mut inner, mut inner_invalid, mut inner_invalid_max_ti) = (0, 0, 0.0f64);
    let mut errs = Vec::new();
    let mut g = [0.0; 3];
    for bin in Bin::all() {
        let p = bin.centre_pair();
        let (ti, to) = (p.wi.theta().to_degrees(), p.wo.theta().to_degrees());
        let sampled = bin.theta_h.is_multiple_of(3)
            && bin.theta_d.is_multiple_of(3)
            && bin.phi_d.is_multiple_of(3)
            && ti <= 40.0
            && p.wi.is_above()
            && p.wo.is_above();
        let Some(v) = m.bin_values(bin) else {
            assert!(!sampled, "a sampled bin is valid: {bin}");
            if ti <= 30.0 && to <= 75.0 {
                inner_invalid += 1;
                inner_invalid_max_ti = inner_invalid_max_ti.max(ti);
            }
            continue;
        };
        if ti <= 30.0 && to <= 75.0 {
            inner += 1;
        }
        valid += 1;
        // Never farther from the samples than the documented distance.
        assert!(
            ti <= 40.0 + reach.to_degrees() + 1e-9,
            "{bin} is filled {ti:.2}° from the normal"
        );
        assert!(p.wi.is_above() && p.wo.is_above());
        if sampled {
            exact += 1;
            let w = full.bin_values(bin).expect("valid");
            for ch in 0..3 {
                assert!(rel(v[ch], w[ch]) <= TWO_ULPS, "{bin}");
            }
        } else if ti <= 40.0 {
            model.eval(p.wi, p.wo, &mut g);
            errs.push(rel(v[1], g[1]));
        }
    }
    let (median, p95, max) = quantiles(errs);
    eprintln!(
        "samples: {n} (every third bin, θi ≤ 40°) → {valid} valid bins, {exact} of them \
         exact; interpolated bins with θi ≤ 40° vs the model (G): median rel. error \
         {median:.2e}, 95% {p95:.2e}, max {max:.2e}"
    );
    eprintln!(
        "bins with θi ≤ 30°, θo ≤ 75°: {inner} valid, {inner_invalid} invalid (θi ≤ \
         {inner_invalid_max_ti:.2}°)"
    );
    assert_eq!(exact, n);
    assert!(
        median < 1e-3 && p95 < 0.02 && max < 0.05,
        "{median} {p95} {max}"
    );
    // Well inside the sampled region nothing is left out but a few bins at near-normal
    // incidence, where the samples' isotropic distance (both pairs turned to φi = 0)
    // overstates how far apart nearby pairs are: conservative, never inventive.
    assert!(inner_invalid <= 10 && inner_invalid_max_ti < 5.0);
    assert!(inner > 250_000);
}

#[test]
fn merl_refuses_what_it_cannot_hold() {
    let wl = Channels::wavelengths(&[450.0, 550.0]).expect("channels");
    let samples = Samples {
        channels: wl,
        samples: vec![Sample {
            pair: PairDeg {
                incident: SphericalDeg::new(10.0, 0.0),
                outgoing: SphericalDeg::new(10.0, 180.0),
            },
            value: vec![0.1, 0.2],
            sigma: None,
            flags: 0,
        }],
        isotropic: true,
    };
    let e = MerlBrdf::from_samples(&samples, &FromSamples::default()).expect_err("spectral");
    assert!(e.message.contains("wavelength"), "{e}");
    let e = formats::write(Format::Merl, &Data::Samples(samples.clone())).expect_err("spectral");
    assert_eq!(e.format, Some(Format::Merl));
    let bad = FromSamples {
        max_distance: f64::NAN,
        ..FromSamples::default()
    };
    let rgb = Samples {
        channels: Channels::Rgb,
        samples: vec![Sample {
            value: vec![0.1, 0.2, 0.3],
            ..samples.samples[0].clone()
        }],
        isotropic: true,
    };
    assert!(MerlBrdf::from_samples(&rgb, &bad).is_err());
    assert!(MerlBrdf::from_file_values(vec![0.0; 10]).is_err());
    let mut v = vec![0.0; 3 * BINS];
    v[BINS + 7] = f64::INFINITY;
    let e = MerlBrdf::from_file_values(v).expect_err("+inf");
    assert_eq!(e.byte, Some(12 + 8 * (BINS as u64 + 7)));
}

// ----------------------------------------------------------- MERL: damage

#[test]
fn damaged_merl_files_name_the_byte() {
    let (bytes, _) = lafortune_merl();
    let p = Some(Path::new("paint.binary"));

    // One byte short: detected by its header, refused at the end.
    let short = &bytes[..bytes.len() - 1];
    assert_eq!(formats::detect(short), None);
    let e = formats::read(short, p).expect_err("truncated");
    assert_eq!((e.format, e.byte), (Some(Format::Merl), Some(34_992_011)));
    assert!(e.message.contains("truncated"), "{e}");
    assert!(
        e.to_string()
            .starts_with("paint.binary: byte 34992011: the file is truncated"),
        "{e}"
    );

    // One byte long.
    let mut long = bytes.clone();
    long.push(0);
    let e = formats::read(&long, p).expect_err("long");
    assert_eq!(e.byte, Some(34_992_012));

    // A wrong header int: the exact length of a binary file still reads as MERL.
    let mut wrong = bytes.clone();
    wrong[4..8].copy_from_slice(&91i32.to_le_bytes());
    assert_eq!(formats::detect(&wrong), None);
    let e = formats::read(&wrong, p).expect_err("header");
    assert_eq!(e.byte, Some(4));
    assert!(e.message.contains("is 91, expected 90"), "{e}");
    wrong[4..8].copy_from_slice(&90i32.to_le_bytes());
    wrong[8..12].copy_from_slice(&360i32.to_le_bytes());
    assert_eq!(formats::read(&wrong, p).expect_err("φd").byte, Some(8));

    // +inf in a value: refused at its byte; NaN and negatives mark invalid bins.
    let mut bad = bytes.clone();
    let bin = Bin::new(10, 20, 30).expect("bin");
    let at = 12 + 8 * (2 * BINS + bin.index());
    bad[at..at + 8].copy_from_slice(&f64::INFINITY.to_le_bytes());
    let e = formats::read_merl(&bad, p).expect_err("inf");
    assert_eq!(e.byte, Some(at as u64));
    assert!(e.message.contains("channel B"), "{e}");
    bad[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    let m = formats::read_merl(&bad, p).expect("NaN marks an invalid bin");
    assert_eq!(m.value(bin, 2), None);
    assert!(m.value(bin, 0).is_some());
    assert_eq!(
        formats::read_merl(&bad, p).expect("again"),
        m,
        "NaN markers compare equal"
    );
    assert!(!m.is_valid_bin(bin));
    assert_eq!(m.valid_bins(), BINS - 1);
    let c = bin.centre_pair();
    let mut f = [1.0; 3];
    m.eval(c.wi, c.wo, &mut f);
    assert_eq!(f[2], 0.0);
    assert!(f[0] > 0.0);
    bad[at..at + 8].copy_from_slice(&f64::NEG_INFINITY.to_le_bytes());
    assert!(formats::read_merl(&bad, p).is_ok());

    // Shorter than the header.
    let e = formats::read_merl(&bytes[..5], p).expect_err("tiny");
    assert_eq!(e.byte, Some(5));
    let e = formats::read(&bytes[..12], p).expect_err("header only");
    assert_eq!((e.format, e.byte), (Some(Format::Merl), Some(12)));
}

// ------------------------------------------------------------------- ASTM

fn awkward_samples(channels: Channels, n: usize, seed: u64, isotropic: bool) -> Samples {
    let mut s = Stream(seed);
    let nc = channels.len();
    let specials = [
        0.1 + 0.2,
        1.0 / 3.0,
        1e-300,
        -2.5e-7,
        123456789.123,
        5e-324,
        1e17,
        0.0,
        -0.0,
    ];
    let samples = (0..n)
        .map(|i| {
            let pick = |s: &mut Stream, k: usize| {
                if k.is_multiple_of(3) {
                    specials[(i + k) % specials.len()]
                } else {
                    s.next() / 3.0
                }
            };
            Sample {
                pair: PairDeg {
                    incident: SphericalDeg::new(90.0 * s.next(), 720.0 * s.next() - 360.0),
                    outgoing: SphericalDeg::new(
                        if i == 0 { 90.0 } else { 90.0 * s.next() },
                        360.0 * s.next(),
                    ),
                },
                value: (0..nc).map(|k| pick(&mut s, k)).collect(),
                sigma: None,
                flags: 0,
            }
        })
        .collect();
    Samples {
        channels,
        samples,
        isotropic,
    }
}

#[test]
fn astm_round_trip_is_lossless() {
    for (channels, iso) in [
        (Channels::Rgb, true),
        (Channels::Single, false),
        (
            Channels::wavelengths(&[400.0, 412.5, 700.0]).expect("wavelengths"),
            true,
        ),
    ] {
        let s = awkward_samples(channels, 500, 0xa57e, iso);
        let text = write_astm(&s);
        // Tiny and huge numbers in exponent form, the rest as decimals.
        assert!(
            text.contains(",1e-300") && text.contains(",5e-324"),
            "{text}"
        );
        assert!(
            text.contains(",1e17") && text.contains(",123456789.123"),
            "{text}"
        );
        assert_eq!(formats::detect(text.as_bytes()), Some(Format::Astm));
        let back = read_astm(&text, None).expect("reads");
        assert_eq!(back, s, "bit for bit");
        for (a, b) in back.samples.iter().zip(&s.samples) {
            for (x, y) in a.value.iter().zip(&b.value) {
                assert_eq!(x.to_bits(), y.to_bits());
            }
        }
        let Data::Samples(again) = formats::read(text.as_bytes(), None).expect("dispatch") else {
            panic!("ASTM reads as samples");
        };
        assert_eq!(again, s);
    }
    // The exact header.
    let s = awkward_samples(Channels::Rgb, 2, 1, true);
    let text = write_astm(&s);
    let head: Vec<&str> = text.lines().take(5).collect();
    assert_eq!(
        head,
        [
            "# ASTM E1392-style BRDF written by Gonio",
            "# angles in degrees (theta from the normal, phi from +x towards +y), BRDF in 1/sr",
            "# isotropic: true",
            "NUM_POINTS 2",
            "VARS theta_i,phi_i,theta_s,phi_s,R,G,B",
        ]
    );
}

#[test]
fn astm_reads_cornell_style_headers() {
    let text = "# measured at Cornell\r\n\
                FORMAT ASTM E1392-96\r\n\
                SAMPLE_NAME blue paint\r\n\
                \r\n\
                NUM_POINTS 3\r\n\
                VARS theta_i phi_i theta_s phi_s 450 550 650\r\n\
                10 0 10 180 0.1 0.2 0.3\r\n\
                # a comment among the rows\r\n\
                \r\n\
                10\t0\t20\t180\t0.4 0.5 0.6\r\n\
                30, 0, 30, 180, 0.7, 0.8, 0.9\r\n";
    assert_eq!(formats::detect(text.as_bytes()), Some(Format::Astm));
    let s = read_astm(text, Some(Path::new("paint.astm"))).expect("reads");
    assert_eq!(
        s.channels,
        Channels::wavelengths(&[450.0, 550.0, 650.0]).expect("wl")
    );
    assert_eq!(s.samples.len(), 3);
    assert_eq!(s.samples[1].pair.outgoing.theta_deg, 20.0);
    assert_eq!(s.samples[2].value, vec![0.7, 0.8, 0.9]);
    assert!(!s.isotropic);
    // RGB and single channels, Gonio's column names, commas in VARS.
    let s = read_astm(
        "NUM_POINTS 1\nVARS theta_i,phi_i,theta_o,phi_o,R,G,B\n1,2,3,4,5,6,7\n",
        None,
    )
    .expect("RGB");
    assert_eq!(s.channels, Channels::Rgb);
    let s = read_astm(
        "# isotropic: true\nnum_points 1\nVARS THETA_I PHI_I THETA_S PHI_S value\n1 2 3 4 5\n",
        None,
    )
    .expect("single");
    assert_eq!((s.channels, s.isotropic), (Channels::Single, true));
}

#[test]
fn damaged_astm_files_name_the_line_and_field() {
    let p = Some(Path::new("paint.astm"));
    let err = |t: &str| read_astm(t, p).expect_err(t);
    let head = "# Cornell\nNUM_POINTS 3\nVARS theta_i phi_i theta_s phi_s R G B\n";

    // NUM_POINTS larger than the rows: at the NUM_POINTS line.
    let e = err(&format!("{head}10 0 10 180 1 2 3\n10 0 20 180 1 2 3\n"));
    assert_eq!((e.line, e.field.as_deref()), (Some(2), Some("NUM_POINTS")));
    assert!(
        e.message.contains("announces 3 rows, the file has 2"),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "paint.astm:2: field `NUM_POINTS`: NUM_POINTS announces 3 rows, the file has 2 \
         (truncated?)"
    );
    // More rows than NUM_POINTS: at the first extra row.
    let e = err(&format!(
        "{head}10 0 10 180 1 2 3\n10 0 20 180 1 2 3\n1 0 1 0 1 2 3\n\n2 0 2 0 1 2 3\n"
    ));
    assert_eq!(e.line, Some(8));
    // A non-numeric field, NaN, infinity, θ beyond 90°: at the line and column.
    let e = err(&format!(
        "{head}10 0 10 180 1 2 3\n10 0 20 180 1 x 3\n1 0 1 0 1 2 3\n"
    ));
    assert_eq!((e.line, e.field.as_deref()), (Some(5), Some("G")));
    assert!(
        e.to_string()
            .starts_with("paint.astm:5: field `G`: not a finite number")
    );
    let e = err(&format!("{head}10 0 10 180 1 2 NaN\n"));
    assert_eq!((e.line, e.field.as_deref()), (Some(4), Some("B")));
    let e = err(&format!("{head}10 inf 10 180 1 2 3\n"));
    assert_eq!(e.field.as_deref(), Some("phi_i"));
    let e = err(&format!("{head}10 0 95 180 1 2 3\n"));
    assert_eq!((e.line, e.field.as_deref()), (Some(4), Some("theta_s")));
    let e = err(&format!("{head}10 0 10 180 1 2\n"));
    assert_eq!((e.line, e.field), (Some(4), None));
    // An absurd NUM_POINTS is refused before anything is read or allocated.
    let e = err("NUM_POINTS 1000000000000\nVARS theta_i phi_i theta_s phi_s R G B\n");
    assert_eq!((e.line, e.field.as_deref()), (Some(1), Some("NUM_POINTS")));
    assert!(e.message.contains("50000000"), "{e}");
    let e = err("NUM_POINTS -3\nVARS theta_i phi_i theta_s phi_s R G B\n");
    assert_eq!(e.line, Some(1));
    let e = err("NUM_POINTS 1\nNUM_POINTS 1\n");
    assert_eq!(e.line, Some(2));
    // Header faults.
    let e = err("VARS theta_i phi_i theta_s phi_s R G B\n1 2 3 4 5 6 7\n");
    assert_eq!((e.line, e.field.as_deref()), (Some(1), Some("NUM_POINTS")));
    let e = err("NUM_POINTS 1\nVARS theta_in phi_i theta_s phi_s R G B\n");
    assert_eq!((e.line, e.field.as_deref()), (Some(2), Some("VARS")));
    let e = err("NUM_POINTS 1\nVARS theta_i phi_i theta_s phi_s X Y Z\n");
    assert!(e.message.contains("channels"), "{e}");
    let e = err("NUM_POINTS 1\n1 2 3 4 5\n");
    assert_eq!(e.line, Some(2));
    let e = err("NUM_POINTS 0\nVARS theta_i phi_i theta_s phi_s R G B\n");
    assert!(e.message.contains("no data rows"), "{e}");
    let e = err("NUM_POINTS 1\n");
    assert!(e.message.contains("VARS"), "{e}");
    let e = err(&format!("{head}10 0 10 180 1 2 3\nNUM_POINTS 4\n"));
    assert_eq!((e.line, e.field.as_deref()), (Some(5), Some("NUM_POINTS")));
    // Invalid UTF-8 through the dispatcher: the byte and the line.
    let mut bytes = head.as_bytes().to_vec();
    bytes.extend_from_slice(b"10 0 10 180 1 2 \xff\n");
    let e = formats::read(&bytes, p).expect_err("utf-8");
    assert_eq!((e.line, e.byte), (Some(4), Some(bytes.len() as u64 - 2)));
}

// -------------------------------------------------------------------- CSV

#[test]
fn csv_dispatches_to_the_process_file() {
    let mut s = awkward_samples(Channels::Rgb, 300, 7, true);
    for (i, x) in s.samples.iter_mut().enumerate() {
        x.sigma = Some(vec![0.01, 0.02, i as f64 * 1e-3]);
        x.flags = (i % 3) as u32;
    }
    let data = Data::Samples(s.clone());
    let bytes = formats::write(Format::Csv, &data).expect("csv");
    assert_eq!(formats::detect(&bytes), Some(Format::Csv));
    let meta = formats::csv_meta(&data);
    assert_eq!(
        formats::read_csv_from(&bytes[..], bytes.len() as u64, Some(&meta), None).expect("reads"),
        data
    );
    // The CSV alone: the same samples; their isotropy is only in the sidecar.
    let Data::Samples(alone) = formats::read(&bytes, None).expect("reads") else {
        panic!("samples");
    };
    assert_eq!((alone.samples, alone.isotropic), (s.samples.clone(), false));

    let grid = Grid::isotropic(
        Axis::polar_midpoints(4),
        Axis::full_turn(8),
        Axis::polar_midpoints(4),
    );
    let t = Table::from_brdf(&lafortune(), grid).expect("table");
    let bytes = formats::write(Format::Csv, &Data::Table(t.clone())).expect("csv");
    assert_eq!(formats::detect(&bytes), Some(Format::Csv));
    // On disk with its sidecar, an isotropic table reads back as itself.
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("t.csv");
    formats::write_file(Format::Csv, &Data::Table(t.clone()), &path).expect("writes");
    assert_eq!(std::fs::read(&path).expect("csv"), bytes);
    let Data::Table(back) = formats::read_file(&path).expect("reads") else {
        panic!("a table reads as a table");
    };
    assert_eq!(back, t);
    // Without it, its rows are samples (gonio_dataset recognises their grid).
    std::fs::remove_file(gonio_process::file::sidecar_path(&path)).expect("rm");
    let Data::Samples(rows) = formats::read_file(&path).expect("reads") else {
        panic!("no sidecar: samples");
    };
    assert_eq!(rows.samples.len(), t.grid.len());

    // Tables and samples to ASTM: their samples.
    let astm = formats::write(Format::Astm, &Data::Table(t.clone())).expect("astm");
    let Data::Samples(back) = formats::read(&astm, None).expect("reads") else {
        panic!("ASTM reads as samples");
    };
    assert_eq!(back, Samples::from_table(&t));

    // Errors come back with the file, line and column name.
    let text =
        "# gonio-samples: 1\ntheta_i,phi_i,theta_o,phi_o,R,G,B\n1,2,3,4,5,6,7\n1,2,3,4,5,x,7\n";
    let e = formats::read(text.as_bytes(), Some(Path::new("s.csv"))).expect_err("x");
    assert_eq!(
        (e.format, e.line, e.field.as_deref()),
        (Some(Format::Csv), Some(4), Some("G"))
    );
    assert!(e.to_string().starts_with("s.csv:4: field `G`:"), "{e}");
}

// -------------------------------------------------------------- detection

#[test]
fn detection_picks_the_format_from_content() {
    let (bytes, _) = lafortune_merl();
    assert_eq!(formats::detect(bytes), Some(Format::Merl));
    let Data::Merl(_) = formats::read(bytes, None).expect("MERL") else {
        panic!("MERL reads as MERL");
    };
    let astm = "# x\nFORMAT ASTM\nVARS theta_i phi_i theta_s phi_s value\n";
    assert_eq!(formats::detect(astm.as_bytes()), Some(Format::Astm));
    assert_eq!(
        formats::detect(b"\n  NUM_POINTS 4\n"),
        Some(Format::Astm),
        "NUM_POINTS alone"
    );
    let csv = "# gonio-table: 1\n# grid: isotropic=true phi_i=0:360:1 theta_i=0:10:2 phi_o=0:90:4 theta_o=0:10:2\n\
               theta_i, phi_i, theta_o, phi_o, value\n";
    assert_eq!(formats::detect(csv.as_bytes()), Some(Format::Csv));
    assert_eq!(formats::detect(b""), None);
    assert_eq!(formats::detect(b"\x00\x01\x02binary"), None);
    assert_eq!(formats::detect(b"hello\n1,2,3\n"), None);
    assert_eq!(formats::detect(b"theta,phi,value\n"), None);
    assert_eq!(
        formats::detect(&[90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0]),
        None
    );

    let e = formats::read(b"", Some(Path::new("e.txt"))).expect_err("empty");
    assert_eq!(e.to_string(), "e.txt: empty file");
    let e = formats::read(b"hello\n1,2,3\n", Some(Path::new("j.txt"))).expect_err("junk");
    assert_eq!((e.format, e.line), (None, Some(2)));
    assert!(e.to_string().starts_with("j.txt:2: not a BRDF file"), "{e}");
    let e = formats::read(b"\x00\x01\x02binary", None).expect_err("binary");
    assert!(e.message.contains("not text"), "{e}");

    assert_eq!(Format::from_name("MERL"), Some(Format::Merl));
    assert_eq!(Format::from_name("astm"), Some(Format::Astm));
    assert_eq!(
        Format::from_extension(Path::new("a/b.binary")),
        Some(Format::Merl)
    );
    assert_eq!(
        Format::from_extension(Path::new("b.CSV")),
        Some(Format::Csv)
    );
    assert_eq!(Format::from_extension(Path::new("b.txt")), None);
}

#[test]
fn a_wrong_csv_header_names_the_columns_expected() {
    let e = formats::read(
        b"# mine\ntheta,phi,theta_o,phi_o,value\n0,0,0,0,1\n",
        Some(Path::new("w.csv")),
    )
    .expect_err("header");
    assert_eq!((e.format, e.line), (Some(Format::Csv), Some(2)));
    assert_eq!(
        e.to_string(),
        format!(
            "w.csv:2: not a CSV header Gonio reads: expected the columns {}; found \
             \"theta,phi,theta_o,phi_o,value\"",
            gonio_process::file::EXPECTED_COLUMNS
        )
    );
    // The right angles and a wrong channel column: the CSV reader says which.
    let e =
        formats::read(b"theta_i,phi_i,theta_o,phi_o,red\n0,0,0,0,1\n", None).expect_err("channel");
    assert_eq!((e.format, e.line), (Some(Format::Csv), Some(1)));
    assert!(
        e.message
            .contains("expected the columns theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg, then"),
        "{e}"
    );
    // An ASTM keyword line with a comma after a space is not taken for a CSV header.
    let e = formats::read(b"SOURCE lab, 2020, x, y\n1 2 3\n", None).expect_err("junk");
    assert_eq!((e.format, e.line), (None, Some(1)));
    assert!(e.message.starts_with("not a BRDF file Gonio reads"), "{e}");
}

#[test]
fn a_byte_order_mark_is_ignored_by_detection_and_readers() {
    let s = awkward_samples(Channels::Rgb, 6, 5, false);
    let csv = gonio_process::file::write_samples(&s);
    let astm = write_astm(&s);
    for (text, format) in [(csv, Format::Csv), (astm, Format::Astm)] {
        let with = format!("\u{feff}{text}");
        assert_eq!(formats::detect(with.as_bytes()), Some(format));
        assert_eq!(
            formats::read(with.as_bytes(), None).expect("BOM"),
            formats::read(text.as_bytes(), None).expect("plain"),
            "{format:?}"
        );
    }
}

#[test]
fn files_on_disk_name_themselves() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let s = awkward_samples(Channels::Rgb, 20, 3, true);
    let path = dir.join("s.astm");
    formats::write_file(Format::Astm, &Data::Samples(s.clone()), &path).expect("writes");
    assert_eq!(formats::read_file(&path).expect("reads"), Data::Samples(s));
    let missing = dir.join("missing.binary");
    let e = formats::read_file(&missing).expect_err("missing");
    assert!(
        e.to_string().starts_with(&missing.display().to_string()),
        "{e}"
    );
    // A directory or a device is refused without being read (/dev/zero never ends).
    let e = formats::read_file(dir).expect_err("a directory");
    assert!(
        e.to_string().contains("a directory, not a regular file"),
        "{e}"
    );
    #[cfg(unix)]
    {
        let e = formats::read_file(Path::new("/dev/zero")).expect_err("a device");
        assert_eq!(
            e.to_string(),
            "/dev/zero: cannot read: a character device, not a regular file (Gonio reads its \
             inputs from regular files only)"
        );
    }
}

// ------------------------------------------------------------ fuzz bodies

#[test]
fn fuzz_bodies_accept_the_real_files() {
    let s = awkward_samples(Channels::Rgb, 50, 11, false);
    fuzz::astm_read(write_astm(&s).as_bytes());
    fuzz::csv_read(gonio_process::file::write_samples(&s).as_bytes());
    // Format 1 with its `# isotropic:` line: the isotropy survives the round trip
    // through the sidecar.
    fuzz::csv_read(b"# isotropic: true\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,20,180,0.25\n");
    let grid = Grid::isotropic(
        Axis::polar_midpoints(3),
        Axis::full_turn(4),
        Axis::polar_midpoints(3),
    );
    let t = Table::from_brdf(&lafortune(), grid).expect("table");
    fuzz::csv_read(gonio_process::file::write_table(&t).as_bytes());
    let (bytes, _) = lafortune_merl();
    fuzz::merl_read(&bytes[..4096]);
    fuzz::merl_read(&bytes[..bytes.len() - 1]);
}

fn mutate(text: &str, at: usize, with: &str) -> String {
    let mut cut = at.min(text.len());
    while !text.is_char_boundary(cut) {
        cut -= 1;
    }
    let mut end = (cut + 1).min(text.len());
    while !text.is_char_boundary(end) {
        end += 1;
    }
    format!("{}{with}{}", &text[..cut], &text[end..])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Hostile numbers, lost and repeated lines, a BOM (`gonio_core::fuzz::mutate`)
    /// in files Gonio wrote: read as any format, never a panic.
    #[test]
    fn written_files_with_hostile_changes_never_panic(
        seeds in prop::collection::vec(any::<u64>(), 1..4),
        seed in 0u64..100,
    ) {
        let s = awkward_samples(Channels::Rgb, 4, seed + 1, seed % 2 == 0);
        for text in [write_astm(&s), gonio_process::file::write_samples(&s)] {
            let bad = gonio_core::fuzz::mutate(&text, &seeds);
            fuzz::astm_read(bad.as_bytes());
            fuzz::csv_read(bad.as_bytes());
            if let Err(e) = formats::read(bad.as_bytes(), None) {
                prop_assert!(e.line.is_none_or(|l| l >= 1), "{e}");
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn fuzz_bodies_never_panic_on_bytes(data in proptest::collection::vec(any::<u8>(), 0..400)) {
        fuzz::merl_read(&data);
        fuzz::astm_read(&data);
        fuzz::csv_read(&data);
    }

    #[test]
    fn fuzz_bodies_never_panic_on_damaged_files(
        at in 0usize..400,
        with in prop::sample::select(vec!["", "x", ",", " ", "\n", "-", "9", "e", "#", "NaN", "1e400", "é"]),
        seed in 0u64..1000,
    ) {
        let s = awkward_samples(Channels::Rgb, 4, seed + 1, seed % 2 == 0);
        let astm = mutate(&write_astm(&s), at, with);
        fuzz::astm_read(astm.as_bytes());
        let _ = formats::read(astm.as_bytes(), None);
        let csv = mutate(&gonio_process::file::write_samples(&s), at, with);
        fuzz::csv_read(csv.as_bytes());
        let _ = formats::read(csv.as_bytes(), None);
    }
}
