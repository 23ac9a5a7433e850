//! The simulated FW102C alone (`gonio_sim::filterwheel`), byte for byte on virtual
//! time: echo, answers, prompts, moves, refusals, transmittance, config checks.

use gonio_proto::fw102c::PROMPT;
use gonio_sim::filterwheel::{FilterWheelSim, Fw102cTwin};
use gonio_sim::twin::TimedLine;

/// A wheel just powered up, its power-up prompt already read.
fn wheel() -> Fw102cTwin {
    let mut w = Fw102cTwin::new(&FilterWheelSim::default());
    let mut out = Vec::new();
    w.poll(0.0, &mut out);
    assert_eq!(out, PROMPT);
    w
}

/// Sends `tx` at `t` and returns what comes back by `t`.
fn exchange(w: &mut Fw102cTwin, t: f64, tx: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    w.receive(t, tx, &mut out);
    out
}

#[test]
fn queries_echo_answer_and_prompt() {
    let mut w = wheel();
    assert_eq!(
        exchange(&mut w, 0.0, b"*idn?\r"),
        b"*idn?\rTHORLABS FW102C/FW212C Filter Wheel version 1.04\r> "
    );
    assert_eq!(exchange(&mut w, 0.1, b"pos?\r"), b"pos?\r1\r> ");
    assert_eq!(exchange(&mut w, 0.2, b"pcount?\r"), b"pcount?\r6\r> ");
    assert_eq!(exchange(&mut w, 0.3, b"speed=0\r"), b"speed=0\r> ");
    assert_eq!(exchange(&mut w, 0.4, b"speed?\r"), b"speed?\r0\r> ");
    assert_eq!(exchange(&mut w, 0.5, b"sensors=0\r"), b"sensors=0\r> ");
    assert_eq!(exchange(&mut w, 0.6, b"sensors?\r"), b"sensors?\r0\r> ");
    assert_eq!(exchange(&mut w, 0.7, b"trig?\r"), b"trig?\r0\r> ");
    assert_eq!(exchange(&mut w, 0.8, b"save\r"), b"save\r> ");
}

#[test]
fn power_up_sends_the_prompt_once() {
    let mut w = Fw102cTwin::new(&FilterWheelSim::default());
    assert_eq!(w.next_event(), Some(0.0));
    // Unread, it comes before the first answer.
    assert_eq!(exchange(&mut w, 1.0, b"pos?\r"), b"> pos?\r1\r> ");
    assert_eq!(w.next_event(), None);
    assert_eq!(exchange(&mut w, 2.0, b"pos?\r"), b"pos?\r1\r> ");
}

#[test]
fn upper_case_is_not_a_command() {
    let mut w = wheel();
    for line in [&b"*IDN?\r"[..], b"POS=3\r", b"Pos?\r", b"Trig?\r"] {
        let mut want = line.to_vec();
        want.extend_from_slice(b"Command error CMD_NOT_DEFINED\r> ");
        assert_eq!(exchange(&mut w, 0.0, line), want);
    }
    assert_eq!(w.position_at(0.0), Some(1), "POS=3 did not move");
    assert_eq!(exchange(&mut w, 0.0, b" pos? \r"), b" pos? \r1\r> ");
}

#[test]
fn baud_is_recorded_and_read_back() {
    let mut w = wheel();
    assert_eq!(w.baud(), 1, "115200 from the factory");
    assert_eq!(exchange(&mut w, 0.0, b"baud?\r"), b"baud?\r1\r> ");
    assert_eq!(exchange(&mut w, 0.0, b"baud=0\r"), b"baud=0\r> ");
    assert_eq!(w.baud(), 0);
    assert_eq!(exchange(&mut w, 0.0, b"baud?\r"), b"baud?\r0\r> ");
    assert_eq!(
        exchange(&mut w, 0.0, b"baud=2\r"),
        b"baud=2\rCommand error CMD_ARG_INVALID\r> "
    );
    assert_eq!(
        exchange(&mut w, 0.0, b"BAUD=1\r"),
        b"BAUD=1\rCommand error CMD_NOT_DEFINED\r> "
    );
    assert_eq!(w.baud(), 0);
}

