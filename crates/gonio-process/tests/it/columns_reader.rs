//! The column reader (`file::read_columns`): another tool's table (columns in any
//! order, units in the header, no sidecar) reads as the same table, bit for bit, as
//! Gonio's own; chunk and block boundaries change nothing; 1 and 2 threads give the
//! same bytes; bad input is refused at its line.

use gonio_brdf::Model;
use gonio_process::file::{self, Columns, Content, Meta};
use gonio_process::{Axis, Grid, Samples, Table, measure};
use proptest::prelude::*;

use crate::RGB_PAINT as PAINT;

/// The paint on a full grid of `n_phi` azimuths × `n_theta` polar bands each side,
/// with an uncertainty of 1% + 1e-4 when `sigma`.
fn paint_table(n_phi: usize, n_theta: usize, sigma: bool) -> Table {
    let m = Model::from_toml(PAINT, None).expect("model");
    let g = Grid::full(
        Axis::full_turn(n_phi),
        Axis::polar_midpoints(n_theta),
        Axis::full_turn(n_phi),
        Axis::polar_midpoints(n_theta),
    );
    let t = Table::from_brdf(&m, g).expect("table");
    if !sigma {
        return t;
    }
    let s = t.values.iter().map(|v| 0.01 * v + 1e-4).collect();
    t.with_values(t.values.clone(), Some(s))
}

/// Gonio's CSV rewritten as another tool might: the columns in the order `perm`
/// (the new column j is Gonio's column `perm[j]`), named `names` (in Gonio's order).
fn other_tool(text: &str, perm: &[usize], names: &[&str]) -> String {
    let mut out = String::with_capacity(text.len());
    for (k, line) in text.lines().enumerate() {
        let f: Vec<&str> = if k == 0 {
            names.to_vec()
        } else {
            line.split(',').collect()
        };
        assert_eq!(f.len(), perm.len());
        let row: Vec<&str> = perm.iter().map(|&j| f[j]).collect();
        out.push_str(&row.join(","));
        out.push('\n');
    }
    out
}

fn columns(text: &str) -> Columns {
    file::read_columns(text.as_bytes(), text.len() as u64, None).expect("columns")
}

