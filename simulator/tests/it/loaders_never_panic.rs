//! A simulator config of any content is a config or a located error, never a panic:
//! arbitrary text, and the shipped config with each kind of sample (the embedded
//! model, a model file, a table, a microgeometry surface) and hostile changes
//! (`gonio_core::fuzz::mutate`: a number made `nan`, `inf`, `-0`, `1e308` or a huge
//! integer, a line deleted or repeated, a BOM). An accepted config loads its sample
//! and builds an instrument that answers a move, a position query and a reading.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use gonio_brdf::Model;
use gonio_core::fuzz::mutate;
use gonio_process::{Grid, Table};
use gonio_sim::{SampleKind, SimClock, SimConfig, SimInstrument};
use proptest::prelude::*;

const BLUE_PAINT: &str = include_str!("../../../config/models/blue-paint-550nm.toml");

/// The shipped config's `[sample]` table, which the cases replace.
const SAMPLE: &str = "[sample]                       # the embedded blue paint when no model is given\n# model = \"models/blue-paint-550nm.toml\"\n";

/// One sample of each kind, relative to the files of [`dir`].
const SAMPLES: &[&str] = &[
    SAMPLE,
    "[sample]\nmodel = \"paint.toml\"\nchannel = \"550nm\"\n",
    "[sample]\ntable = \"paint.csv\"\n",
    "[sample.micro]\nsurface = \"surface.toml\"\ngrid = [30, 90]\nrays = 8\nseed = 5\n",
];

/// A tiny surface: quick to trace with a few rays.
const SURFACE: &str = "channels = [\"value\"]\n[surface]\nkind = \"gaussian\"\nsize = [8, 8]\n\
                       rms_height = 0.5\ncorrelation_length = 2.0\nseed = 3\nmaterial = \"w\"\n\
                       [materials.w]\nkind = \"lambert\"\nalbedo = [0.8]\n";

/// The directory the cases' configs are read from: the paint as a model file and as
/// a table, and the surface.
fn dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = tempfile::tempdir().expect("temp dir");
        let paint = Model::from_toml(BLUE_PAINT, None).expect("paint");
        let table = Table::from_brdf(&paint, Grid::hemisphere(3, 4)).expect("table");
        std::fs::write(
            d.path().join("paint.csv"),
            gonio_process::file::write_table(&table),
        )
        .expect("write");
        std::fs::write(d.path().join("paint.toml"), BLUE_PAINT).expect("write");
        std::fs::write(d.path().join("surface.toml"), SURFACE).expect("write");
        d
    })
    .path()
}

fn config_path() -> PathBuf {
    dir().join("sim.toml")
}

fn with_sample(sample: &str) -> String {
    gonio_sim::config::DEFAULT_SIM.replace(SAMPLE, sample)
}

fn load(text: &str) -> Result<(), TestCaseError> {
    let cfg = match SimConfig::from_toml(text, Some(&config_path())) {
        Ok(c) => c,
        Err(e) => {
            prop_assert!(e.line.is_none_or(|l| l >= 1), "{e}");
            return Ok(());
        }
    };
    // Tracing time grows with the rays: no part of this property.
    if cfg.sample_kind() == SampleKind::Micro
        && cfg.sample.micro.as_ref().is_some_and(|m| m.rays > 64)
    {
        return Ok(());
    }
    let addrs = cfg.role_addresses();
    prop_assert!(addrs.is_ok(), "validated: {:?}", addrs);
    let Ok(mut sim) = SimInstrument::new(&cfg, SimClock::driven(0.0)) else {
        return Ok(());
    };
    let a = addrs.unwrap_or_default()[0];
    let _ = sim.motion_bytes(format!("{a}OR\r\n").as_bytes());
    sim.clock().advance(Duration::from_secs(100));
    let _ = sim.motion_bytes(format!("{a}PA10\r\n").as_bytes());
    sim.clock().advance(Duration::from_secs(100));
    let _ = sim.motion_bytes(format!("{a}TP\r\n{a}TS\r\n").as_bytes());
    let _ = sim.lockin_bytes(b"*IDN?\nOUTX 0\nSNAP?1,2\n");
    sim.clock().advance(Duration::from_secs(1));
    let _ = sim.lockin_bytes(b"SNAP?1,2\nLIAS?\n");
    let _ = sim.signal(sim.clock().seconds());
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn sim_configs_from_any_text(text in any::<String>()) {
        load(&text)?;
    }

    #[test]
    fn shipped_config_damaged(
        sample in prop::sample::select(SAMPLES),
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        load(&mutate(&with_sample(sample), &seeds))?;
    }
}

#[test]
fn every_sample_kind_loads_with_and_without_a_byte_order_mark() {
    for sample in SAMPLES {
        let text = with_sample(sample);
        assert_ne!(
            text == gonio_sim::config::DEFAULT_SIM,
            *sample != SAMPLE,
            "{sample}"
        );
        for t in [text.clone(), format!("\u{feff}{text}")] {
            let cfg = SimConfig::from_toml(&t, Some(&config_path())).expect(sample);
            let (b, channel) = cfg.load_sample().expect(sample);
            assert_eq!((b.channels().len(), channel), (1, 0), "{sample}");
            load(&t).expect(sample);
        }
    }
}

/// Found by the `sim_config` fuzz target: a controller's `start_position = nan` was
/// accepted and panicked in the first move. Every number of a controller must be
/// finite, and the error names it.
#[test]
fn a_controller_number_that_is_not_finite_is_refused_by_name() {
    let text = gonio_sim::config::DEFAULT_SIM;
    let line = text
        .lines()
        .position(|l| l.starts_with("start_position = 12.5"))
        .expect("the first controller's start")
        + 1;
    for bad in ["nan", "inf", "-inf"] {
        let t = text.replacen(
            "start_position = 12.5",
            &format!("start_position = {bad}"),
            1,
        );
        let e = SimConfig::from_toml(&t, None).expect_err(bad);
        assert_eq!(
            e.to_string(),
            format!(
                "<sim config>:{line}:18: field `controllers[0].start_position`: must be \
                 finite, got {}",
                bad.replace("nan", "NaN")
            )
        );
    }
}
