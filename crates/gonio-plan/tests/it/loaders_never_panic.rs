//! A plan file of any content is a plan or a located error, never a panic: arbitrary
//! text, and the shipped plans with hostile changes (`gonio_core::fuzz::mutate`: a
//! number made `nan`, `inf`, `-0`, `1e308` or a huge integer, a line deleted or
//! repeated, a BOM). What parses is then expanded and checked against the simulated
//! instrument, which must not panic either.

use crate::common;

use gonio_core::fuzz::mutate;
use gonio_plan::Plan;
use proptest::prelude::*;

const PLANS: &[(&str, &str)] = &[
    (
        "plan-hemisphere.toml",
        include_str!("../../../../config/plan-hemisphere.toml"),
    ),
    (
        "plan-in-plane.toml",
        include_str!("../../../../config/plan-in-plane.toml"),
    ),
    (
        "plan-list.toml",
        include_str!("../../../../config/plan-list.toml"),
    ),
    (
        "plan-spectral.toml",
        include_str!("../../../../config/plan-spectral.toml"),
    ),
];

/// Reads `text` as a plan anchored in `config/` (so a list plan finds its CSV) and,
/// if it reads, expands and prepares it with the ordering off (its wall-time budget
/// is no part of this property).
fn load(text: &str, mech: &gonio_plan::Mechanics) -> Result<(), String> {
    let path = common::root().join("config/fuzzed-plan.toml");
    let mut plan = Plan::from_toml(text, Some(&path)).map_err(|e| {
        assert!(e.line.is_none_or(|l| l >= 1), "{e}");
        e.to_string()
    })?;
    plan.order.optimise = false;
    let pairs = plan.pairs().map_err(|e| e.to_string())?;
    assert!(pairs.len() <= gonio_plan::plan::MAX_POINTS);
    // The check of every pair is linear; keep the property's cases quick.
    if pairs.len() <= 20_000 {
        gonio_plan::prepare(mech, 1.0, &plan).map_err(|e| e.to_string())?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn plans_from_any_text(text in any::<String>()) {
        let _ = load(&text, &common::mechanics());
    }

    #[test]
    fn plans_from_plan_like_text(
        text in "(name = \"p\"\n)?\\[points\\]\nkind = \"(grid|isotropic|in-plane|list)\"\n\
                 ((theta_i|theta_o|phi_i|phi_o|delta_phi|file) = \
                 (\\[[-0-9e., ]{0,12}\\]|[-0-9e.]{1,6}|\\{ ?(from|to|step) = [-0-9.]{1,4} ?\\}|\"[a-z.]{0,8}\")\n){0,5}",
    ) {
        let _ = load(&text, &common::mechanics());
    }

    /// Wavelengths of any form, either loop order, on a monochromator of any
    /// timing within its ranges.
    #[test]
    fn spectral_plans_from_plan_like_text(
        text in "wavelengths = (\\[[-0-9e., ]{0,16}\\]|[-0-9e.]{1,6}|\\{ ?from = [0-9.]{1,4}, to = [0-9.]{1,4}, step = [-0-9.e]{1,4} ?\\})\n\
                 (channels = \\[\"R\"\\]\n)?(\\[spectral\\]\ninner = \"(auto|wavelength|geometry|up)\"\n)?\
                 \\[points\\]\nkind = \"in-plane\"\ntheta_i = \\[30\\]\ntheta_o = \\[10, 50\\]\n\
                 (\\[drift\\]\nevery = [0-3]\n)?(\\[calibration\\]\ndark = true\nrepeat_at_end = true\n)?",
        slew in 1e-3f64..1e6,
        settle in 0f64..3600.0,
        backlash in 0f64..1000.0,
        change in 0f64..3600.0,
        at in prop::collection::vec(1f64..1e5, 0..4),
    ) {
        let mut at = at;
        at.sort_by(f64::total_cmp);
        at.dedup();
        let timing = gonio_core::spectral_timing::WavelengthTiming::monochromator(slew, settle)
            .with_backlash(backlash)
            .with_order_filter(change, &at)
            .with_grating(change, &at);
        prop_assert_eq!(timing.validate("wavelength"), Ok(()));
        let _ = load(&text, &common::mechanics().with_wavelength(timing));
    }

    #[test]
    fn shipped_plans_damaged(
        file in prop::sample::select(PLANS),
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        let _ = load(&mutate(file.1, &seeds), &common::mechanics());
    }
}

#[test]
fn shipped_plans_read_with_a_byte_order_mark() {
    let mech = common::mechanics();
    for (name, text) in PLANS {
        let plain = Plan::from_toml(text, None).expect(name);
        let bom = Plan::from_toml(&format!("\u{feff}{text}"), None).expect(name);
        assert_eq!(plain, bom, "{name}");
        load(&format!("\u{feff}{text}"), &mech).expect(name);
    }
}
