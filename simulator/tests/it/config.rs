//! The simulator config's limits: every number has a finite range, and a value
//! outside it is refused with its field, line and the limit (docs/simulator.md,
//! "Limits") before anything runs. `start_position = nan` used to abort the process in
//! the middle of an acquisition; `time_scale = 1e308` panicked in a step's task.

use gonio_sim::SimConfig;
use gonio_sim::config::DEFAULT_SIM;

/// The default config with `from` replaced by `to` (which must occur).
fn with(from: &str, to: &str) -> String {
    assert!(
        DEFAULT_SIM.contains(from),
        "{from:?} not in the default config"
    );
    DEFAULT_SIM.replacen(from, to, 1)
}

/// The line of the first occurrence of `needle` in `text`, 1-based.
fn line_of(text: &str, needle: &str) -> usize {
    let at = text.find(needle).expect("needle in text");
    text[..at].matches('\n').count() + 1
}

#[test]
fn numbers_outside_their_range_are_refused_naming_field_line_and_limit() {
    let cases: Vec<(String, &str, &str, &str)> = vec![
        (
            with("start_position = 12.5", "start_position = nan"),
            "start_position = nan",
            "controllers[0].start_position",
            "must be finite, got NaN",
        ),
        (
            with("time_scale = 0.0", "time_scale = 1e308"),
            "time_scale = 1e308",
            "time_scale",
            "must be at most 1000, got 1e308",
        ),
        (
            with(
                "start_position = -40.0",
                "start_position = -40.0\nvelocity = 0.0",
            ),
            "velocity = 0.0",
            "controllers[1].velocity",
            "must be at least 1e-6 units/s, got 0",
        ),
        (
            with(
                "positive_limit = 180.0",
                "positive_limit = 180.0\nhome_timeout_s = 1e20",
            ),
            "home_timeout_s = 1e20",
            "controllers[2].home_timeout_s",
            "must be at most 3600 s, got 1e20",
        ),
        (
            with("source_power_w = 1e-3", "source_power_w = inf"),
            "source_power_w = inf",
            "optics.source_power_w",
            "must be finite, got inf",
        ),
        (
            with("pickup_v = 0.0", "pickup_v = 0.0\ndrift_per_hour = 50.0"),
            "drift_per_hour = 50.0",
            "optics.drift_per_hour",
            "must be at most 1, got 50",
        ),
        (
            with("shot_noise = 2e-6", "shot_noise = 2e-6\nphase_deg = 1e9"),
            "phase_deg = 1e9",
            "lockin.phase_deg",
            "must be at most 360 deg, got 1e9",
        ),
        (
            format!("{DEFAULT_SIM}\n[faults]\nreply_delay_s = nan\n"),
            "reply_delay_s = nan",
            "faults.reply_delay_s",
            "must be finite, got NaN",
        ),
        (
            format!("{DEFAULT_SIM}\n[[faults.overload]]\nfrom_s = 10.0\nto_s = 5.0\n"),
            "to_s = 5.0",
            "faults.overload[0].to_s",
            "must not be before `from_s`",
        ),
        (
            format!("{DEFAULT_SIM}\n[link]\nmotion_baud = 0\n"),
            "motion_baud = 0",
            "link.motion_baud",
            "must be at least 50 baud, got 0",
        ),
        (
            with(
                "[sample]                       # the embedded blue paint when no model is given",
                "[sample.micro]\nsurface = \"s.toml\"\nrays = 18446744073709551615",
            ),
            "rays = 18446744073709551615",
            "sample.micro.rays",
            "must be at most 1000000000 rays, got 18446744073709551615",
        ),
        (
            with(
                "[sample]                       # the embedded blue paint when no model is given",
                "[sample.micro]\nsurface = \"s.toml\"\ngrid = [0.001, 0.001]",
            ),
            "grid = [0.001, 0.001]",
            "sample.micro.grid",
            "0.001,0.001 makes a grid of 1.05e21 nodes, more than the 33554432 a grid may \
             have (the finest is about 2.5,2.5)",
        ),
    ];
    for (text, at, field, message) in cases {
        let e = SimConfig::from_toml(&text, None).expect_err(at);
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert_eq!(e.line, Some(line_of(&text, at)), "{e}");
        assert_eq!(e.message, message, "{at}");
    }
    // The default itself is within every range.
    SimConfig::from_toml(DEFAULT_SIM, None).expect("the default config");
}

#[cfg(unix)]
#[test]
fn a_config_that_is_not_a_regular_file_is_refused_unread() {
    let e = SimConfig::load(std::path::Path::new("/dev/zero")).expect_err("a device");
    assert_eq!(
        e.to_string(),
        "/dev/zero: a character device, not a regular file (Gonio reads its inputs from \
         regular files only)"
    );
}
