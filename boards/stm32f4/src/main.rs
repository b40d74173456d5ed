//! firmware-core on an STM32F407/405 board: the servo tick in a timer
//! interrupt, step and direction pulses on GPIO pins, a feed-hold input,
//! and a USART link that receives the plan table.
//!
//! # What runs where
//!
//! The host plans (`feedplan plan ... -o table.bin`) and sends the table
//! over the link ([`link`]); the board checks the frame, then
//! `Table::parse` checks the table, then it ticks. Nothing moves before
//! both checks pass.
//!
//! | task | binds | priority | does |
//! |---|---|---|---|
//! | `pulse` | TIM3, every [`config::SLOT_US`] µs | 3 (highest) | one slot of the step plan on the step pins ([`steps`]) |
//! | `servo` | TIM2, every servo period (250 µs) | 2 | feed-hold input, `Interpolator::tick`, setpoint → `StepDirSink` → next period's plan ([`job`]) |
//! | `link` | USART2 receive | 1 | frame bytes into the RAM buffer ([`link`]) |
//! | `clock` | SysTick, 1 kHz | 1 | a millisecond count (the servo rate is checked against it) |
//! | `idle` | — | 0 | parses a received table, starts the run, reports |
//!
//! # Why RTIC 2 with stm32f4xx-hal (and not embassy)
//!
//! The work is two periodic hardware interrupts at fixed priorities and
//! one receive interrupt: exactly RTIC's model (hardware tasks, priority
//! ceiling resource locks, no executor, no allocator, the resource
//! analysis at compile time). embassy's strengths (async drivers, its time
//! driver) are not needed on the tick path. The dependencies build from
//! scratch in 32 s on the project's 2-core machine (`docs/board.md`).
//!
//! # Memory
//!
//! The received table lives in a static 96 KiB buffer (RTIC's `init`
//! local resource: a `&'static mut` without `unsafe`). Once a table is
//! accepted the buffer is frozen to `&'static [u8]` for the
//! interpolator's lifetime, so one table can be received per reset; a
//! second frame is refused with a log line. With the `baked-table`
//! feature the table is instead built into flash (`BOARD_TABLE` at build
//! time) and the link is not used.
//!
//! No `unsafe` in this crate (`#![forbid(unsafe_code)]`); the HAL, the
//! PAC and RTIC's generated code have their own.
#![no_std]
#![no_main]
#![forbid(unsafe_code)]

#[cfg(feature = "qemu")]
mod check;
mod config;
mod job;
mod link;
mod steps;

use defmt_rtt as _;
use panic_probe as _;

/// Defmt timestamps: milliseconds since start (the SysTick count).
static MILLIS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);
/// Servo timer interrupts since start.
static SERVO_IRQS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);
/// Pulse timer interrupts since start.
static PULSE_IRQS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

defmt::timestamp!("{=u32:ms}", MILLIS.load(core::sync::atomic::Ordering::Relaxed));

/// 8-byte aligned bytes (the table's sections are 8-aligned offsets).
#[repr(C, align(8))]
pub struct Aligned<T: ?Sized>(pub T);

#[cfg(feature = "baked-table")]
static BAKED: &Aligned<[u8]> = &Aligned(*include_bytes!(env!("BOARD_TABLE_PATH")));

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true)]
mod app {
    use crate::config::{
        HOLD_DEBOUNCE_TICKS, LINK_BAUD, SERVO_PERIOD_S, SERVO_PERIOD_US, SLOTS, SLOT_US, TABLE_BUF_LEN,
    };
    use crate::job::{Job, RunState};
    use crate::link::{Event as LinkEvent, FrameRx};
    use crate::steps::{SlotPlan, StepPins};
    use crate::{Aligned, MILLIS, PULSE_IRQS, SERVO_IRQS};
    use core::sync::atomic::Ordering::Relaxed;
    use firmware_core::{Interpolator, Table};
    use stm32f4xx_hal::gpio::{ErasedPin, Input, Output};
    use stm32f4xx_hal::pac::{TIM2, TIM3, USART2};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::serial::{Config, Rx};
    use stm32f4xx_hal::timer::{CounterUs, Event as TimEvent, Flag};

    /// QEMU's STM32F405 model clocks TIM2-5 at a fixed 48 MHz whatever the
    /// RCC says (it has no RCC), while the HAL sets the prescaler for the
    /// 16 MHz HSI it believes in: timer durations are scaled by 3 there.
    #[cfg(feature = "qemu")]
    const TIMER_SCALE: u32 = 3;
    #[cfg(not(feature = "qemu"))]
    const TIMER_SCALE: u32 = 1;