fn table_of(c: Content) -> Table {
    match c {
        Content::Table(t) => t,
        Content::Samples(_) => panic!("samples, not a table"),
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The same table to the bit: grid, channels, values and uncertainties.
fn assert_same(a: &Table, b: &Table) {
    assert_eq!(a.grid, b.grid);
    assert_eq!(a.channels, b.channels);
    assert_eq!(bits(&a.values), bits(&b.values));
    assert_eq!(
        a.sigma.as_deref().map(bits),
        b.sigma.as_deref().map(bits),
        "σ"
    );
}

#[test]
fn another_tools_table_is_gonios_own_bit_for_bit() {
    let t = paint_table(8, 4, true);
    let text = file::write_table(&t);
    let meta = Meta::for_table(&t);
    // Today's two paths: with the sidecar, and the rows as samples that form the grid.
    let with_sidecar = table_of(
        file::read_from(text.as_bytes(), text.len() as u64, Some(&meta), None).expect("sidecar"),
    );
    assert_same(&with_sidecar, &t);
    let Content::Samples(s) = file::read(&text, None).expect("samples") else {
        panic!("no sidecar: samples");
    };
    let as_samples = s.to_table().expect("a grid");
    // The column reader, both ways.
    assert_same(
        &table_of(
            columns(&text)
                .into_content(Some(&meta), None)
                .expect("sidecar"),
        ),
        &t,
    );
    let recognised = table_of(columns(&text).into_content(None, None).expect("recognised"));
    assert_same(&recognised, &as_samples);
    // Shuffled, with units in several spellings.
    let names = [
        "theta_i [deg]",
        "phi_i (deg)",
        "theta_o",
        "phi_o_deg",
        "f_r_R [1/sr]",
        "f_r_G_per_sr",
        "f_r_B (1/sr)",
        "sigma_R [1/sr]",
        "sigma_G_per_sr",
        "\"sigma_B_per_sr\"",
    ];
    let perm = [7, 2, 4, 0, 9, 1, 5, 3, 8, 6];
    let other = other_tool(&text, &perm, &names);
    assert!(other.starts_with("sigma_R [1/sr],theta_o,f_r_R [1/sr],theta_i [deg],"));
    let c = columns(&other);
    assert_eq!(c.roles.angles, [3, 5, 1, 7]);
    assert_eq!(c.roles.values, [2, 6, 9]);
    assert_eq!(c.roles.sigma, Some(vec![0, 8, 4]));
    assert_same(
        &table_of(c.into_content(None, None).expect("other")),
        &as_samples,
    );
    // The grid's rows in another order, and format-1 names, read the same too.
    let mut lines: Vec<&str> = text.lines().collect();
    lines[1..].reverse();
    let reversed = lines.join("\n").replace(
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_R_per_sr,f_r_G_per_sr,f_r_B_per_sr,\
         sigma_R_per_sr,sigma_G_per_sr,sigma_B_per_sr",
        "theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R,sigma_G,sigma_B",
    );
    assert!(reversed.starts_with("theta_i,phi_i,"));
    assert_same(
        &table_of(
            columns(&reversed)
                .into_content(None, None)
                .expect("reversed"),
        ),
        &as_samples,
    );
    // And on the sidecar's grid: each row placed at its node.
    let mut lines: Vec<&str> = text.lines().collect();
    lines[1..].reverse();
    assert_same(
        &table_of(
            columns(&lines.join("\n"))
                .into_content(Some(&meta), None)
                .expect("reversed, sidecar"),
        ),
        &t,
    );
    // The sidecar's grid against the recognised one: the same axes.
    assert_eq!(with_sidecar.grid, as_samples.grid);
}

#[test]
fn isotropic_rows_and_scattered_samples_read_as_today() {
    // An isotropic table marked by `# isotropic: true`: recognised in φo − φi.
    let g = Grid::isotropic(
        Axis::polar_midpoints(3),
        Axis::full_turn(8),
        Axis::polar_midpoints(3),
    );
    let iso = Table::new(
        gonio_core::Channels::Single,
        g,
        (0..72).map(|i| 0.1 + f64::from(i) * 0.01).collect(),
        None,
    )
    .expect("isotropic");
    let text = format!("# isotropic: true\n{}", file::write_table(&iso));
    let Content::Samples(s) = file::read(&text, None).expect("samples") else {
        panic!("samples");
    };
    let today = s.to_table().expect("grid");
    assert!(today.grid.isotropic);
    assert_same(
        &table_of(columns(&text).into_content(None, None).expect("iso")),
        &today,
    );
    // Samples off any grid, with flags: the same samples as the streaming reader's.
    let text = "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_per_sr,sigma_per_sr,flags\n\
                10,0,20,180,0.25,0.5,1\n30,5,40,175.5,1,0,0\n12.5,90,7,3,2,0.1,4\n";
    let want = file::read(text, None).expect("read");
    let got = columns(text).into_content(None, None).expect("columns");
    assert_eq!(got, want);
    let Content::Samples(Samples { samples, .. }) = got else {
        panic!("samples");
    };
    assert_eq!(samples[2].flags, 4);
    // Repeats of a node: samples, which `Samples::to_table` then combines as today.
    let t = paint_table(4, 2, true);
    let text = file::write_table(&t);
    let twice = format!("{text}{}", text.lines().nth(5).expect("row"));
    let Content::Samples(s) = columns(&twice).into_content(None, None).expect("repeat") else {
        panic!("a repeated node is not a table of its own");
    };
    let Content::Samples(old) = file::read(&twice, None).expect("old") else {
        panic!("samples");
    };
    assert_eq!(s, old);
}

/// A table's text with comment and blank lines among the rows and CRLF line ends.
fn noisy_text() -> String {
    let t = paint_table(4, 3, true);
    let mut out = String::from("\u{feff}# made by another tool\n\n");
    for (k, l) in file::write_table(&t).lines().enumerate() {
        out.push_str(l);
        out.push_str(if k % 7 == 3 { "\r\n" } else { "\n" });
        if k % 50 == 17 {
            out.push_str("# a note\n   \n");
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any block and chunk size: the same columns, and an error at the same line.
    #[test]
    fn chunk_and_block_boundaries_change_nothing(block in 1usize..400, chunk in 1usize..300) {
        let text = noisy_text();
        let want = columns(&text);
        let got = file::read_columns_in(text.as_bytes(), text.len() as u64, None, block, chunk)
            .expect("columns");
        prop_assert_eq!(&got, &want);
        prop_assert_eq!(got.line_of(100), want.line_of(100));
        let mut lines: Vec<&str> = text.lines().collect();
        let k = (120..lines.len()).find(|k| lines[*k].contains(',')).expect("a row");
        let bad = lines[k].replacen(',', ",x", 1);
        lines[k] = &bad;
        let bad = lines.join("\n");
        let e = file::read_columns_in(bad.as_bytes(), bad.len() as u64, None, block, chunk)
            .expect_err("bad");
        prop_assert_eq!(e.line, Some(k + 1));
        prop_assert_eq!(e.field.as_deref(), Some("phi_i_deg"));
    }
}

#[test]
fn row_lines_are_counted_past_comments() {
    let text = noisy_text();
    let c = columns(&text);
    let lines: Vec<&str> = text.lines().collect();
    // Row r's text is on line line_of(r).
    for r in [0, 1, 17, 18, 19, 100, c.rows() - 1] {
        let l = lines[c.line_of(r) - 1];
        let theta_i: f64 = l.split(',').next().expect("field").parse().expect("θi");
        assert_eq!(theta_i, c.angles[0][r], "row {r}");
    }
}

/// The table and `gonio check`'s measures from the text, in a pool of `threads`.
fn measured_in(threads: usize, text: &str) -> (Vec<u64>, String) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| {
        let c = file::read_columns_in(text.as_bytes(), text.len() as u64, None, 1 << 16, 4096)
            .expect("columns");
        let t = table_of(c.into_content(None, None).expect("table"));
        let r = measure::report_with(&t, None, &[1, 5, 10], 5).expect("report");
        (bits(&t.values), serde_json::to_string(&r).expect("json"))
    })
}

#[test]
fn one_and_two_threads_give_the_same_bytes() {
    // A is 288 × 288: the truncated SVD's products on rayon (faer's matrix
    // products); many chunks and blocks.
    let t = paint_table(32, 9, false);
    let text = file::write_table(&t);
    let one = measured_in(1, &text);
    let two = measured_in(2, &text);
    assert!(one.0 == bits(&t.values), "1 thread: not the table written");
    assert!(two.0 == one.0, "2 threads: another table");
    if let Some(at) = one.1.bytes().zip(two.1.bytes()).position(|(a, b)| a != b) {
        let from = at.saturating_sub(300);
        panic!(
            "the measures differ at byte {at}: {} / {}",
            &one.1[from..at + 40],
            &two.1[at..at + 40]
        );
    }
    assert_eq!(one.1, two.1);
    assert!(one.1.contains("\"p_s\""), "{}", one.1);
}

/// The error of reading `text` (as `t.csv`): line, field and message.
fn error(text: &str) -> (Option<usize>, Option<String>, String) {
    let path = std::path::Path::new("t.csv");
    let e = file::read_columns_in(text.as_bytes(), text.len() as u64, Some(path), 64, 16)
        .and_then(|c| c.into_content(None, Some(path)))
        .expect_err("bad input");
    assert_eq!(e.path.as_deref(), Some(path));
    (e.line, e.field, e.message)
}

#[test]
fn bad_input_is_refused_at_its_line_and_column() {
    let head = "phi_o [deg],theta_i [deg],f_r_550nm [1/sr],phi_i [deg],theta_o [deg]";
    let (l, f, m) = error(&format!("{head}\n0,10,0.5,0,20\n# note\n\n0,10,x,0,30\n"));
    assert_eq!((l, f.as_deref()), (Some(5), Some("f_r_550nm [1/sr]")));
    assert_eq!(m, "not a finite number: \"x\"");
    let (l, f, m) = error(&format!("{head}\n0,10,0.5,0,20\n0,10,0.5,0\n"));
    assert_eq!(
        (l, f, m.as_str()),
        (Some(3), None, "4 fields, the header has 5")
    );
    let (l, f, m) = error(&format!("{head}\n0,95,0.5,0,20\n"));
    assert_eq!((l, f.as_deref()), (Some(2), Some("theta_i [deg]")));
    assert_eq!(m, "θ must lie in [0, 90], got 95");
    let (l, _, m) = error(&format!("# a\n{head}\n"));
    assert_eq!((l, m.as_str()), (None, "no data rows"));
    let (_, f, m) = error("theta_i,phi_i,theta_o,phi_o,value,sigma_value\n1,2,3,4,5,-1\n");
    assert_eq!(
        (f.as_deref(), m.as_str()),
        (Some("sigma_value"), "uncertainty is negative")
    );
    // Headers that are ambiguous or say something else than degrees.
    let (l, _, m) = error("theta_i,theta_i_deg,phi_i,theta_o,phi_o,value\n");
    assert_eq!(l, Some(1));
    assert_eq!(
        m,
        "columns 1 (\"theta_i\") and 2 (\"theta_i_deg\") both name the same quantity"
    );
    let (l, _, m) = error("\n# x\ntheta_i [rad],phi_i,theta_o,phi_o,value\n1,2,3,4,5\n");
    assert_eq!(l, Some(3));
    assert_eq!(
        m,
        "column \"theta_i [rad]\" is in radians; the angles are read in degrees"
    );
    let (_, _, m) = error("theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R\n");
    assert_eq!(
        m,
        "the uncertainty of channel \"G\" is missing: either every channel has one or none"
    );
    let (_, _, m) = error("theta_i,phi_i,theta_o,value\n");
    assert!(m.starts_with("no column for φo;"), "{m}");
    let (_, _, m) = error("theta_i,phi_i,theta_o,phi_o,f_r_R_per_sr,R\n");
    assert_eq!(
        m,
        "columns 5 (\"f_r_R_per_sr\") and 6 (\"R\") both name the same quantity"
    );
    let (_, _, m) = error("theta_i,phi_i,theta_o,phi_o,value,sigma_R\n");
    assert!(
        m.contains("uncertainty of \"R\", which has no value column"),
        "{m}"
    );
    // A grid line: rows off the grid, or a node twice, at their lines.
    let grid = "# grid: isotropic=false phi_i=0:90:1 theta_i=0:45:1 phi_o=0:90:1 theta_o=0:45:2\n";
    let (l, f, m) = error(&format!("{grid}{head}\n0,0,1,0,0\n0,0,1,0,44\n"));
    assert_eq!((l, f.as_deref()), (Some(4), Some("theta_o")));
    assert_eq!(m, "44 is not a node of the grid");
    let (l, _, m) = error(&format!("{grid}{head}\n0,0,1,0,0\n\n0,0,1,0,0\n"));
    assert_eq!((l, m.as_str()), (Some(5), "this node was already given"));
    let (l, f, _) = error(&format!("{grid}{head}\n0,0,1,0,0\n"));
    assert_eq!((l, f.as_deref()), (Some(1), Some("grid")));
    // A line longer than the reader takes, in a later block.
    let long = format!("{head}\n0,0,1,0,0\n{}\n", "1".repeat(70_000));
    let (l, _, m) = error(&long);
    assert_eq!((l, m.as_str()), (Some(3), "longer than 65536 bytes"));
}

#[test]
fn a_header_from_any_tool_is_recognised_and_others_are_not() {
    for yes in [
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_per_sr",
        "# x\nphi_o,theta_o,phi_i,theta_i,R,G,B\n1,2,3",
        "theta_o (°),phi_o [degrees],theta_i,phi_i,f_r_550nm [1/sr],f_r_650nm [1/sr]",
    ] {
        assert!(file::is_columns_header(yes.as_bytes()), "{yes}");
    }
    for no in [
        "NUM_POINTS 3\nVARS theta_i,phi_i",
        "theta_i,phi_i,theta_o,phi_o",
        "a,b,c,d,e",
        "theta_i,phi_i,theta_o,phi_o,colour",
    ] {
        assert!(!file::is_columns_header(no.as_bytes()), "{no}");
    }
}

#[test]
fn the_floors_are_the_same_bytes_on_one_and_two_threads() {
    // A is 72 × 72, below the truncated SVD's size: the separability floor takes a
    // full SVD with its vectors, then its noise draws side by side on rayon.
    let t = paint_table(12, 6, true);
    let floors_in = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let r = measure::report_with(&t, None, &[1, 5], 5).expect("report");
            let f = gonio_process::floor::floors(&t, None, &r, &[1, 5], 8).expect("floors");
            format!("{f:?}")
        })
    };
    let one = floors_in(1);
    assert!(one.contains("separability: Some"), "{one}");
    assert_eq!(one, floors_in(2));
}
