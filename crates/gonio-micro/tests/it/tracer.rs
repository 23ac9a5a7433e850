//! The max-mip traversal and the flat grid DDA against brute force over every cell:
//! the same hit cell, triangle and `t` on thousands of random rays, on surfaces whose
//! hierarchies differ (power-of-two and odd sizes, 1-D profiles).

use gonio_core::Vec3;
use gonio_micro::{GaussianParams, HeightField, Method, Ray, Tracer};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn surfaces() -> Vec<(&'static str, HeightField)> {
    let g = |nx, ny, seed| {
        HeightField::gaussian(&GaussianParams {
            nx,
            ny,
            spacing: 0.5,
            rms_height: 0.6,
            correlation_length: 2.0,
            seed,
        })
        .expect("gaussian")
    };
    vec![
        ("gaussian 64×64", g(64, 64, 1)),
        ("gaussian 48×20", g(48, 20, 2)),
        ("gaussian 7×5", g(7, 5, 3)),
        (
            "sawtooth 30°/60°",
            HeightField::sawtooth(1.0, 30f64.to_radians(), 60f64.to_radians()).expect("saw"),
        ),
        (
            "cylinders",
            HeightField::cylinders(1.0, 2.5, 40).expect("cyl"),
        ),
    ]
}

fn random_dir(rng: &mut ChaCha8Rng, down: bool) -> Vec3 {
    let z: f64 = rng.random::<f64>() * 2.0 - 1.0;
    let z = if down { -z.abs().max(1e-3) } else { z };
    let phi = std::f64::consts::TAU * rng.random::<f64>();
    let s = (1.0 - z * z).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), z)
}

#[test]
fn max_mip_and_grid_agree_with_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for (name, hf) in surfaces() {
        let (lx, ly) = hf.period();
        let (h0, h1) = (hf.min_height(), hf.max_height());
        let tr = Tracer::new(hf);
        let mut hits = 0;
        let n = 1500;
        for k in 0..n {
            // Half the rays come from above (far outside the patch, too), half start on
            // the surface's height range going anywhere, as bounced rays do.
            let from_above = k % 2 == 0;
            let o = Vec3::new(
                (rng.random::<f64>() * 3.0 - 1.0) * lx,
                (rng.random::<f64>() * 3.0 - 1.0) * ly,
                if from_above {
                    h1 + rng.random::<f64>()
                } else {
                    h0 + (h1 - h0) * rng.random::<f64>()
                },
            );
            let ray = Ray {
                o,
                d: random_dir(&mut rng, from_above),
                t_min: 0.0,
                skip: None,
            };
            let brute = tr.first_hit(&ray, Method::BruteForce);
            for m in [Method::MaxMip, Method::Grid] {
                let h = tr.first_hit(&ray, m);
                match (h, brute) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        assert_eq!((a.cell, a.tri), (b.cell, b.tri), "{name} ray {k} {m:?}");
                        assert!(
                            (a.t - b.t).abs() <= 1e-12 * b.t.abs().max(1.0),
                            "{name} ray {k} {m:?}: {} vs {}",
                            a.t,
                            b.t
                        );
                    }
                    _ => panic!("{name} ray {k} {m:?}: {h:?} vs brute force {brute:?}"),
                }
            }
            hits += usize::from(brute.is_some());
            // A ray from above always meets the surface.
            if from_above {
                assert!(brute.is_some(), "{name} ray {k} from above missed");
            }
        }
        assert!(hits > n / 2, "{name}: only {hits} hits");
    }
}