    /// The pulse interrupt's slot counter starts here, so that its slot 0
    /// falls 130 µs (at 250 µs: just past half a period) after each servo
    /// interrupt: the servo tick has that long to hand over the next plan,
    /// and its plan is always taken at the same slot 0 however long it ran.
    const FIRST_SLOT: usize = SLOTS + 1 - SLOTS.div_ceil(2);

    #[shared]
    struct Shared {
        /// The run, once a table was accepted.
        job: Option<Job>,
        /// The next period's pulses, from the servo tick to the pulse task.
        next: Option<SlotPlan>,
        /// A received, CRC-checked table, from the link to idle.
        received: Option<&'static [u8]>,
    }

    #[local]
    struct Local {
        servo_timer: CounterUs<TIM2>,
        pulse_timer: CounterUs<TIM3>,
        pins: StepPins<ErasedPin<Output>>,
        hold_pin: ErasedPin<Input>,
        rx: Rx<USART2>,
        buf: Option<&'static mut Aligned<[u8; TABLE_BUF_LEN]>>,
    }

    #[init(local = [table_buf: Aligned<[u8; TABLE_BUF_LEN]> = Aligned([0; TABLE_BUF_LEN])])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let dp = cx.device;
        let mut core = cx.core;
        let rcc = dp.RCC.constrain();
        // The board: 8 MHz crystal, 168 MHz core, APB1 42 MHz (timers 84 MHz).
        // Under QEMU: the 16 MHz HSI, no PLL (QEMU has no RCC: a PLL would
        // never report lock).
        #[cfg(not(feature = "qemu"))]
        let clocks = rcc
            .cfgr
            .use_hse(8.MHz())
            .sysclk(168.MHz())
            .pclk1(42.MHz())
            .freeze();
        #[cfg(feature = "qemu")]
        let clocks = rcc.cfgr.freeze();
        defmt::info!(
            "board-stm32f4: core {} Hz, servo period {} us, {} slots of {} us",
            clocks.hclk().raw(),
            SERVO_PERIOD_US,
            SLOTS,
            SLOT_US
        );

        let gpioa = dp.GPIOA.split();
        let gpioe = dp.GPIOE.split();
        let mut pins = StepPins {
            step: [
                gpioe.pe9.into_push_pull_output().erase(),
                gpioe.pe11.into_push_pull_output().erase(),
                gpioe.pe13.into_push_pull_output().erase(),
            ],
            dir: [
                gpioe.pe10.into_push_pull_output().erase(),
                gpioe.pe12.into_push_pull_output().erase(),
                gpioe.pe14.into_push_pull_output().erase(),
            ],
        };
        pins.all_low();
        let hold_pin = gpioe.pe7.into_pull_up_input().erase();

        let mut rx = match dp
            .USART2
            .rx(gpioa.pa3, Config::default().baudrate(LINK_BAUD.bps()), &clocks)
        {
            Ok(rx) => rx,
            Err(_) => panic!("USART2 configuration"),
        };
        rx.listen();

        // SysTick at 1 kHz on the core clock (QEMU's model: 168 MHz fixed).
        #[cfg(feature = "qemu")]
        let core_hz = 168_000_000;
        #[cfg(not(feature = "qemu"))]
        let core_hz = clocks.hclk().raw();
        core.SYST
            .set_clock_source(cortex_m::peripheral::syst::SystClkSource::Core);
        core.SYST.set_reload(core_hz / 1_000 - 1);
        core.SYST.clear_current();
        core.SYST.enable_interrupt();
        core.SYST.enable_counter();

        // Both timers count at 1 MHz from the same clock; started back to
        // back here (interrupts are off in init) their phase is fixed.
        let mut pulse_timer = dp.TIM3.counter_us(&clocks);
        let mut servo_timer = dp.TIM2.counter_us(&clocks);
        if pulse_timer.start((SLOT_US * TIMER_SCALE).micros()).is_err()
            || servo_timer
                .start((SERVO_PERIOD_US * TIMER_SCALE).micros())
                .is_err()
        {
            panic!("timer period out of range");
        }
        // QEMU's timer model does not keep the programmed period, and with
        // this 10 µs interrupt on as well a run may not finish (docs/board.md):
        // it stays off there; the plans are still made and checked.
        if !cfg!(feature = "qemu") {
            pulse_timer.listen(TimEvent::Update);
        }
        servo_timer.listen(TimEvent::Update);

