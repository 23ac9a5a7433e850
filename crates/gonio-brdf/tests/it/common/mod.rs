//! Shared fixtures for the model tests: one instance of every kind, anisotropic and
//! multi-channel ones included, and a seeded random source.

#![allow(dead_code)]

use gonio_brdf::Model;
use gonio_core::{Dir, SphericalDeg};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The blue paint of Lafortune et al. 1997, Table 1, at 550 nm.
pub const TABLE1: &str = include_str!("../../../../../config/models/blue-paint-550nm.toml");

/// Every kind of model, with the name a failing test prints.
pub fn zoo() -> Vec<(&'static str, Model)> {
    let src: &[(&str, &str)] = &[
        (
            "lambert",
            r#"kind = "lambert"
channels = ["R", "G", "B"]
rho = [0.2, 0.5, 0.8]"#,
        ),
        (
            "minnaert",
            r#"kind = "minnaert"
channels = ["value"]
rho = [0.7]
n = [0.5]"#,
        ),
        (
            "phong",
            r#"kind = "phong"
channels = ["value"]
rho_s = [0.2]
n = [20]
[diffuse]
rho = [0.8]"#,
        ),
        (
            "phong-mirror",
            r#"kind = "phong"
channels = ["value"]
rho_s = [0.2]
n = [20]
normalization = "power"
[diffuse]
rho = [0.4]
n = [0.5]
[mirror]
rm = [0.4]"#,
        ),
        (
            "phong-shading",
            r#"kind = "phong"
channels = ["value"]
rho_s = [0.3]
n = [12]
shading = true
[diffuse]
rho = [0.5]"#,
        ),
        (
            "blinn-phong",
            r#"kind = "blinn-phong"
channels = ["R", "G", "B"]
rho_s = [0.3, 0.3, 0.3]
n = [40, 60, 80]
[diffuse]
rho = [0.1, 0.2, 0.3]"#,
        ),
        (
            "ward-iso",
            r#"kind = "ward"
channels = ["value"]
rho_s = [0.05]
alpha = [0.15]
[diffuse]
rho = [0.3]"#,
        ),
        (
            "ward-aniso",
            r#"kind = "ward"
channels = ["value"]
rho_s = [0.1]
alpha_x = [0.08]
alpha_y = [0.3]"#,
        ),
        (
            "ct-beckmann",
            r#"kind = "cook-torrance"
channels = ["R", "G", "B"]
distribution = "beckmann"
f0 = [0.95, 0.64, 0.54]
alpha = [0.3, 0.3, 0.3]"#,
        ),
        (
            "ct-ggx-aniso",
            r#"kind = "cook-torrance"
channels = ["value"]
distribution = "ggx"
f0 = [0.04]
alpha_x = [0.1]
alpha_y = [0.4]
[diffuse]
rho = [0.5]"#,
        ),
        (
            "ct-ggx-rough",
            r#"kind = "cook-torrance"
channels = ["value"]
distribution = "ggx"
f0 = [1.0]
alpha = [0.8]"#,
        ),
        (
            "oren-nayar",
            r#"kind = "oren-nayar"
channels = ["value"]
rho = [0.8]
sigma_deg = [30]"#,
        ),
        (
            "oren-nayar-q",
            r#"kind = "oren-nayar"
channels = ["value"]
rho = [0.8]
sigma_deg = [20]
variant = "qualitative""#,
        ),
        ("lafortune-table1", TABLE1),
        (
            "lafortune-aniso-matrix",
            r#"kind = "lafortune"
channels = ["R", "G", "B"]
[[lobes]]
cx = [-0.9, -0.8, -0.7]
cy = [-0.6, -0.6, -0.6]
cz = [0.8, 0.8, 0.75]
n = [15, 20, 25]
[[lobes]]
m = [[[0.3, 0.1, 0.0], [0.1, 0.2, 0.0], [0.0, 0.0, 0.6]],
     [[0.3, 0.1, 0.0], [0.1, 0.2, 0.0], [0.0, 0.0, 0.6]],
     [[0.3, 0.1, 0.0], [0.1, 0.2, 0.0], [0.0, 0.0, 0.6]]]
n = [3, 3, 3]
[diffuse]
rho = [0.1, 0.2, 0.3]
n = [0.3, 0.3, 0.3]
[mirror]
rm = [0.2, 0.3, 0.4]"#,
        ),
        // A lobe whose matrix couples z with x and y: tilted off the normal's plane.
        (
            "lafortune-tilted",
            r#"kind = "lafortune"
channels = ["value"]
[[lobes]]
m = [[[-0.8, 0.05, 0.15], [0.05, -0.7, -0.1], [0.15, -0.1, 0.9]]]
n = [12]
[diffuse]
rho = [0.2]"#,
        ),
    ];
    src.iter()
        .map(|(name, text)| {
            let m = Model::from_toml(text, None).unwrap_or_else(|e| panic!("{name}: {e}"));
            (*name, m)
        })
        .collect()
}

/// A seeded generator: every random test is reproducible.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A direction uniform over the upper hemisphere.
pub fn random_dir(r: &mut impl Rng) -> Dir {
    let z: f64 = r.random::<f64>();
    let phi: f64 = r.random::<f64>() * std::f64::consts::TAU;
    let s = (1.0 - z * z).sqrt();
    Dir::new(gonio_core::Vec3::new(s * phi.cos(), s * phi.sin(), z)).expect("unit")
}

/// `SphericalDeg` shorthand.
pub fn deg(theta: f64, phi: f64) -> Dir {
    Dir::from(SphericalDeg::new(theta, phi))
}
