//! The readers of this crate — the directions file and the strict TOML layer every
//! config goes through — take any text to a value or a located error, never a panic:
//! arbitrary strings, and the shipped files with hostile changes
//! (`gonio_core::fuzz::mutate`).

use std::collections::BTreeMap;

use gonio_core::dirfile;
use gonio_core::fuzz::mutate;
use gonio_core::tomlfile::{self, FileError, Tagged};
use proptest::prelude::*;
use serde::{Deserialize, Deserializer};

const DIRS: &str = include_str!("../../../../config/dirs-example.csv");

/// Every TOML file in `config/`, as the texts to damage.
const TOML: &[&str] = &[
    include_str!("../../../../config/instrument-example.toml"),
    include_str!("../../../../config/instrument-sim.toml"),
    include_str!("../../../../config/micro-brushed-aluminium.toml"),
    include_str!("../../../../config/micro-gaussian-gold.toml"),
    include_str!("../../../../config/micro-sawtooth-deyoung.toml"),
    include_str!("../../../../config/plan-hemisphere.toml"),
    include_str!("../../../../config/plan-in-plane.toml"),
    include_str!("../../../../config/plan-list.toml"),
    include_str!("../../../../config/sim-example.toml"),
    include_str!("../../../../config/models/lafortune-fig9.toml"),
];

/// A document that takes every shape of value, so that any TOML reaches some
/// deserializer: numbers of each width, lists, nested tables, a tagged table.
#[derive(Debug, Deserialize)]
#[allow(dead_code)]
struct Anything {
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    repeats: Option<u32>,
    #[serde(default)]
    seed: Option<u64>,
    #[serde(default)]
    step: Option<f64>,
    #[serde(default)]
    list: Option<Vec<f64>>,
    #[serde(default)]
    points: Option<Shape>,
    #[serde(default)]
    surface: Option<Shape>,
    #[serde(default)]
    tables: BTreeMap<String, BTreeMap<String, toml::Value>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct Fields {
    #[serde(default)]
    theta_i: Option<Vec<f64>>,
    #[serde(default)]
    size: Option<[usize; 2]>,
    #[serde(default)]
    file: Option<std::path::PathBuf>,
}

#[derive(Debug)]
#[allow(dead_code)]
enum Shape {
    A(Fields),
}

impl<'de> Deserialize<'de> for Shape {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let t = Tagged::read(d, &["in-plane", "gaussian"])?;
        match t.kind() {
            "in-plane" | "gaussian" => t.fields().map(Shape::A),
            _ => Err(t.unknown_kind()),
        }
    }
}

/// An error's place lies inside the text it was read from, and it displays.
fn check_place(text: &str, e: &FileError) {
    let text = gonio_core::text::strip_bom(text);
    if let Some(line) = e.line {
        assert!(line >= 1 && line <= text.lines().count().max(1) + 1, "{e}");
    }
    if let Some(c) = e.column {
        assert!(c >= 1, "{e}");
    }
    assert!(!e.to_string().is_empty());
}

fn toml_any(text: &str) {
    match tomlfile::parse::<Anything>("test file", text, None, |_| Ok(())) {
        Ok(_) => {}
        Err(e) => check_place(text, &e),
    }
    // Every path a validation might name is located somewhere, or nowhere.
    for path in [
        "points.theta_o",
        "a[0].b",
        "x[",
        "[]",
        "...",
        "z[999999999999999999999]",
    ] {
        if let Some(s) = tomlfile::span_of(text, path) {
            assert!(s.start <= s.end && s.end <= text.len(), "{path}: {s:?}");
        }
        let _ = tomlfile::FileError::at_field("test file", None, text, path.into(), "m");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn directions_files_from_any_text(text in any::<String>()) {
        let _ = dirfile::read_pairs(&text);
    }

    #[test]
    fn directions_files_damaged(seeds in prop::collection::vec(any::<u64>(), 1..4)) {
        let text = mutate(DIRS, &seeds);
        match dirfile::read_pairs(&text) {
            Ok(pairs) => {
                for p in pairs {
                    let t = [p.incident.theta_deg, p.outgoing.theta_deg];
                    prop_assert!(t.iter().all(|t| (0.0..=90.0).contains(t)), "{p:?}");
                    prop_assert!(p.incident.phi_deg.is_finite() && p.outgoing.phi_deg.is_finite());
                }
            }
            Err(e) => prop_assert!(e.line >= 1, "{e}"),
        }
    }

    #[test]
    fn toml_from_any_text(text in any::<String>()) {
        toml_any(&text);
    }

    #[test]
    fn toml_from_tomlish_text(text in "[a-z_\\[\\]=\\.\"{},0-9 \n#-]{0,120}") {
        toml_any(&text);
    }

    #[test]
    fn toml_configs_damaged(
        file in prop::sample::select(TOML),
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        toml_any(&mutate(file, &seeds));
    }
}

#[test]
fn every_shipped_file_reads_with_a_byte_order_mark() {
    let with = format!("\u{feff}{DIRS}");
    assert_eq!(
        dirfile::read_pairs(&with).expect("BOM"),
        dirfile::read_pairs(DIRS).expect("plain")
    );
    for text in TOML {
        let plain: toml::Table = tomlfile::parse("f", text, None, |_| Ok(())).expect("plain");
        let bom: toml::Table =
            tomlfile::parse("f", &format!("\u{feff}{text}"), None, |_| Ok(())).expect("BOM");
        assert_eq!(plain, bom);
    }
}
