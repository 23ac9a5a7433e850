//! The RGL material (`.bsdf`): the tensor file's bytes as Mitsuba's format defines
//! them, the material's values at its nodes and between them against the source,
//! an albedo integrated from the file alone, round trips, and every malformed input
//! refused by name. (Mitsuba 3's own plugin holds the files in
//! `crates/gonio-py/tests/test_rgl.py`.)

use gonio_brdf::{Brdf, Model};
use gonio_core::Dir;
use gonio_io::formats::rgl::tensor::{self, Field, Values};
use gonio_io::formats::{self, Data, Format, RglBsdf, RglOptions, fuzz};
use proptest::prelude::*;

fn model(text: &str) -> Model {
    Model::from_toml(text, None).expect("model")
}

fn lambert(rho: f64) -> Model {
    model(&format!(
        "kind = \"lambert\"\nchannels = [\"R\", \"G\", \"B\"]\nrho = [{rho}, {}, {}]\n",
        rho * 0.5,
        rho * 0.25
    ))
}

fn write(b: &dyn Brdf, opts: &RglOptions) -> RglBsdf {
    RglBsdf::from_brdf(b, opts, "test", &|_, _| true).expect("writes")
}

#[test]
fn a_tensor_file_has_the_bytes_the_format_defines() {
    let fields = vec![
        Field::bytes("jacobian", vec![1]),
        Field::f32("theta_i", vec![2], vec![0.0, 0.5]),
    ];
    let bytes = tensor::write(&fields);
    let mut want = b"tensor_file\0".to_vec();
    want.extend([1, 0]);
    want.extend(2u32.to_le_bytes());
    // Header: 18 + (2 + 8 + 2 + 1 + 8 + 8) + (2 + 7 + 2 + 1 + 8 + 8) = 75 bytes, the
    // first field's data at the next multiple of 8 (80), the second at 88.
    for (name, code, off, n) in [("jacobian", 1u8, 80u64, 1u64), ("theta_i", 10, 88, 2)] {
        want.extend((name.len() as u16).to_le_bytes());
        want.extend(name.as_bytes());
        want.extend(1u16.to_le_bytes());
        want.push(code);
        want.extend(off.to_le_bytes());
        want.extend(n.to_le_bytes());
    }
    assert_eq!(want.len(), 75);
    want.resize(80, 0);
    want.push(1);
    want.resize(88, 0);
    want.extend(0f32.to_le_bytes());
    want.extend(0.5f32.to_le_bytes());
    assert_eq!(bytes, want);
    assert_eq!(tensor::read(&bytes, None).expect("reads"), fields);
}

#[test]
fn a_lambertian_surface_is_its_albedo_over_pi_at_the_nodes_and_between_them() {
    let m = lambert(0.8);
    let r = write(&m, &RglOptions::default());
    let e = r.interpolation_error(&m, 75.0);
    // f32 storage at the nodes; between them the warped interpolation of a smooth
    // function.
    assert!(e.at_nodes < 1e-6, "{e:?}");
    assert!(e.between < 0.02, "{e:?}");
    // The albedo integrated from the file alone (Gonio's quadrature over its values).
    let mut a = [0.0; 3];
    for theta in [0.0f64, 40.0, 70.0] {
        r.albedo(Dir::from_angles(theta.to_radians(), 0.3), &mut a);
        for (got, want) in a.iter().zip([0.8, 0.4, 0.2]) {
            assert!(
                (got - want).abs() < 0.01 * want,
                "θi {theta}: {got} against {want}"
            );
        }
    }
}

