//! Sizes and magnitudes a file or a flag may ask for, and the refusals that name the
//! limit: grids of too many nodes (before anything is allocated), table headers that
//! claim them, separable factors too large to multiply.

use gonio_process::file;
use gonio_process::separable::SeparableBrdf;
use gonio_process::{Grid, GridStep, MAX_GRID_NODES, Table};

#[test]
fn a_grid_step_of_too_many_nodes_is_refused_with_the_cap() {
    // 2.5° × 2.5° is the finest full grid: (36 × 144)² = 26.9 million nodes.
    let fine = GridStep::new(2.5, 2.5).expect("within the cap");
    assert_eq!(fine.grid().len(), 26_873_856);
    assert!(fine.grid().len() <= MAX_GRID_NODES);
    for s in ["2,2", "0.001,0.001", "0.0001,0.0001"] {
        let e = s.parse::<GridStep>().expect_err(s);
        assert!(
            e.contains(&format!(
                "more than the {MAX_GRID_NODES} a grid may have (the finest is about 2.5,2.5)"
            )),
            "{s}: {e}"
        );
    }
    // 0.0001° makes ~10^25 nodes: counted without overflow.
    let e = "0.0001,0.0001".parse::<GridStep>().expect_err("1e19 nodes");
    assert!(e.contains("1.05e25 nodes"), "{e}");
}

#[test]
fn a_table_header_claiming_too_many_nodes_is_refused_before_any_row() {
    // 10^6 nodes on each axis: 10^24 nodes, which would overflow the node count.
    let text = "# grid: isotropic=false phi_i=0:0.00001:1000000 theta_i=0:0.00001:1000000 \
                phi_o=0:0.00001:1000000 theta_o=0:0.00001:1000000\n\
                theta_i,phi_i,theta_o,phi_o,value\n0,0,0,0,1\n";
    let e = file::read(text, None).expect_err("too many nodes");
    let s = e.to_string();
    assert_eq!(e.line, Some(1), "{s}");
    assert!(
        s.contains("over 2^64 nodes, more than the 33554432 a grid may have"),
        "{s}"
    );
    // Within usize, but past the cap.
    let g = Grid::hemisphere(90, 360);
    let e = Table::new(gonio_core::Channels::Single, g, vec![0.0; 1], None).expect_err("cap");
    assert!(e.to_string().contains("1049760000 nodes"), "{e}");
}

#[test]
fn a_separable_file_with_an_absurd_factor_is_refused_naming_it() {
    let g = Grid::hemisphere(3, 4);
    let values: Vec<f64> = (0..g.len()).map(|i| 0.1 + i as f64 * 1e-3).collect();
    let t = Table::new(gonio_core::Channels::Single, g, values, None).expect("table");
    let sep = SeparableBrdf::from_table(&t, 1, false).expect("factors");
    let text = sep.to_toml();
    // The first value of the first factor, made absurd.
    let at = text.find("in = [").expect("the first factor") + "in = [".len();
    let end = at + text[at..].find([',', ']']).expect("a value");
    let bad = format!("{}1e200{}", &text[..at], &text[end..]);
    let e = SeparableBrdf::from_toml(&bad, None).expect_err("1e200 refused");
    assert!(
        e.to_string()
            .contains("field `channel[0].term[0]`: values must be at most 1e100 in magnitude"),
        "{e}"
    );
}
