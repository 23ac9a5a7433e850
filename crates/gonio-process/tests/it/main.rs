//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod albedo_quadrature;
mod columns_reader;
mod floors;
mod hemisphere;
mod interpolation;
mod limits;
mod loaders_never_panic;
mod properties;
mod samples;
mod separability;
mod sh;

/// One forward lobe of Table 1 with its Lambert term in R, G and B: the RGB paint the
/// column reader's, the samples' and the properties' tests tabulate.
const RGB_PAINT: &str = r#"
kind = "lafortune"
channels = ["R", "G", "B"]
[diffuse]
rho = [0.3094, 0.39667, 0.70837]
[[lobes]]
cx = [-0.870567, -0.857255, -0.670982]
cz = [0.803624, 0.774290, 0.586674]
n  = [21.820103, 18.597755, 7.472717]
"#;
