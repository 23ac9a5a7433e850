//! The status bits of `MGMSG_MOT_GET_DCSTATUSUPDATE`, `MOT_GET_STATUSUPDATE`,
//! `MOT_GET_STATUSBITS` and the long `MOVE_COMPLETED`/`MOVE_STOPPED` (the manual's
//! status-bit table under `MGMSG_MOT_GET_STATUSUPDATE`). Controllers set only the bits
//! that apply to them; the KDC101 documents the limit, motion, homing, tracking,
//! settled, motion-error, current-limit and enabled bits.

crate::codec::status_bits! {
    u32;
    /// Forward (clockwise) hardware limit switch active.
    FWD_HW_LIMIT = 0x0000_0001 "forward limit switch",
    /// Reverse (counter-clockwise) hardware limit switch active.
    REV_HW_LIMIT = 0x0000_0002 "reverse limit switch",
    /// Forward software limit reached.
    FWD_SW_LIMIT = 0x0000_0004 "forward software limit",
    /// Reverse software limit reached.
    REV_SW_LIMIT = 0x0000_0008 "reverse software limit",
    /// Moving forward.
    MOVING_FWD = 0x0000_0010 "moving forward",
    /// Moving in reverse.
    MOVING_REV = 0x0000_0020 "moving reverse",
    /// Jogging forward.
    JOGGING_FWD = 0x0000_0040 "jogging forward",
    /// Jogging in reverse.
    JOGGING_REV = 0x0000_0080 "jogging reverse",
    /// Motor connected.
    CONNECTED = 0x0000_0100 "motor connected",
    /// A home search is under way.
    HOMING = 0x0000_0200 "homing",
    /// The stage has been homed (its position counter is referenced).
    HOMED = 0x0000_0400 "homed",
    /// Initialising.
    INITIALISING = 0x0000_0800 "initialising",
    /// Tracking: the position is within the tracking window of the target.
    TRACKING = 0x0000_1000 "tracking",
    /// Settled: the position has stayed within the settle window.
    SETTLED = 0x0000_2000 "settled",
    /// Motion error: the position error exceeded its limit (a stalled or blocked stage).
    MOTION_ERROR = 0x0000_4000 "motion error",
    /// Instrument error.
    INSTRUMENT_ERROR = 0x0000_8000 "instrument error",
    /// Interlock open.
    INTERLOCK = 0x0001_0000 "interlock",
    /// Over temperature.
    OVER_TEMP = 0x0002_0000 "over temperature",
    /// Supply voltage fault.
    VOLTAGE_FAULT = 0x0004_0000 "voltage fault",
    /// Commutation error.
    COMMUTATION_ERROR = 0x0008_0000 "commutation error",
    /// The motor current limit was reached.
    CURRENT_LIMIT = 0x0100_0000 "current limit",
    /// Encoder fault.
    ENCODER_FAULT = 0x0200_0000 "encoder fault",
    /// Over current.
    OVER_CURRENT = 0x0400_0000 "over current",
    /// Bus current fault.
    BUS_CURRENT_FAULT = 0x0800_0000 "bus current fault",
    /// Power supply good.
    POWER_OK = 0x1000_0000 "power ok",
    /// Active (a move is in progress).
    ACTIVE = 0x2000_0000 "active",
    /// Error.
    ERROR = 0x4000_0000 "error",
    /// The channel (motor drive) is enabled.
    CHANNEL_ENABLED = 0x8000_0000 "channel enabled",
}

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
    crate::codec::bit_names(bits, NAMES)
}