        (
            Shared {
                job: None,
                next: None,
                received: None,
            },
            Local {
                servo_timer,
                pulse_timer,
                pins,
                hold_pin,
                rx,
                buf: Some(cx.local.table_buf),
            },
        )
    }

    #[idle(shared = [job, received])]
    fn idle(mut cx: idle::Context) -> ! {
        #[cfg(feature = "qemu")]
        crate::qemu::self_check();
        #[cfg(feature = "qemu")]
        crate::qemu::calibrate();
        #[cfg(feature = "baked-table")]
        start(&crate::BAKED.0, &mut cx.shared.job);
        #[cfg(not(feature = "baked-table"))]
        defmt::info!("waiting for a table on USART2 (PA3, {} baud)", LINK_BAUD);
        // (the QEMU script sends the table once it reads this line)
        #[cfg(all(feature = "qemu", not(feature = "baked-table")))]
        cortex_m_semihosting::hprintln!("link: waiting for a table on USART2");
        let mut reported = false;
        loop {
            if let Some(bytes) = cx.shared.received.lock(Option::take) {
                start(bytes, &mut cx.shared.job);
            }
            let end = cx.shared.job.lock(|j| {
                j.as_ref()
                    .filter(|j| j.state() != RunState::Running)
                    .map(|j| (j.state(), j.setpoints, j.digest.finish(), j.steps()))
            });
            if let (Some((state, setpoints, digest, steps)), false) = (end, reported) {
                reported = true;
                report(state, setpoints, digest, steps);
            }
            cortex_m::asm::wfi();
        }
    }

    /// Parse `bytes` and, when it is a good table, start the run.
    fn start(bytes: &'static [u8], job: &mut impl rtic::Mutex<T = Option<Job>>) {
        let table = match Table::parse(bytes) {
            Ok(t) => t,
            Err(e) => {
                defmt::error!("table refused: {}", e);
                return;
            }
        };
        defmt::info!(
            "table: {} bytes, L = {} mm, predicted {} s",
            bytes.len(),
            table.path_length_mm(),
            table.predicted_time_s()
        );
        let ip = match Interpolator::new(table, SERVO_PERIOD_S) {
            Ok(ip) => ip,
            Err(e) => {
                defmt::error!("interpolator refused: {}", e);
                return;
            }
        };
        match Job::new(ip) {
            Ok(j) => {
                job.lock(|slot| *slot = Some(j));
                #[cfg(feature = "qemu")]
                crate::qemu::started();
                defmt::info!("running");
            }
            Err(e) => defmt::error!("step configuration refused: {}", e),
        }
    }

    fn report(state: RunState, setpoints: u32, digest: u64, steps: Option<([i64; 3], [i64; 3])>) {
        if cfg!(feature = "digest") {
            defmt::info!("run {}: {} setpoints, digest {=u64:x}", state, setpoints, digest);
        } else {
            defmt::info!("run {}: {} setpoints", state, setpoints);
        }
        if let Some((emitted, want)) = steps {
            defmt::info!("steps emitted {}, at the last setpoint {}", emitted, want);
        }
        #[cfg(feature = "qemu")]
        crate::qemu::finished(state, setpoints, digest, steps);
    }

    /// The servo tick: feed-hold input, one interpolator tick, the next
    /// period's step plan to the pulse task. Never panics.
    #[task(binds = TIM2, priority = 2, shared = [job, next],
           local = [servo_timer, hold_pin, hold_active: bool = false, hold_run: u8 = 0])]
    fn servo(mut cx: servo::Context) {
        cx.local.servo_timer.clear_flags(Flag::Update);
        SERVO_IRQS.fetch_add(1, Relaxed);
        // Feed hold: input low (switch to ground, pull-up) = hold. QEMU has
        // no GPIO model (every pin reads low): there the input is simulated
        // (`qemu::hold_input`).
        #[cfg(not(feature = "qemu"))]
        let active = cx.local.hold_pin.is_low();
        #[cfg(feature = "qemu")]
        let active = crate::qemu::hold_input();
        let mut change = None;
        if active == *cx.local.hold_active {
            *cx.local.hold_run = 0;
        } else {
            *cx.local.hold_run = cx.local.hold_run.saturating_add(1);
            if *cx.local.hold_run >= HOLD_DEBOUNCE_TICKS {
                *cx.local.hold_active = active;
                *cx.local.hold_run = 0;
                change = Some(active);
            }
        }
        let plan = cx.shared.job.lock(|j| {
            let j = j.as_mut()?;
            // Under QEMU each tick of a running job is an instruction-count
            // window (`qemu::mark_begin` .. `qemu::mark_end`).
            #[cfg(feature = "qemu")]
            if j.state() == RunState::Running {
                crate::qemu::mark_begin();
                let plan = j.tick(change);
                crate::qemu::mark_end();
                return plan;
            }
            j.tick(change)
        });
        if let Some(plan) = plan {
            let late = cx.shared.next.lock(|n| n.replace(plan).is_some());
            if late {
                defmt::warn!("step plan not taken in time: one period of pulses lost");
            }
        }
    }

    /// One slot of step pulses; at slot 0 the next plan and its directions.
    #[task(binds = TIM3, priority = 3, shared = [next],
           local = [pulse_timer, pins, slot: usize = FIRST_SLOT, plan: SlotPlan = SlotPlan::EMPTY])]
    fn pulse(mut cx: pulse::Context) {
        cx.local.pulse_timer.clear_flags(Flag::Update);
        PULSE_IRQS.fetch_add(1, Relaxed);
        let slot = *cx.local.slot;
        if slot == 0 {
            match cx.shared.next.lock(Option::take) {
                Some(p) => {
                    *cx.local.plan = p;
                    cx.local.pins.set_dir(cx.local.plan);
                }
                None => cx.local.plan.high = [0; SLOTS],
            }
        }
        cx.local.pins.play(cx.local.plan, slot);
        *cx.local.slot = if slot + 1 >= SLOTS { 0 } else { slot + 1 };
    }

    /// Link bytes into the table buffer; a good frame goes to idle.
    #[task(binds = USART2, priority = 1, shared = [received], local = [rx, buf, frame: FrameRx = FrameRx::new()])]
    fn link(mut cx: link::Context) {
        use stm32f4xx_hal::nb;
        loop {
            let b = match cx.local.rx.read() {
                Ok(b) => b,
                Err(nb::Error::WouldBlock) => return,
                Err(nb::Error::Other(e)) => {
                    defmt::warn!("link: {} (frame dropped)", defmt::Debug2Format(&e));
                    *cx.local.frame = FrameRx::new();
                    continue;
                }
            };
            let Some(buf) = cx.local.buf.as_mut() else {
                // A table is already running from the buffer.
                continue;
            };
            match cx.local.frame.push(b, &mut buf.0) {
                LinkEvent::None => {}
                LinkEvent::Started(n) => defmt::info!("link: receiving {} bytes", n),
                LinkEvent::TooLong(n) => defmt::warn!("link: {} bytes do not fit {}", n, TABLE_BUF_LEN),
                LinkEvent::BadCrc(want, got) => {
                    defmt::warn!("link: CRC {=u32:x} != {=u32:x} (frame dropped)", got, want)
                }
                LinkEvent::Done(n) => {
                    if let Some(buf) = cx.local.buf.take() {
                        // from here on the buffer is read-only, for good
                        let frozen: &'static Aligned<[u8; TABLE_BUF_LEN]> = buf;
                        let table = frozen.0.get(..n).unwrap_or(&[]);
                        cx.shared.received.lock(|r| *r = Some(table));
                        defmt::info!("link: table received ({} bytes); reset to load another", n);
                    }
                }
            }
        }
    }

    /// A millisecond count, for the logs and to check the servo rate.
    #[task(binds = SysTick, priority = 1)]
    fn clock(_: clock::Context) {
        MILLIS.fetch_add(1, Relaxed);
    }
}

