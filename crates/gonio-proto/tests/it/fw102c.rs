//! FW102C codec against the manual (Rev H, §5.2 and p. 11): every command Gonio
//! encodes is lower case, and the power-up prompt in front of the first line is
//! stripped. (The UNCONFIRMED list is checked against the documentation in
//! `unconfirmed.rs`.)

use gonio_proto::fw102c::{Command, Line, PROMPT, SensorMode, Speed, TriggerMode, strip_prompt};

/// Every command the codec encodes, one of each value.
fn every_command() -> Vec<Command> {
    let mut all = vec![
        Command::Identify,
        Command::QueryPosition,
        Command::QueryPositionCount,
        Command::QuerySpeed,
        Command::QueryTrigger,
        Command::QuerySensors,
        Command::Save,
        Command::SetPositionCount(6),
        Command::SetPositionCount(12),
        Command::SetSpeed(Speed::Low),
        Command::SetSpeed(Speed::High),
        Command::SetTrigger(TriggerMode::Input),
        Command::SetTrigger(TriggerMode::Output),
        Command::SetSensors(SensorMode::OffWhenIdle),
        Command::SetSensors(SensorMode::AlwaysOn),
    ];
    all.extend((1..=12).map(Command::SetPosition));
    all
}

/// "All commands and queries are in lower case letters" (p. 11), and "must be
/// terminated by a carriage return" (§5.2).
#[test]
fn every_command_is_lower_case_and_ends_with_cr() {
    for c in every_command() {
        let bytes = c.to_bytes();
        assert!(!bytes.iter().any(u8::is_ascii_uppercase), "{c}");
        assert_eq!(bytes.last(), Some(&b'\r'), "{c}");
        assert_eq!(bytes.iter().filter(|b| **b == b'\r').count(), 1, "{c}");
    }
}

/// "The prompt symbol '>' will appear on power-up and after a command is accepted"
/// (User Guide Rev M): unterminated, it begins the first line the host reads, which is
/// the echo of its first command, and a line holding only it is blank, not an answer.
#[test]
fn the_power_up_prompt_is_stripped_from_the_first_line() {
    let mut first = PROMPT.to_vec();
    first.extend_from_slice(b"*idn?");
    assert_eq!(strip_prompt(&first), b"*idn?");
    assert_eq!(Line::classify(&first), Line::Text(b"*idn?"));
    // The manual's `>` alone, without Odemis's space, too.
    assert_eq!(Line::classify(b">*idn?"), Line::Text(b"*idn?"));
    assert_eq!(Line::classify(PROMPT), Line::Blank);
    assert_eq!(Line::classify(b">"), Line::Blank);
}
