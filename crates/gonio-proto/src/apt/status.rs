//! The status bits of `MGMSG_MOT_GET_DCSTATUSUPDATE`, `MOT_GET_STATUSUPDATE`,
//! `MOT_GET_STATUSBITS` and the long `MOVE_COMPLETED`/`MOVE_STOPPED` (the manual's
//! status-bit table under `MGMSG_MOT_GET_STATUSUPDATE`). Controllers set only the bits
//! that apply to them; the KDC101 documents the limit, motion, homing, tracking,
//! settled, motion-error, current-limit and enabled bits.

/// Forward (clockwise) hardware limit switch active.
pub const FWD_HW_LIMIT: u32 = 0x0000_0001;
/// Reverse (counter-clockwise) hardware limit switch active.
pub const REV_HW_LIMIT: u32 = 0x0000_0002;
/// Forward software limit reached.
pub const FWD_SW_LIMIT: u32 = 0x0000_0004;
/// Reverse software limit reached.
pub const REV_SW_LIMIT: u32 = 0x0000_0008;
/// Moving forward.
pub const MOVING_FWD: u32 = 0x0000_0010;
/// Moving in reverse.
pub const MOVING_REV: u32 = 0x0000_0020;
/// Jogging forward.
pub const JOGGING_FWD: u32 = 0x0000_0040;
/// Jogging in reverse.
pub const JOGGING_REV: u32 = 0x0000_0080;
/// Motor connected.
pub const CONNECTED: u32 = 0x0000_0100;
/// A home search is under way.
pub const HOMING: u32 = 0x0000_0200;
/// The stage has been homed (its position counter is referenced).
pub const HOMED: u32 = 0x0000_0400;
/// Initialising.
pub const INITIALISING: u32 = 0x0000_0800;
/// Tracking: the position is within the tracking window of the target.
pub const TRACKING: u32 = 0x0000_1000;
/// Settled: the position has stayed within the settle window.
pub const SETTLED: u32 = 0x0000_2000;
/// Motion error: the position error exceeded its limit (a stalled or blocked stage).
pub const MOTION_ERROR: u32 = 0x0000_4000;
/// Instrument error.
pub const INSTRUMENT_ERROR: u32 = 0x0000_8000;
/// Interlock open.
pub const INTERLOCK: u32 = 0x0001_0000;
/// Over temperature.
pub const OVER_TEMP: u32 = 0x0002_0000;
/// Supply voltage fault.
pub const VOLTAGE_FAULT: u32 = 0x0004_0000;
/// Commutation error.
pub const COMMUTATION_ERROR: u32 = 0x0008_0000;
/// The motor current limit was reached.
pub const CURRENT_LIMIT: u32 = 0x0100_0000;
/// Encoder fault.
pub const ENCODER_FAULT: u32 = 0x0200_0000;
/// Over current.
pub const OVER_CURRENT: u32 = 0x0400_0000;
/// Bus current fault.
pub const BUS_CURRENT_FAULT: u32 = 0x0800_0000;
/// Power supply good.
pub const POWER_OK: u32 = 0x1000_0000;
/// Active (a move is in progress).
pub const ACTIVE: u32 = 0x2000_0000;
/// Error.
pub const ERROR: u32 = 0x4000_0000;
/// The channel (motor drive) is enabled.
pub const CHANNEL_ENABLED: u32 = 0x8000_0000;

/// Any motion bit: moving or jogging, either way, or homing.
pub const MOTION: u32 = MOVING_FWD | MOVING_REV | JOGGING_FWD | JOGGING_REV | HOMING;
/// Either hardware limit switch.
pub const HW_LIMITS: u32 = FWD_HW_LIMIT | REV_HW_LIMIT;
/// The bits that mean the drive itself is in fault.
pub const FAULTS: u32 = MOTION_ERROR
    | INSTRUMENT_ERROR
    | OVER_TEMP
    | VOLTAGE_FAULT
    | COMMUTATION_ERROR
    | ENCODER_FAULT
    | OVER_CURRENT
    | BUS_CURRENT_FAULT;

/// The names of the bits set in `bits`, for messages.
pub fn describe(bits: u32) -> Vec<&'static str> {
    const NAMES: [(u32, &str); 28] = [
        (FWD_HW_LIMIT, "forward limit switch"),
        (REV_HW_LIMIT, "reverse limit switch"),
        (FWD_SW_LIMIT, "forward software limit"),
        (REV_SW_LIMIT, "reverse software limit"),
        (MOVING_FWD, "moving forward"),
        (MOVING_REV, "moving reverse"),
        (JOGGING_FWD, "jogging forward"),
        (JOGGING_REV, "jogging reverse"),
        (CONNECTED, "motor connected"),
        (HOMING, "homing"),
        (HOMED, "homed"),
        (INITIALISING, "initialising"),
        (TRACKING, "tracking"),
        (SETTLED, "settled"),
        (MOTION_ERROR, "motion error"),
        (INSTRUMENT_ERROR, "instrument error"),
        (INTERLOCK, "interlock"),
        (OVER_TEMP, "over temperature"),
        (VOLTAGE_FAULT, "voltage fault"),
        (COMMUTATION_ERROR, "commutation error"),
        (CURRENT_LIMIT, "current limit"),
        (ENCODER_FAULT, "encoder fault"),
        (OVER_CURRENT, "over current"),
        (BUS_CURRENT_FAULT, "bus current fault"),
        (POWER_OK, "power ok"),
        (ACTIVE, "active"),
        (ERROR, "error"),
        (CHANNEL_ENABLED, "channel enabled"),
    ];
    NAMES
        .iter()
        .filter(|(m, _)| bits & m != 0)
        .map(|(_, n)| *n)
        .collect()
}
