//! Every family's list of what stays unconfirmed (`<family>::UNCONFIRMED`, named by
//! `gonio instrument check --connect` and the self-test) is its doc's: the bullets of
//! the `## UNCONFIRMED` section of `docs/instruments/<family>.md`, in order, each
//! beginning with the fact's words.

use std::path::Path;

use gonio_proto::Unconfirmed;

/// The bullets of a doc's `## UNCONFIRMED` section, continuation lines joined.
fn bullets(family: &str) -> Vec<String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../docs/instruments")
        .join(format!("{family}.md"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
    let start = text
        .find("\n## UNCONFIRMED\n")
        .unwrap_or_else(|| panic!("{family}.md has no ## UNCONFIRMED section"));
    let section = &text[start + 1..];
    let section = &section[..section[3..].find("\n#").map_or(section.len(), |i| i + 3)];
    let mut out: Vec<String> = Vec::new();
    for line in section.lines().skip(1) {
        if let Some(item) = line.strip_prefix("- ") {
            out.push(item.to_string());
        } else if line.starts_with("  ") && !out.is_empty() {
            let last = out.last_mut().expect("an item");
            last.push(' ');
            last.push_str(line.trim());
        } else if !line.trim().is_empty() {
            // Prose after the list ends it.
            break;
        }
    }
    out
}

fn same(family: &str, facts: &[Unconfirmed]) {
    let items = bullets(family);
    assert_eq!(
        items.len(),
        facts.len(),
        "{family}.md lists {items:#?}; the code {facts:#?}"
    );
    for (item, u) in items.iter().zip(facts) {
        assert!(
            item.starts_with(u.fact),
            "{family}.md: {item:?} does not begin with {:?}",
            u.fact
        );
        assert!(
            !u.check.trim().is_empty(),
            "{family}: {:?} says no check",
            u.fact
        );
    }
}

#[test]
fn each_familys_unconfirmed_facts_are_its_docs() {
    same("smc100", gonio_proto::smc100::UNCONFIRMED);
    same("apt", gonio_proto::apt::UNCONFIRMED);
    same("sr830", gonio_proto::sr830::UNCONFIRMED);
    same("k6485", gonio_proto::k6485::UNCONFIRMED);
    same("cs130", gonio_proto::cs130::UNCONFIRMED);
    same("fw102c", gonio_proto::fw102c::UNCONFIRMED);
}