#[test]
fn refusals_carry_the_codes() {
    let mut w = wheel();
    assert_eq!(
        exchange(&mut w, 0.0, b"\r"),
        b"\rCommand error CMD_NOT_DEFINED\r> "
    );
    assert_eq!(
        exchange(&mut w, 0.0, b"home\r"),
        b"home\rCommand error CMD_NOT_DEFINED\r> "
    );
    assert_eq!(
        exchange(&mut w, 0.0, b"pos=7\r"),
        b"pos=7\rCommand error CMD_ARG_INVALID\r> "
    );
    assert_eq!(
        exchange(&mut w, 0.0, b"speed=3\r"),
        b"speed=3\rCommand error CMD_ARG_INVALID\r> "
    );
    assert_eq!(w.position_at(0.0), Some(1));
}

#[test]
fn a_move_sends_its_prompt_when_it_stops_and_holds_later_bytes() {
    let mut w = wheel();
    // 1 → 5 on 6 positions: 2 slots the short way (1 → 6 → 5), 0.5 s each.
    assert_eq!(exchange(&mut w, 1.0, b"pos=5\r"), b"pos=5\r");
    assert!((w.move_time(1, 5) - 1.0).abs() < 1e-12);
    assert_eq!(w.busy_until(), 2.0);
    assert_eq!(w.position_at(1.5), None);
    // Sent during the move: read when it stops.
    assert_eq!(exchange(&mut w, 1.2, b"pos?\r"), b"");
    assert_eq!(w.next_event(), Some(2.0));
    let mut out = Vec::new();
    w.poll(1.999, &mut out);
    assert!(out.is_empty());
    w.poll(2.0, &mut out);
    assert_eq!(out, b"> pos?\r5\r> ");
    assert_eq!(w.next_event(), None);
    assert_eq!(w.position_at(2.0), Some(5));
    // Low speed: 5 → 2 is 3 slots at 1 s.
    exchange(&mut w, 3.0, b"speed=0\r");
    exchange(&mut w, 3.0, b"pos=2\r");
    assert_eq!(w.busy_until(), 6.0);
    // pos= of the present position does not move.
    let mut out = Vec::new();
    w.poll(6.0, &mut out);
    assert_eq!(exchange(&mut w, 6.5, b"pos=2\r"), b"pos=2\r> ");
    assert_eq!(w.busy_until(), 6.0);
}

#[test]
fn transmittance_follows_the_filter_formulas() {
    let config: FilterWheelSim = toml::from_str(
        r#"
        longpass_rise_nm = 8.0
        [[filters]]
        position = 2
        kind = "bandpass"
        centre_nm = 550
        fwhm_nm = 10
        peak_transmittance = 0.8
        [[filters]]
        position = 3
        kind = "longpass"
        cut_on_nm = 495
        [[filters]]
        position = 4
        kind = "dark"
        "#,
    )
    .unwrap();
    config.validate().unwrap();
    let mut w = Fw102cTwin::new(&config);
    // Position 1: no filter listed, an empty aperture.
    assert_eq!(w.transmittance(550.0, 0.0), 1.0);
    exchange(&mut w, 0.0, b"pos=2\r");
    assert_eq!(w.transmittance(550.0, 0.25), 0.0, "blocked while turning");
    let t = 0.5;
    assert!((w.transmittance(550.0, t) - 0.8).abs() < 1e-12);
    // Half the peak at ± FWHM/2, 1/16 of it at ± FWHM.
    assert!((w.transmittance(555.0, t) - 0.4).abs() < 1e-12);
    assert!((w.transmittance(540.0, t) - 0.05).abs() < 1e-12);
    exchange(&mut w, 1.0, b"pos=3\r");
    let t = 1.5;
    assert!((w.transmittance(495.0, t) - 0.5).abs() < 1e-12);
    // 10 % and 90 % at cut-on ∓ rise/2.
    assert!((w.transmittance(491.0, t) - 0.1).abs() < 1e-12);
    assert!((w.transmittance(499.0, t) - 0.9).abs() < 1e-12);
    exchange(&mut w, 2.0, b"pos=4\r");
    assert_eq!(w.transmittance(600.0, 2.5), 0.0);
}

#[test]
fn bad_sim_values_name_their_field() {
    let field = |text: &str| match toml::from_str::<FilterWheelSim>(text) {
        Ok(c) => c.validate().unwrap_err().field,
        Err(e) => format!("parse: {e}"),
    };
    assert_eq!(field("positions = 10"), "positions");
    assert_eq!(field("initial_position = 7"), "initial_position");
    assert_eq!(field("slot_time_low_s = 0"), "slot_time_low_s");
    assert_eq!(field("latency_s = -1"), "latency_s");
    assert_eq!(
        field("[[filters]]\nposition = 9\nkind = \"dark\""),
        "filters[0].position"
    );
    assert!(toml::from_str::<FilterWheelSim>("colour = 1").is_err());
}