#[test]
fn a_model_holds_at_the_nodes_and_within_the_resolution_between_them() {
    for text in [
        "kind = \"cook-torrance\"\nchannels = [\"R\", \"G\", \"B\"]\ndistribution = \"ggx\"\n\
         f0 = [0.9, 0.6, 0.3]\nalpha = [0.3, 0.3, 0.3]\n",
        // Anisotropic: sixteen azimuths of incidence.
        "kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.15]\nalpha_x = [0.1]\n\
         alpha_y = [0.25]\n[diffuse]\nrho = [0.2]\n",
    ] {
        let m = model(text);
        let r = write(&m, &RglOptions::default());
        let e = r.interpolation_error(&m, 75.0);
        assert!(e.at_nodes < 1e-5, "{text}: {e:?}");
        assert!(e.between < 0.05, "{text}: {e:?}");
        // Finer slices hold the material closer between the nodes.
        let fine = write(
            &m,
            &RglOptions {
                slice: 64,
                incidences: 12,
                ..RglOptions::default()
            },
        );
        assert!(
            fine.interpolation_error(&m, 75.0).between < e.between,
            "{text}"
        );
    }
}

#[test]
fn a_material_reads_back_to_the_same_fields_and_values() {
    let m = lambert(0.5);
    let r = write(
        &m,
        &RglOptions {
            slice: 8,
            vndf: 16,
            ndf: 12,
            incidences: 3,
            ..RglOptions::default()
        },
    );
    let bytes = r.to_bytes();
    assert_eq!(formats::detect(&bytes), Some(Format::Rgl));
    let Data::Rgl(back) = formats::read(&bytes, None).expect("reads") else {
        panic!("not an RGL material");
    };
    assert_eq!(back.fields(), r.fields());
    assert_eq!(back.to_bytes(), bytes);
    let (wi, wo) = (Dir::from_angles(0.4, 0.1), Dir::from_angles(1.0, 2.0));
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    r.eval(wi, wo, &mut a);
    back.eval(wi, wo, &mut b);
    assert_eq!(a, b);
    // The `valid` mask travels with it; the description too.
    assert_eq!(back.valid.as_ref().map(Vec::len), Some(3 * 8 * 8));
    assert_eq!(back.description, "test");
    fuzz::rgl_read(&bytes);
}

#[test]
fn malformed_materials_are_refused_naming_the_field_or_byte() {
    let r = write(
        &lambert(0.5),
        &RglOptions {
            slice: 4,
            vndf: 4,
            ndf: 4,
            incidences: 2,
            ..RglOptions::default()
        },
    );
    let good = r.to_bytes();
    let err = |bytes: &[u8]| formats::read(bytes, None).expect_err("refused").to_string();
    let mut v = good.clone();
    v[12] = 2;
    assert_eq!(
        err(&v),
        "<RGL material file>: byte 12: tensor file version 2.0: only 1.0 is read"
    );
    assert!(
        err(&good[..40]).contains("truncated"),
        "{}",
        err(&good[..40])
    );
    assert!(err(&good[..good.len() - 1]).contains("runs past the end of the file"));
    let without = |name: &str| -> Vec<u8> {
        tensor::write(
            &r.fields()
                .iter()
                .filter(|f| f.name != name)
                .cloned()
                .collect::<Vec<_>>(),
        )
    };
    assert!(err(&without("vndf")).contains("no field `vndf`"));
    let edit = |name: &str, f: &dyn Fn(&mut Field)| -> Vec<u8> {
        let mut fields = r.fields().to_vec();
        fields.iter_mut().filter(|x| x.name == name).for_each(f);
        tensor::write(&fields)
    };
    let e = err(&edit("sigma", &|x| {
        if let Values::F32(v) = &mut x.values {
            v[1] = 0.0;
        }
    }));
    assert!(e.contains("field `sigma`: a value 0"), "{e}");
    let e = err(&edit("theta_i", &|x| {
        x.shape = vec![1];
        x.values = Values::F32(vec![0.0]);
    }));
    assert!(e.contains("shapes that do not match"), "{e}");
    let e = err(&edit("jacobian", &|x| x.values = Values::F32(vec![1.0])));
    assert!(e.contains("field `jacobian`: f32"), "{e}");
}

