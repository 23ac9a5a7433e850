//! A model file of any content is a model or a located error, never a panic:
//! arbitrary text, model-like text of every kind, and the shipped models with hostile
//! changes (`gonio_core::fuzz::mutate`: a number made `nan`, `inf`, `-0`, `1e308` or
//! a huge integer, a line deleted or repeated, a BOM). A model that is accepted
//! evaluates without panicking and writes a file that reads back to it.

use gonio_brdf::{Brdf, Model};
use gonio_core::fuzz::mutate;
use gonio_core::{Dir, SphericalDeg};
use proptest::prelude::*;

const MODELS: &[&str] = &[
    include_str!("../../../../config/models/blinn-phong-plastic.toml"),
    include_str!("../../../../config/models/blue-paint-550nm.toml"),
    include_str!("../../../../config/models/conventions-example.toml"),
    include_str!("../../../../config/models/cook-torrance-gold.toml"),
    include_str!("../../../../config/models/lafortune-fig9.toml"),
    include_str!("../../../../config/models/minnaert-matte.toml"),
    include_str!("../../../../config/models/oren-nayar-plaster.toml"),
    include_str!("../../../../config/models/phong-fig7.toml"),
    include_str!("../../../../config/models/phong-shading.toml"),
    include_str!("../../../../config/models/ward-brushed.toml"),
    include_str!("../../../../config/models/white-reference.toml"),
];

fn dir(theta: f64, phi: f64) -> Dir {
    Dir::from(SphericalDeg::new(theta, phi))
}

fn load(text: &str) -> Result<(), TestCaseError> {
    let m = match Model::from_toml(text, None) {
        Ok(m) => m,
        Err(e) => {
            prop_assert!(
                e.line
                    .is_none_or(|l| l >= 1 && l <= text.lines().count() + 1),
                "{e}"
            );
            return Ok(());
        }
    };
    let mut out = vec![0.0; m.channels().len()];
    for (wi, wo) in [
        (dir(0.0, 0.0), dir(0.0, 0.0)),
        (dir(30.0, 0.0), dir(30.0, 180.0)),
        (dir(89.9, 10.0), dir(60.0, 250.0)),
        (dir(90.0, 0.0), dir(90.0, 180.0)),
    ] {
        m.eval(wi, wo, &mut out);
        m.mirror(wi, &mut out);
    }
    let back = Model::from_toml(&m.to_toml(), None);
    prop_assert_eq!(back.as_ref(), Ok(&m));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn models_from_any_text(text in any::<String>()) {
        load(&text)?;
    }

    #[test]
    fn models_from_model_like_text(
        text in "kind = \"(lambert|phong|blinn-phong|ward|cook-torrance|lafortune|minnaert|oren-nayar)\"\n\
                 channels = \\[(\"(R|G|B|value|550nm)\",? ?){0,3}\\]\n\
                 ((rho|rho_s|n|alpha|alpha_x|alpha_y|f0|sigma_deg) = \\[[-0-9e., ]{0,12}\\]\n){0,4}\
                 (distribution = \"(ggx|beckmann|x)\"\n)?(\\[(diffuse|mirror)\\]\n(rho|rm|n) = \\[[-0-9e., ]{0,8}\\]\n)?\
                 (\\[\\[lobes\\]\\]\n((cx|cy|cz|n) = \\[[-0-9e., ]{0,8}\\]\n){0,4}){0,2}",
    ) {
        load(&text)?;
    }

    #[test]
    fn shipped_models_damaged(
        file in prop::sample::select(MODELS),
        seeds in prop::collection::vec(any::<u64>(), 1..4),
    ) {
        load(&mutate(file, &seeds))?;
    }
}
