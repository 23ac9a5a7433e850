//! The crate map holds (ARCHITECTURE.md): the pure crates have no SQLite, tokio or
//! serial port anywhere in their dependency trees, the run engine does not depend on
//! the simulator, each crate depends only on crates below it in the map, the
//! simulator's library parses no arguments, and no two modules of a crate import
//! each other, directly or around a loop.
//!
//! Read from `cargo metadata` (the resolved graph, normal dependencies only) and
//! from the sources.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The crates, ground floor first: each may depend only on crates before it.
const MAP: [&str; 18] = [
    "gonio-core",
    "gonio-brdf",
    "gonio-proto",
    "gonio-driver",
    "gonio-plan",
    "gonio-run",
    "gonio-acquire",
    "gonio-process",
    "gonio-reduce",
    "gonio-fit",
    "gonio-micro",
    "gonio-io",
    "gonio-dataset",
    "gonio-live",
    "gonio-sim",
    "gonio-cli",
    "gonio-py",
    "gonio-e2e",
];

/// The crates that must stay pure.
const PURE: [&str; 8] = [
    "gonio-core",
    "gonio-brdf",
    "gonio-proto",
    "gonio-plan",
    "gonio-process",
    "gonio-fit",
    "gonio-micro",
    "gonio-io",
];

/// What no pure crate may reach.
const IMPURE: [&str; 3] = ["rusqlite", "tokio", "serialport"];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Package name → names of its normal (non-dev, non-build) dependencies, for every
/// package in the resolved graph with default features.
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--offline",
            "--manifest-path",
        ])
        .arg(root().join("Cargo.toml"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata JSON");
    let names: BTreeMap<String, String> = v["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| {
            (
                p["id"].as_str().unwrap_or_default().to_string(),
                p["name"].as_str().unwrap_or_default().to_string(),
            )
        })
        .collect();
    let mut g = BTreeMap::new();
    for node in v["resolve"]["nodes"].as_array().expect("resolve") {
        let name = names[node["id"].as_str().unwrap_or_default()].clone();
        let deps: BTreeSet<String> = node["deps"]
            .as_array()
            .expect("deps")
            .iter()
            .filter(|d| {
                d["dep_kinds"]
                    .as_array()
                    .is_some_and(|k| k.iter().any(|k| k["kind"].is_null()))
            })
            .map(|d| names[d["pkg"].as_str().unwrap_or_default()].clone())
            .collect();
        g.insert(name, deps);
    }
    g
}

/// Everything `name` reaches through normal dependencies.
fn reach(g: &BTreeMap<String, BTreeSet<String>>, name: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut stack = vec![name.to_string()];
    while let Some(n) = stack.pop() {
        for d in g.get(&n).into_iter().flatten() {
            if seen.insert(d.clone()) {
                stack.push(d.clone());
            }
        }
    }
    seen
}

#[test]
fn pure_crates_reach_no_sqlite_tokio_or_serial_port() {
    let g = graph();
    for c in PURE {
        assert!(g.contains_key(c), "{c} is not in the workspace");
        let r = reach(&g, c);
        for bad in IMPURE {
            assert!(!r.contains(bad), "{c} reaches {bad}");
        }
    }
    // The one crate that depends on SQLite.
    let direct: Vec<&String> = g
        .iter()
        .filter(|(n, d)| n.starts_with("gonio") && d.contains("rusqlite"))
        .map(|(n, _)| n)
        .collect();
    assert_eq!(
        direct,
        ["gonio-run"],
        "crates depending on rusqlite directly"
    );
}

#[test]
fn the_run_engine_does_not_depend_on_the_simulator() {
    let g = graph();
    assert!(!reach(&g, "gonio-acquire").contains("gonio-sim"));
    assert!(!reach(&g, "gonio-reduce").contains("gonio-sim"));
    assert!(!reach(&g, "gonio-live").contains("gonio-sim"));
}

#[test]
fn the_live_view_serves_nothing_from_disk() {
    // Its page is compiled in (`include_str!`), and the run file is read through
    // `gonio-run`: no file system call in its sources, so no route can reach a
    // path.
    for f in rust_files(&root().join("crates/gonio-live/src")) {
        let text = std::fs::read_to_string(&f).expect("source");
        for call in ["std::fs", "File::open", "fs::read", "ServeDir", "ServeFile"] {
            assert!(!text.contains(call), "{} uses {call}", f.display());
        }
    }
}

#[test]
fn each_crate_depends_only_on_crates_below_it() {
    let g = graph();
    for (i, c) in MAP.iter().enumerate() {
        let Some(deps) = g.get(*c) else { continue };
        for d in deps.iter().filter(|d| d.starts_with("gonio-")) {
            let j = MAP
                .iter()
                .position(|m| m == d)
                .unwrap_or_else(|| panic!("{d} is not on the map"));
            assert!(j < i, "{c} depends on {d}, which is not below it");
        }
    }
}