#[test]
fn bad_options_are_refused() {
    let m = lambert(0.5);
    for opts in [
        RglOptions {
            slice: 1,
            ..RglOptions::default()
        },
        RglOptions {
            theta_max_deg: 90.0,
            ..RglOptions::default()
        },
    ] {
        let e = RglBsdf::from_brdf(&m, &opts, "", &|_, _| true).expect_err("refused");
        assert_eq!(e.format, Some(Format::Rgl));
    }
    // Each within its bound, too many values together for an anisotropic material.
    let ward = model(
        "kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.15]\nalpha_x = [0.1]\n\
         alpha_y = [0.25]\n",
    );
    let opts = RglOptions {
        azimuths: 64,
        vndf: 512,
        ..RglOptions::default()
    };
    let e = RglBsdf::from_brdf(&ward, &opts, "", &|_, _| true).expect_err("refused");
    assert!(e.message.contains("more than the 67108864"), "{e}");
}

#[test]
fn the_half_vector_of_a_node_is_where_the_source_was_evaluated() {
    // At each of the file's node pairs the value is the source's, on a material whose
    // value changes with every angle: to the f32 storage and the inverse warp's
    // rounding (worst 6e-4 relative, near the horizon where the value is smallest).
    let m = model(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.3]\n[[lobes]]\n\
         cx = [-0.8]\ncy = [-0.8]\ncz = [0.9]\nn = [15]\n",
    );
    let r = write(&m, &RglOptions::default());
    let mut worst: f64 = 0.0;
    let (mut a, mut b) = ([0.0; 3], [0.0; 1]);
    for (wi, wo) in r.node_pairs().into_iter().step_by(7) {
        r.eval(wi, wo, &mut a);
        m.eval(wi, wo, &mut b);
        worst = worst.max((a[1] - b[0]).abs() / b[0]);
    }
    assert!(worst < 2e-3, "{worst}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any bytes, and any corruption of a real file, read without panicking.
    #[test]
    fn no_input_panics(bytes in proptest::collection::vec(any::<u8>(), 0..400), at in 0usize..3000, with in any::<u8>()) {
        fuzz::rgl_read(&bytes);
        let mut head = b"tensor_file\0\x01\0".to_vec();
        head.extend(&bytes);
        fuzz::rgl_read(&head);
        let r = write(&lambert(0.5), &RglOptions { slice: 4, vndf: 4, ndf: 4, incidences: 2, ..RglOptions::default() });
        let mut good = r.to_bytes();
        let at = at % good.len();
        good[at] = with;
        fuzz::rgl_read(&good);
    }
}

#[test]
fn the_valid_mask_marks_the_nodes_beyond_the_source() {
    // A source that holds data only up to θo = 60°: the mask is 0 exactly at the
    // nodes whose outgoing direction lies beyond.
    let opts = RglOptions {
        slice: 12,
        incidences: 3,
        ..RglOptions::default()
    };
    let reach = 60f64.to_radians();
    let r =
        RglBsdf::from_brdf(&lambert(0.5), &opts, "", &|_, wo| wo.theta() <= reach).expect("writes");
    let mask = r.valid.clone().expect("a mask");
    let (ns, mut beyond) = (12, 0);
    for (k, theta) in r.theta_i.iter().enumerate() {
        let pairs: Vec<_> = r
            .node_pairs()
            .into_iter()
            .filter(|(wi, _)| (wi.theta() - *theta as f64).abs() < 1e-6)
            .collect();
        let marked = mask[k * ns * ns..(k + 1) * ns * ns]
            .iter()
            .filter(|v| **v == 0)
            .count();
        let far = pairs.iter().filter(|(_, wo)| wo.theta() > reach).count();
        // Nodes below the horizon hold nothing and are marked too.
        assert_eq!(marked, far + ns * ns - pairs.len(), "θi {theta}");
        beyond += far;
    }
    assert!(beyond > 0);
}
