//! The bodies of the cargo-fuzz targets `merl_read`, `rgl_read`, `astm_read` and `csv_read` in
//! `fuzz/` (run with `cargo +nightly fuzz run <target>`); the tests run them under
//! proptest too. None may panic on any input; each checks that whatever reads writes
//! back to the same thing.

use super::merl::{self, Bin, PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use super::{Data, detect, read_astm, read_csv, write_astm};

/// Arbitrary bytes as a MERL file: detection, the header and length checks, value
/// decoding (the bytes after a 12-byte header as the values), and the bin lookup
/// (the bytes as angles and as bin indices: a bin's centre pair falls in that bin).
pub fn merl_read(data: &[u8]) {
    let _ = detect(data);
    match merl::read_merl(data, None) {
        Ok(m) => assert_eq!(m.to_bytes(), data, "a MERL file re-encodes to itself"),
        Err(e) => {
            let _ = e.to_string();
        }
    }
    if let Ok(values) = merl::decode_values(data.get(12..).unwrap_or(&[]), 12, None) {
        assert!(values.iter().all(|v| *v != f64::INFINITY), "+inf decoded");
    }
    // The geometry checks look at the first 4 KiB (a whole file would take seconds).
    let head = &data[..data.len().min(4096)];
    for c in head.chunks_exact(8) {
        let mut b = [0u8; 8];
        b.copy_from_slice(c);
        let x = f64::from_le_bytes(b);
        assert!(merl::theta_h_index(x) < THETA_H_BINS);
        assert!(merl::theta_d_index(x) < THETA_D_BINS);
        assert!(merl::phi_d_index(x) < PHI_D_BINS);
    }
    for c in head.chunks_exact(32) {
        let mut a = [0.0; 4];
        for (k, v) in a.iter_mut().enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(&c[8 * k..8 * k + 8]);
            *v = f64::from_le_bytes(b);
        }
        let wi = gonio_core::Dir::from_angles(a[0], a[1]);
        let wo = gonio_core::Dir::from_angles(a[2], a[3]);
        if let Some(bin) = Bin::of(wi, wo) {
            assert!(Bin::from_index(bin.index()) == Some(bin));
        }
    }
    for c in head.chunks_exact(3) {
        let bin = Bin {
            theta_h: c[0] as usize % THETA_H_BINS,
            theta_d: c[1] as usize % THETA_D_BINS,
            phi_d: (c[2] as usize * 7) % PHI_D_BINS,
        };
        let p = bin.centre_pair();
        assert_eq!(Bin::of(p.wi, p.wo), Some(bin), "the centre of {bin}");
    }
}

/// Arbitrary bytes as ASTM E1392 text: whatever reads writes back and reads again to
/// the same samples.
pub fn astm_read(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match read_astm(text, None) {
        Ok(s) => {
            let again = write_astm(&s);
            let back = read_astm(&again, None).expect("Gonio's own ASTM output reads");
            assert_eq!(back, s, "ASTM round trip");
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

/// Arbitrary bytes as a CSV sample or table file: samples that read write back and
/// read again to the same samples; a table that reads and is read again after
/// writing has the same values.
pub fn csv_read(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match read_csv(text, None) {
        Ok(Data::Samples(s)) => {
            // Read back with its sidecar, which carries what the CSV cannot (isotropy).
            let again = gonio_process::file::write_samples(&s);
            let meta = gonio_process::file::Meta::for_samples(&s);
            let back =
                super::read_csv_from(again.as_bytes(), again.len() as u64, Some(&meta), None)
                    .expect("Gonio's own CSV output reads");
            assert_eq!(back, Data::Samples(s), "CSV samples round trip");
        }
        Ok(Data::Table(t)) => {
            // gonio_process::file writes axes to 1e-9° (a single node's step below that
            // as 0), so a table with such axes may not read back; when it does, it must
            // hold the same values, never different ones.
            let again = gonio_process::file::write_table(&t);
            let meta = gonio_process::file::Meta::for_table(&t);
            match super::read_csv_from(again.as_bytes(), again.len() as u64, Some(&meta), None) {
                Ok(Data::Table(back)) => assert_eq!(
                    (back.channels, back.values, back.sigma),
                    (t.channels, t.values, t.sigma),
                    "CSV table round trip"
                ),
                Ok(_) => panic!("a table written reads back as something else"),
                Err(e) => {
                    let _ = e.to_string();
                }
            }
        }
        Ok(Data::Merl(_) | Data::Rgl(_)) => panic!("the CSV reader gave a binary format"),
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

/// Arbitrary bytes as an RGL material (a tensor file): the header and every
/// declared size are checked before anything is allocated for them; a material
/// that reads writes back to bytes that read to the same fields, and evaluates to
/// finite values.
pub fn rgl_read(data: &[u8]) {
    let _ = detect(data);
    match super::rgl::tensor::read(data, None) {
        Ok(fields) => {
            let again = super::rgl::tensor::write(&fields);
            let back = super::rgl::tensor::read(&again, None).expect("written fields read");
            let kept: Vec<_> = fields
                .into_iter()
                .filter(|f| !matches!(f.values, super::rgl::tensor::Values::Other(_)))
                .collect();
            assert_eq!(back, kept, "tensor file round trip");
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    if let Ok(r) = super::rgl::RglBsdf::read(data, None) {
        let mut out = vec![0.0; gonio_brdf::Brdf::channels(&r).len()];
        for (t, p) in [(0.1, 0.0), (0.7, 1.0), (1.3, -2.0)] {
            let wi = gonio_core::Dir::from_angles(t, p);
            let wo = gonio_core::Dir::from_angles(1.4 - t, p + 2.5);
            r.eval_cos(wi, wo, &mut out);
            assert!(out.iter().all(|v| v.is_finite()), "a non-finite value");
        }
    }
}
