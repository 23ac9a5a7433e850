//! Spectral data in the long-form CSV (a row per pair per wavelength) are recognised
//! from their content and opened into the same samples or table, bit for bit.

use gonio_brdf::Model;
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, SphericalDeg};
use gonio_dataset::{Dataset, Kind, OpenOptions, detect, open};
use gonio_io::formats::{self, Data, Format};
use gonio_process::{Grid, Sample, Samples, Table};

fn scattered() -> Samples {
    let pair = |ti: f64, to: f64, po: f64| PairDeg {
        incident: SphericalDeg::new(ti, 0.0),
        outgoing: SphericalDeg::new(to, po),
    };
    let sample = |p: PairDeg, k: f64| Sample {
        pair: p,
        value: vec![0.1 * k, 0.2 * k + 1e-17, 1.0 / (3.0 * k)],
        sigma: Some(vec![1e-3 * k, 7e-4, 3.3e-4 / k]),
        flags: if k > 2.0 { 2 } else { 0 },
    };
    Samples {
        channels: Channels::wavelengths(&[400.0, 555.5, 700.0]).expect("valid"),
        samples: vec![
            sample(pair(10.0, 20.0, 160.0), 1.0),
            sample(pair(10.0, 35.0, 170.0), 2.0),
            sample(pair(40.0, 50.0, 30.0), 3.0),
        ],
        isotropic: true,
    }
}

#[test]
fn long_form_samples_open_as_the_same_samples() {
    let dir = tempfile::tempdir().expect("temp dir");
    let s = scattered();
    // A name that says nothing of the content.
    let path = dir.path().join("data.txt");
    formats::write_file(Format::CsvLong, &Data::Samples(s.clone()), &path).expect("writes");
    let head = std::fs::read(&path).expect("read");
    assert_eq!(formats::detect(&head), Some(Format::CsvLong));
    assert_eq!(detect(&head), Some(Kind::Csv));
    let opened = open(&path, &OpenOptions::default()).expect("opens");
    assert_eq!(opened.kind, Kind::Csv);
    let Dataset::Samples(back) = opened.data else {
        panic!("scattered samples stay samples")
    };
    // Values, σ, flags and the isotropy (from the sidecar), bit for bit.
    assert_eq!(back, s);
    // Without the sidecar the rows still read; only the isotropy is not known.
    std::fs::remove_file(format!("{}.json", path.display())).expect("sidecar");
    let Dataset::Samples(bare) = open(&path, &OpenOptions::default()).expect("opens").data else {
        panic!("samples")
    };
    assert_eq!(bare.samples, s.samples);
    assert!(!bare.isotropic);
}

#[test]
fn a_spectral_table_in_the_long_form_opens_as_the_same_table() {
    let dir = tempfile::tempdir().expect("temp dir");
    let m = Model::from_toml(
        "kind = \"lambert\"\nchannels = [\"450nm\", \"550nm\", \"650nm\"]\n\
         rho = [0.2, 0.5, 0.8]\n",
        None,
    )
    .expect("model");
    let t = Table::from_brdf(&m, Grid::hemisphere_isotropic(6, 12)).expect("table");
    let path = dir.path().join("t.csv");
    formats::write_file(Format::CsvLong, &Data::Table(t.clone()), &path).expect("writes");
    let Dataset::Table(back) = open(&path, &OpenOptions::default()).expect("opens").data else {
        panic!("the nodes of a grid open as its table")
    };
    assert_eq!(back.channels, t.channels);
    assert!(back.grid.isotropic);
    // The same nodes with the same values: compared as samples, bit for bit.
    assert_eq!(Samples::from_table(&back), Samples::from_table(&t));
}

#[test]
fn a_broken_long_form_is_refused_with_its_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("bad.csv");
    std::fs::write(
        &path,
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,f_r_per_sr\n\
         10,0,20,180,450,0.1\n10,0,20,180,550,0.2\n10,0,30,180,550,0.3\n",
    )
    .expect("write");
    let e = open(&path, &OpenOptions::default()).unwrap_err();
    assert!(e.is_bad_input());
    let msg = e.to_string();
    assert!(
        msg.starts_with(&format!("{}:4: field `wavelength_nm`", path.display())),
        "{msg}"
    );
    assert!(msg.contains("no row at 450 nm"), "{msg}");
}
