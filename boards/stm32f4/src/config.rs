//! The board's fixed configuration: servo period, step slot length, step
//! drive interface, table buffer size and the link's baud rate.
//!
//! Why constants and not a file: the board has no file system, and every
//! value here shapes a static buffer or a timer setting made once at start.
//! The servo period can be set at build time (`BOARD_SERVO_PERIOD_US`,
//! default 250 µs = 4 kHz, the machine file's `[emcmot] servo_period_ns`
//! default); it must equal the period the table was planned for.

use firmware_core::output::step_dir::StepConfig;

/// Servo period, µs (build-time `BOARD_SERVO_PERIOD_US`, default 250).
pub const SERVO_PERIOD_US: u32 = parse_u32(option_env!("BOARD_SERVO_PERIOD_US"), 250);

/// Servo period, ns.
pub const SERVO_PERIOD_NS: u32 = SERVO_PERIOD_US * 1_000;

/// Servo period, s (what `Interpolator::new` takes).
pub const SERVO_PERIOD_S: f64 = SERVO_PERIOD_US as f64 * 1e-6;

/// Length of one step slot, µs: the pulse timer's period. A step pulse is
/// high for one slot and low for at least one, so the slot must be at most
/// half the drives' shortest step period (1 / [`MAX_STEP_HZ`]) and at least
/// the pulse's high and low times.
pub const SLOT_US: u32 = 10;

/// Slots per servo period (the period must be a whole number of slots).
pub const SLOTS: usize = (SERVO_PERIOD_US / SLOT_US) as usize;

const _: () = assert!(
    SERVO_PERIOD_US.is_multiple_of(SLOT_US),
    "servo period not a whole number of slots"
);
const _: () = assert!(SLOTS >= 4 && SLOTS <= 255, "slots per period out of range");

/// The drives' largest step rate, steps/s.
pub const MAX_STEP_HZ: f64 = 50_000.0;

const _: () = assert!(
    2 * SLOT_US as u64 * MAX_STEP_HZ as u64 <= 1_000_000,
    "slot longer than half a step period"
);

/// The step and direction interface (LinuxCNC's `STEPLEN`, `STEPSPACE`,
/// `DIRSETUP`; pulse times are the machine file's `[stepgen]` defaults):
/// 200 steps/mm on every axis (200 full steps a turn, 16 microsteps, 16 mm
/// lead), 50 kHz at most.
pub const STEP_CONFIG: StepConfig = StepConfig {
    steps_per_mm: [200.0, 200.0, 200.0],
    max_step_hz: MAX_STEP_HZ,
    step_len_ns: 2_000,
    step_space_ns: 2_000,
    dir_setup_ns: 5_000,
    invert_dir: [false, false, false],
};

const _: () =
    assert!(STEP_CONFIG.step_len_ns <= SLOT_US * 1_000 && STEP_CONFIG.step_space_ns <= SLOT_US * 1_000);
const _: () = assert!(STEP_CONFIG.dir_setup_ns > 0 && STEP_CONFIG.dir_setup_ns <= SLOT_US * 1_000);

/// Bytes of RAM for a table received over the link (SRAM is 128 KiB; the
/// rest holds the interpolator, the stack and the HAL's state).
pub const TABLE_BUF_LEN: usize = 96 * 1024;

/// The link's baud rate (8N1). Bytes are taken one per interrupt at the
/// lowest priority, so a byte must not arrive faster than the longest
/// servo tick plus the pulse interrupts: 115,200 baud is 87 µs a byte.
pub const LINK_BAUD: u32 = 115_200;

/// Ticks the feed-hold input must read one level in a row before it
/// counts (2 ms at 4 kHz): contact bounce does not hold and resume.
pub const HOLD_DEBOUNCE_TICKS: u8 = 8;

pub const fn parse_u32(s: Option<&str>, default: u32) -> u32 {
    let Some(s) = s else { return default };
    let b = s.as_bytes();
    let mut v: u32 = 0;
    let mut i = 0;
    while i < b.len() {
        let d = b[i];
        assert!(d.is_ascii_digit(), "BOARD_SERVO_PERIOD_US is not a number");
        v = v * 10 + (d - b'0') as u32;
        i += 1;
    }
    v
}