/// The QEMU run's report, over semihosting (feature `qemu`).
#[cfg(feature = "qemu")]
mod qemu {
    use crate::job::RunState;
    use crate::{MILLIS, PULSE_IRQS, SERVO_IRQS};
    use core::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};
    use cortex_m_semihosting::{debug, hprintln};

    static START: [AtomicU32; 3] = [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)];
    /// The run has started (`START` holds its start).
    static STARTED: AtomicBool = AtomicBool::new(false);
    /// Instruction-count windows opened by [`mark_begin`].
    static WINDOWS: AtomicU32 = AtomicU32::new(0);

    /// Start of an instruction-count window: `firmware-core/mcu/bench_insn.py`
    /// counts the guest instructions from an entry of this function to the
    /// next entry of [`mark_end`] (a TCG plugin, `--marks`).
    #[inline(never)]
    pub fn mark_begin() {
        WINDOWS.fetch_add(1, Relaxed);
        core::hint::black_box(0x6265_6769u32);
    }

    /// End of an instruction-count window.
    #[inline(never)]
    pub fn mark_end() {
        core::hint::black_box(0x656e_6421u32);
    }

    /// Build-time `BOARD_QEMU_HOLD_AT` and `BOARD_QEMU_HOLD_TICKS`: the
    /// simulated feed-hold input is active from that many servo interrupts
    /// after the run started, for that many (none by default).
    const HOLD_AT: u32 = parse(option_env!("BOARD_QEMU_HOLD_AT"));
    const HOLD_TICKS: u32 = parse(option_env!("BOARD_QEMU_HOLD_TICKS"));

    const fn parse(s: Option<&str>) -> u32 {
        match s {
            Some(s) => crate::config::parse_u32(Some(s), 0),
            None => 0,
        }
    }

    /// The simulated feed-hold input (QEMU has no GPIO model).
    pub fn hold_input() -> bool {
        if HOLD_TICKS == 0 || !STARTED.load(Relaxed) {
            return false;
        }
        let since = SERVO_IRQS.load(Relaxed).wrapping_sub(START[1].load(Relaxed));
        (HOLD_AT..HOLD_AT.saturating_add(HOLD_TICKS)).contains(&since)
    }

    /// A hold or resume taken by the interpolator (`state`: the hold state
    /// just after a hold, just before a resume).
    pub fn note(what: &str, setpoints: u32, s_mm: f64, state: firmware_core::HoldState) {
        hprintln!(
            "{}: at setpoint {}, s = {} mm, {:?}",
            what,
            setpoints,
            s_mm,
            state
        );
    }

    /// The board's own logic checked (`crate::check`); exits QEMU with
    /// failure when a check fails.
    pub fn self_check() {
        match crate::check::run() {
            Ok(()) => hprintln!("self-check: ok (frame receiver, step slot plans)"),
            Err(what) => {
                hprintln!("self-check: FAILED: {}", what);
                debug::exit(debug::EXIT_FAILURE);
            }
        }
    }

    /// Back-to-back empty windows, before any tick: the marker overhead
    /// the bench script subtracts.
    pub fn calibrate() {
        const N: u32 = 64;
        for _ in 0..N {
            mark_begin();
            mark_end();
        }
        hprintln!("BENCH-GROUP empty {}", N);
    }

    /// The run started: note the time and the servo count.
    pub fn started() {
        START[0].store(MILLIS.load(Relaxed), Relaxed);
        START[1].store(SERVO_IRQS.load(Relaxed), Relaxed);
        START[2].store(PULSE_IRQS.load(Relaxed), Relaxed);
        STARTED.store(true, Relaxed);
        hprintln!(
            "board: running (servo period {} us)",
            crate::config::SERVO_PERIOD_US
        );
    }

    /// The run ended: print the servo rate against the SysTick clock, the
    /// setpoint count and digest, and exit QEMU.
    pub fn finished(state: RunState, setpoints: u32, digest: u64, steps: Option<([i64; 3], [i64; 3])>) {
        let ms = MILLIS.load(Relaxed).wrapping_sub(START[0].load(Relaxed));
        let irqs = SERVO_IRQS.load(Relaxed).wrapping_sub(START[1].load(Relaxed));
        let hz = if ms > 0 {
            u64::from(irqs) * 1000 / u64::from(ms)
        } else {
            0
        };
        hprintln!(
            "servo: {} timer interrupts in {} ms of SysTick time = {} Hz",
            irqs,
            ms,
            hz
        );
        hprintln!("ticks: {}", setpoints);
        let windows = WINDOWS.load(Relaxed).saturating_sub(64);
        hprintln!("BENCH-GROUP servo-tick {}", windows);
        hprintln!("digest: fnv1a64-pos-le={:016x}", digest);
        let steps_ok = match steps {
            Some((emitted, want)) => {
                hprintln!(
                    "steps: emitted [{}, {}, {}], at the last setpoint [{}, {}, {}]",
                    emitted[0],
                    emitted[1],
                    emitted[2],
                    want[0],
                    want[1],
                    want[2]
                );
                emitted == want
            }
            None => false,
        };
        let ok = state == RunState::Done && steps_ok;
        hprintln!("run: {}", if ok { "done" } else { "FAULTED" });
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
    }
}
