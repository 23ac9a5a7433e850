//! The run file's schema: tables, migrations, the columns each row checksum covers,
//! and the reading flag bits. `docs/run-file.md` describes it for readers outside
//! Gonio.

/// `PRAGMA application_id` of a run file: "GONI".
pub const APPLICATION_ID: i32 = 0x474F_4E49;
/// The schema version this build writes.
pub const SCHEMA_VERSION: i32 = 1;

/// Migrations: entry `k` takes a file from version `k` to `k + 1`. Version 0 is an
/// empty database.
pub(crate) const MIGRATIONS: &[&str] = &[SCHEMA_V1];

const SCHEMA_V1: &str = "
CREATE TABLE meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE sessions (
    id          INTEGER PRIMARY KEY,
    started_s   REAL NOT NULL,
    ended_s     REAL,
    outcome     TEXT,
    software    TEXT NOT NULL,
    pid         INTEGER NOT NULL
);
CREATE TABLE steps (
    id          INTEGER PRIMARY KEY,
    kind        TEXT NOT NULL CHECK (kind IN ('sample','reference','dark','incident','standard')),
    channel     TEXT,
    repeat      INTEGER NOT NULL,
    plan_index  INTEGER,
    theta_i REAL, phi_i REAL, theta_o REAL, phi_o REAL,
    target_0 REAL, target_1 REAL, target_2 REAL, target_3 REAL,
    crc         INTEGER NOT NULL,
    state       TEXT NOT NULL DEFAULT 'pending' CHECK (state IN ('pending','done','failed')),
    attempts    INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE readings (
    step_id     INTEGER PRIMARY KEY REFERENCES steps(id),
    session     INTEGER NOT NULL REFERENCES sessions(id),
    cmd_0 REAL, cmd_1 REAL, cmd_2 REAL, cmd_3 REAL,
    pos_0 REAL, pos_1 REAL, pos_2 REAL, pos_3 REAL,
    theta_i REAL, phi_i REAL, theta_o REAL, phi_o REAL,
    sensitivity INTEGER NOT NULL,
    sensitivity_v REAL NOT NULL,
    time_constant INTEGER NOT NULL,
    time_constant_s REAL NOT NULL,
    slope_db INTEGER NOT NULL,
    r_mean REAL,
    r_std REAL,
    x_mean REAL,
    y_mean REAL,
    n INTEGER NOT NULL,
    autorange_steps INTEGER NOT NULL,
    lias INTEGER NOT NULL,
    flags INTEGER NOT NULL,
    retries INTEGER NOT NULL,
    physical_s REAL,
    wall_s REAL NOT NULL,
    crc INTEGER NOT NULL
);
CREATE TABLE events (
    id       INTEGER PRIMARY KEY,
    session  INTEGER REFERENCES sessions(id),
    wall_s   REAL NOT NULL,
    kind     TEXT NOT NULL,
    step_id  INTEGER,
    message  TEXT NOT NULL
);
";

/// The adaptive plans' decisions: one row per batch of steps a planner appended
/// after the schedule fixed at creation. Created with the first batch, in its
/// transaction, so that other runs' files stay as they were (and the schema version
/// with them); `docs/run-file.md` describes the columns.
pub(crate) const CREATE_DECISIONS: &str = "
CREATE TABLE IF NOT EXISTS decisions (
    id          INTEGER PRIMARY KEY,
    session     INTEGER REFERENCES sessions(id),
    wall_s      REAL NOT NULL,
    first_step  INTEGER NOT NULL,
    steps       INTEGER NOT NULL,
    points      INTEGER NOT NULL,
    method      TEXT NOT NULL,
    readings    INTEGER NOT NULL,
    digest      TEXT NOT NULL,
    detail      TEXT NOT NULL,
    crc         INTEGER NOT NULL
);
";

/// Columns of `decisions` covered by its checksum, in hashing order.
pub(crate) const DECISION_COLUMNS: &str =
    "id, session, wall_s, first_step, steps, points, method, readings, digest, detail";

/// True when the file has a `decisions` table (an adaptive run that appended a
/// batch).
pub(crate) fn has_decisions(conn: &rusqlite::Connection) -> rusqlite::Result<bool> {
    conn.query_row(
        "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'decisions'",
        [],
        |r| r.get::<_, i64>(0),
    )
    .map(|n| n > 0)
}

/// Columns of `steps` covered by its checksum, in hashing order.
pub(crate) const STEP_COLUMNS: &str = "id, kind, channel, repeat, plan_index, theta_i, phi_i, theta_o, \
     phi_o, target_0, target_1, target_2, target_3";
/// Columns of `readings` covered by its checksum, in hashing order.
pub(crate) const READING_COLUMNS: &str = "step_id, session, cmd_0, cmd_1, cmd_2, cmd_3, pos_0, pos_1, \
     pos_2, pos_3, theta_i, phi_i, theta_o, phi_o, sensitivity, sensitivity_v, time_constant, \
     time_constant_s, slope_db, r_mean, r_std, x_mean, y_mean, n, autorange_steps, lias, flags, \
     retries, physical_s, wall_s";

/// Sets the run's status.
pub(crate) const SET_STATUS: &str = "INSERT INTO meta (key, value) VALUES ('status', ?1) \
     ON CONFLICT(key) DO UPDATE SET value = excluded.value";
/// Logs an event.
pub(crate) const INSERT_EVENT: &str = "INSERT INTO events (session, wall_s, kind, step_id, message) \
     VALUES (?1, ?2, ?3, ?4, ?5)";

/// `flags` bits of a reading (bits 0–3 are the LIAS overload and unlock bits).
pub mod flags {
    /// LIAS bit 0: input or reserve overload.
    pub const INPUT_OVERLOAD: u32 = 1 << 0;
    /// LIAS bit 1: filter overload.
    pub const FILTER_OVERLOAD: u32 = 1 << 1;
    /// LIAS bit 2: output overload.
    pub const OUTPUT_OVERLOAD: u32 = 1 << 2;
    /// LIAS bit 3: reference unlock.
    pub const UNLOCK: u32 = 1 << 3;
    /// The read-back directions put the detector arm in the beam.
    pub const SHADOWED: u32 = 1 << 8;
    /// The read-back incidence makes the beam overfill the sample.
    pub const OVERFILLED: u32 = 1 << 9;
    /// The reading reached the plan's `reading.max_s` before its target precision:
    /// kept, with the precision it reached.
    pub const CAPPED: u32 = 1 << 10;
    /// Read to the plan's `[reading]` target: snapshots back to back (one serial
    /// exchange apart, not a time constant plus one), averaged over the window the
    /// settling rule chose. The reduction's snapshot correlation follows.
    pub const TARGETED: u32 = 1 << 11;
    /// Bits 12–15: a targeted reading taken through the SR830's data buffer holds its
    /// sample rate's `SRAT` index plus one (1 … 14), its samples 1/rate apart rather
    /// than one exchange; 0 for a reading by snapshots.
    pub const BUFFER_RATE: u32 = 0xF << 12;
    /// A targeted reading whose values are the settled values fitted through the
    /// filter's transient from all `n` of its snapshots (`gonio_proto`'s
    /// `sr830::target`), `r_std` the snapshot σ its whitened residuals estimate,
    /// rather than a settled window's means and scatter. The reduction's σ of the
    /// value follows (generalised least squares, not a mean).
    pub const FITTED: u32 = 1 << 16;
    /// Bits 17–28: a targeted reading by snapshots holds their mean interval, as the
    /// session's clock measured it, in units of 0.1 ms (1 … 4095, so up to 409.5 ms);
    /// 0 where it is not known (a file written before, a single snapshot, a reading
    /// through the buffer). The reduction's snapshot correlation follows it rather
    /// than the nominal exchange time.
    pub const SNAP_INTERVAL: u32 = 0xFFF << 17;
    /// Bits that say how a reading was taken, not that anything is wrong with it: a
    /// reading carrying only these is not "flagged".
    pub const HOW_READ: u32 = TARGETED | BUFFER_RATE | FITTED | SNAP_INTERVAL;

    /// The [`SNAP_INTERVAL`] bits of snapshots `interval_s` apart (to the nearest
    /// 0.1 ms); none for an interval that is not finite, under 0.05 ms or over 409.5 ms.
    pub fn snap_interval(interval_s: f64) -> u32 {
        let units = (interval_s * 1e4).round();
        if (1.0..=4095.0).contains(&units) {
            (units as u32) << 17
        } else {
            0
        }
    }

    /// The seconds between a targeted reading's snapshots, when `bits` holds a
    /// [`SNAP_INTERVAL`].
    pub fn snap_interval_s(bits: u32) -> Option<f64> {
        let units = (bits & SNAP_INTERVAL) >> 17;
        (units > 0).then(|| f64::from(units) * 1e-4)
    }

    /// The [`BUFFER_RATE`] bits of a reading through the buffer at `SRAT srat`
    /// (0 … 13; anything else, the triggered rate included, sets none).
    pub fn buffered(srat: u8) -> u32 {
        if srat <= 13 {
            (u32::from(srat) + 1) << 12
        } else {
            0
        }
    }

    /// The seconds between a buffered reading's samples (62.5 mHz × 2^srat), when
    /// `bits` holds a [`BUFFER_RATE`].
    pub fn buffer_interval_s(bits: u32) -> Option<f64> {
        let i = (bits & BUFFER_RATE) >> 12;
        (1..=14)
            .contains(&i)
            .then(|| 16.0 / f64::from(1u32 << (i - 1)))
    }

    /// True when `bits` holds a flag that questions the reading (any but
    /// [`HOW_READ`]'s).
    pub fn questioned(bits: u32) -> bool {
        bits & !HOW_READ != 0
    }

    /// Every bit with its name, in bit order.
    pub const NAMES: [(u32, &str); 9] = [
        (INPUT_OVERLOAD, "input overload"),
        (FILTER_OVERLOAD, "filter overload"),
        (OUTPUT_OVERLOAD, "output overload"),
        (UNLOCK, "unlock"),
        (SHADOWED, "shadowed"),
        (OVERFILLED, "overfilled"),
        (CAPPED, "capped"),
        (TARGETED, "targeted"),
        (FITTED, "fitted"),
    ];

    /// The names of the bits set in `bits`, joined by ", " (empty for none).
    pub fn text(bits: u32) -> String {
        NAMES
            .iter()
            .filter(|(b, _)| bits & b != 0)
            .map(|(_, n)| *n)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::flags;

    /// The bits are distinct, in bit order, the plan's cap is bit 10, named `capped`,
    /// and a targeted reading bit 11 (docs/run-file.md).
    #[test]
    fn flag_bits_are_distinct_ordered_and_capped_is_bit_10() {
        for w in flags::NAMES.windows(2) {
            assert!(w[0].0 < w[1].0, "{:?} before {:?}", w[0], w[1]);
        }
        let all = flags::NAMES.iter().fold(0u32, |acc, (b, _)| {
            assert_eq!(acc & b, 0, "bit {b:#x} named twice");
            acc | b
        });
        assert_eq!(all, 0b1_0000_1111_0000_1111);
        assert_eq!(flags::CAPPED, 1024);
        assert_eq!(flags::TARGETED, 2048);
        assert_eq!(flags::FITTED, 1 << 16);
        // The fields of how a reading was taken do not overlap one another or a name.
        let fields = [flags::BUFFER_RATE, flags::SNAP_INTERVAL];
        assert_eq!(fields[0] & fields[1], 0);
        assert!(fields.iter().all(|f| f & all == 0));
        // A snapshot interval: 39 ms is 390 units of 0.1 ms, read back exactly.
        let s = flags::TARGETED | flags::FITTED | flags::snap_interval(0.039);
        assert!(!flags::questioned(s));
        assert_eq!(flags::snap_interval_s(s), Some(390.0 * 1e-4));
        assert_eq!(
            flags::snap_interval_s(flags::snap_interval(0.4095)),
            Some(4095.0 * 1e-4)
        );
        assert_eq!(flags::snap_interval(0.41), 0);
        assert_eq!(flags::snap_interval(0.00004), 0);
        assert_eq!(flags::snap_interval_s(flags::TARGETED), None);
        assert_eq!(flags::text(flags::FITTED), "fitted");
        // A buffered reading at 64 Hz (SRAT 10) is not flagged; its samples 1/64 s apart.
        let b = flags::TARGETED | flags::buffered(10);
        assert!(!flags::questioned(b));
        assert_eq!(flags::buffer_interval_s(b), Some(1.0 / 64.0));
        assert_eq!(flags::buffer_interval_s(flags::buffered(0)), Some(16.0));
        assert_eq!(flags::buffer_interval_s(flags::TARGETED), None);
        assert_eq!(flags::buffered(14), 0);
        assert_eq!(
            flags::text(flags::SHADOWED | flags::CAPPED),
            "shadowed, capped"
        );
    }
}
