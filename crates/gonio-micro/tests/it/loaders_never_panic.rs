//! A surface file of any content is a sample or a located error, never a panic:
//! arbitrary text, surface-like text of every kind, and the shipped surfaces with
//! hostile changes (`gonio_core::fuzz::mutate`: a number made `nan`, `inf`, `-0`,
//! `1e308` or a huge integer, a line deleted or repeated, a BOM).

use std::path::PathBuf;

use gonio_core::fuzz::mutate;
use gonio_micro::Sample;
use proptest::prelude::*;

const SURFACES: &[&str] = &[
    include_str!("../../../../config/micro-brushed-aluminium.toml"),
    include_str!("../../../../config/micro-gaussian-gold.toml"),
    include_str!("../../../../config/micro-sawtooth-deyoung.toml"),
];

/// A surface file named in `config/`, so relative model and height-map paths resolve
/// there.
fn path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/fuzzed-surface.toml")
}

fn load(text: &str) {
    if let Err(e) = Sample::from_toml(text, Some(&path())) {
        assert!(!e.to_string().is_empty());
    }
}

proptest! {
    // Each shipped Gaussian surface is generated in full (512 × 512): few cases.
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn surfaces_from_any_text(text in any::<String>()) {
        load(&text);
    }

    #[test]
    fn surfaces_from_surface_like_text(
        text in "channels = \\[(\"(R|G|B|value|550nm)\",? ?){0,3}\\]\n\\[surface\\]\n\
                 kind = \"(gaussian|sawtooth|v-grooves|cylinders|height-map|x)\"\n\
                 ((size|spacing|rms_height|correlation_length|seed|period|angles_deg|radius|\
                 cells_per_period|height_scale|orientation_deg) = \
                 (\\[[-0-9e., ]{0,10}\\]|[-0-9e.]{1,5})\n){0,6}\
                 (material = \"m\"\n)?(faces = \\[\"m\", \"m\"\\]\n)?(file = \"[a-z./-]{0,20}\"\n)?\
                 \\[materials.m\\]\nkind = \"(mirror|conductor|dielectric|lambert|model)\"\n\
                 ((n|k|eta|albedo|reflectance) = \\[[-0-9e., ]{0,10}\\]\n){0,3}",
    ) {
        load(&text);
    }

    #[test]
    fn shipped_surfaces_damaged(
        file in prop::sample::select(SURFACES),
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        load(&mutate(file, &seeds));
    }
}
