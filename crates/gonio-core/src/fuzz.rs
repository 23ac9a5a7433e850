//! Hostile variations of good input files, for the property tests and `fuzz/` targets
//! that check that no loader panics on what a user might type.
//!
//! Random bytes rarely get past a TOML or CSV reader's first line, so they say little
//! about the code behind it. [`mutate`] starts from a file that loads and makes the
//! changes people and tools make: a number replaced by a hostile one ([`HOSTILE`]:
//! `nan`, `inf`, `-0`, `1e308`, integers past `u64`, negatives, a string), a line
//! deleted or given twice (a key repeated, a row duplicated), lines swapped, a byte
//! order mark in front, the file cut short.

use crate::rng::SplitMix64;

/// Values that break careless numeric code, as they would be typed.
pub const HOSTILE: &[&str] = &[
    "nan",
    "-nan",
    "NaN",
    "inf",
    "-inf",
    "+inf",
    "-0",
    "-0.0",
    "0",
    "0.0",
    "1e308",
    "-1e308",
    "1e309",
    "5e-324",
    "1e-320",
    "-1",
    "-1e9",
    "1e9",
    "255",
    "256",
    "4294967296",
    "2147483648",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "99999999999999999999999",
    "0x7fffffffffffffff",
    "1_000_000_000",
    "\"x\"",
    "\"\"",
    "[]",
    "{}",
    "true",
    "x",
    "",
];

/// The byte order mark.
const BOM: &str = "\u{feff}";

/// `text` with one change for each seed, in turn (the same seeds, the same result).
/// A change that would take the text past twice its first length (plus 1 KiB) is
/// skipped: repeated lines would otherwise grow it exponentially, and a file's size is
/// no part of what the changes are for.
pub fn mutate(text: &str, seeds: &[u64]) -> String {
    let limit = 2 * text.len() + 1024;
    let mut out = text.to_string();
    for &seed in seeds {
        let next = mutate_once(&out, seed);
        if next.len() <= limit {
            out = next;
        }
    }
    out
}

fn mutate_once(text: &str, seed: u64) -> String {
    let mut rng = SplitMix64::new(seed);
    let mut pick = |n: usize| (rng.next_u64() % n.max(1) as u64) as usize;
    match pick(10) {
        0..=4 => {
            let numbers = numbers(text);
            if numbers.is_empty() {
                return format!("{BOM}{text}");
            }
            let at = numbers[pick(numbers.len())].clone();
            let with = HOSTILE[pick(HOSTILE.len())];
            format!("{}{with}{}", &text[..at.start], &text[at.end..])
        }
        5 => edit_lines(text, |lines| {
            if !lines.is_empty() {
                let i = pick(lines.len());
                lines.remove(i);
            }
        }),
        6 => {
            let mut lines: Vec<String> = text.split_inclusive('\n').map(str::to_string).collect();
            if !lines.is_empty() {
                let i = pick(lines.len());
                // The last line may lack its newline; its copy must not run into it.
                let copy = if lines[i].ends_with('\n') {
                    lines[i].clone()
                } else {
                    format!("{}\n", lines[i])
                };
                lines.insert(i, copy);
            }
            lines.concat()
        }
        7 => edit_lines(text, |lines| {
            if !lines.is_empty() {
                let (i, j) = (pick(lines.len()), pick(lines.len()));
                lines.swap(i, j);
            }
        }),
        8 => format!("{BOM}{text}"),
        _ => {
            let mut cut = pick(text.len() + 1);
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            text[..cut].to_string()
        }
    }
}

fn edit_lines(text: &str, edit: impl FnOnce(&mut Vec<&str>)) -> String {
    let mut lines: Vec<&str> = text.split_inclusive('\n').collect();
    edit(&mut lines);
    lines.concat()
}

/// The byte ranges of the numbers in `text`: a digit (after a sign or a point, if
/// any) and what can follow one in a number.
fn numbers(text: &str) -> Vec<std::ops::Range<usize>> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let start = i;
        let mut j = i;
        while j < b.len() && matches!(b[j], b'-' | b'+' | b'.') {
            j += 1;
        }
        if j < b.len() && b[j].is_ascii_digit() && j - start <= 2 {
            while j < b.len()
                && matches!(b[j], b'0'..=b'9' | b'.' | b'e' | b'E' | b'_' | b'+' | b'-')
            {
                j += 1;
            }
            out.push(start..j);
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_found_whole() {
        let t = "a = [-1.5e3, 2]\nb = 550nm\n";
        let got: Vec<&str> = numbers(t).into_iter().map(|r| &t[r]).collect();
        assert_eq!(got, ["-1.5e3", "2", "550"]);
    }

    #[test]
    fn mutations_are_deterministic_and_change_the_text() {
        let t = "x = 1\ny = 2.5\n[t]\nz = [3, 4]\n";
        let mut changed = 0;
        for seed in 0..200 {
            let a = mutate(t, &[seed, seed ^ 7]);
            assert_eq!(a, mutate(t, &[seed, seed ^ 7]));
            changed += usize::from(a != t);
        }
        // A mutation can undo itself (a line swapped with itself), but rarely.
        assert!(changed > 150, "{changed}");
    }

    #[test]
    fn the_text_never_grows_past_twice_its_length() {
        let t = "a = 1\nb = [2, 3]";
        for seed in 0..100u64 {
            let seeds: Vec<u64> = (0..64).map(|k| seed * 64 + k).collect();
            assert!(mutate(t, &seeds).len() <= 2 * t.len() + 1024);
        }
        // A repeated last line keeps its own line.
        let seed = (0..10_000u64)
            .find(|s| {
                let m = mutate(t, &[*s]);
                m.len() > t.len()
                    && m.ends_with("b = [2, 3]")
                    && m.matches("b = [2, 3]").count() == 2
            })
            .expect("some seed repeats the last line");
        assert_eq!(mutate(t, &[seed]), "a = 1\nb = [2, 3]\nb = [2, 3]");
    }
}