#[test]
fn the_simulator_library_parses_no_arguments() {
    let lib = root().join("simulator/src");
    for f in rust_files(&lib) {
        if f.file_name().is_some_and(|n| n == "main.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&f).expect("source");
        assert!(!text.contains("clap"), "{} uses clap", f.display());
        assert!(
            !text.contains("std::env::args"),
            "{} reads arguments",
            f.display()
        );
    }
    // Nor does the gonio binary re-read them behind clap's back.
    for f in rust_files(&root().join("crates/gonio-cli/src")) {
        let text = std::fs::read_to_string(&f).expect("source");
        assert!(
            !text.contains("env::args"),
            "{} re-reads the process arguments",
            f.display()
        );
    }
}

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The module path (`a::b`) of a source file under `src`.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file
        .strip_prefix(src)
        .expect("under src")
        .with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts.join("::")
}

/// Which modules of the crate at `src` depend on which, through the `crate::` and
/// `super::` paths their code (tests and comments aside) names. A dependency of `a::x`
/// on `b::y` is one of `a` on `b`: the loop that matters is between the two siblings
/// (`api` using `cmd` while `cmd::acquire` uses `api` is a loop).
fn imports(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let files = rust_files(src);
    let mods: BTreeSet<String> = files.iter().map(|f| module_of(src, f)).collect();
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in &files {
        let m = module_of(src, f);
        let here: Vec<&str> = m.split("::").filter(|p| !p.is_empty()).collect();
        let text = std::fs::read_to_string(f).expect("source");
        let code: String = text
            .split("#[cfg(test)]")
            .next()
            .unwrap_or("")
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        for (prefix, base) in [("crate::", 0), ("super::", here.len().saturating_sub(1))] {
            for (i, _) in code.match_indices(prefix) {
                if code[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == ':') {
                    continue;
                }
                let path: String = code[i + prefix.len()..]
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                    .collect();
                let mut parts: Vec<&str> = here[..base].to_vec();
                parts.extend(path.split("::").filter(|p| !p.is_empty()));
                // The longest prefix that is a module of the crate.
                let Some(k) = (1..=parts.len())
                    .rev()
                    .find(|&k| mods.contains(&parts[..k].join("::")))
                else {
                    continue;
                };
                let common = here
                    .iter()
                    .zip(&parts[..k])
                    .take_while(|(a, b)| a == b)
                    .count();
                // A module may use its own children and ancestors' items freely.
                if common == here.len() || common == k {
                    continue;
                }
                let (a, b) = (here[..=common].join("::"), parts[..=common].join("::"));
                g.entry(a).or_default().insert(b);
            }
        }
        g.entry(m).or_default();
    }
    g
}

/// The strongly connected components with more than one module (Tarjan).
fn loops(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a str) {
        t.index.insert(v, t.next);
        t.low.insert(v, t.next);
        t.next += 1;
        t.stack.push(v);
        t.on.insert(v);
        let g = t.g;
        for w in g.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low[v];
                t.low.insert(v, lv.min(lw));
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low[v];
                t.low.insert(v, lv.min(iw));
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in g.keys() {
        if !t.index.contains_key(v.as_str()) {
            visit(&mut t, v);
        }
    }
    t.out
}

#[test]
fn the_loop_finder_finds_loops() {
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a", vec!["b"]),
        ("b", vec!["c"]),
        ("c", vec!["a"]),
        ("d", vec!["a"]),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v.into_iter().map(String::from).collect()))
    .collect();
    assert_eq!(loops(&g), vec![vec!["a", "b", "c"]]);
}

#[test]
fn no_module_imports_loop() {
    let mut srcs: Vec<PathBuf> = std::fs::read_dir(root().join("crates"))
        .expect("crates")
        .flatten()
        .map(|e| e.path().join("src"))
        .filter(|p| p.is_dir())
        .collect();
    srcs.push(root().join("simulator/src"));
    srcs.sort();
    let mut found = Vec::new();
    for src in &srcs {
        for l in loops(&imports(src)) {
            found.push(format!("{}: {}", src.display(), l.join(" -> ")));
        }
    }
    assert!(found.is_empty(), "import loops:\n{}", found.join("\n"));
}

/// The tests' profile compiles every Gonio crate with a debug build's arithmetic
/// checks, and nothing else: a member without its `[profile.ci.package.NAME]` entry
/// would be tested without overflow checks, and a `package."*"` entry would also
/// override `build-override` and compile every proc macro optimised (Cargo.toml).
#[test]
fn the_tests_profile_checks_every_gonio_crate_and_only_those() {
    let path = root().join("Cargo.toml");
    let text = std::fs::read_to_string(&path).expect("Cargo.toml");
    let manifest: toml::Table = text.parse().expect("Cargo.toml parses");
    let packages = manifest["profile"]["ci"]["package"]
        .as_table()
        .expect("[profile.ci.package.*]");
    assert!(
        !packages.contains_key("*"),
        "[profile.ci.package.\"*\"] would take precedence over build-override"
    );
    for name in MAP {
        let p = packages
            .get(name)
            .unwrap_or_else(|| panic!("no [profile.ci.package.{name}] in Cargo.toml"));
        assert_eq!(p.get("opt-level"), Some(&toml::Value::Integer(1)), "{name}");
        for check in ["overflow-checks", "debug-assertions"] {
            assert_eq!(
                p.get(check),
                Some(&toml::Value::Boolean(true)),
                "{name} {check}"
            );
        }
    }
    let checked: Vec<&String> = packages
        .keys()
        .filter(|k| packages[k.as_str()].get("overflow-checks").is_some())
        .collect();
    assert_eq!(checked.len(), MAP.len(), "checked crates {checked:?}");
}
