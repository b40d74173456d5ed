//! Logging behind the `defmt` feature (crate-internal).
//!
//! `log::info!`, `log::warn!` and `log::error!` take defmt format strings
//! (`"{}"`, `"{=u64}"`, ...) and expand to the `defmt` macro of the same name
//! under the `defmt` feature; without it they expand to an `if false` block
//! that only type-checks the arguments (no code, no evaluation, no "unused"
//! warnings for values that are only logged).
//!
//! Log points, none per tick on the normal path (all rare events):
//!
//! | where | level | what |
//! |---|---|---|
//! | [`crate::table::Table::parse`] | warn | table refused: the [`crate::table::TableError`] |
//! | [`crate::interp::Interpolator::new`] | info / warn | created: L, predicted time, period, sizes; or the [`crate::interp::InterpError`] |
//! | [`crate::interp::Interpolator::tick`] | error | the [`crate::interp::Fault`] (its s and t), the tick index — once, when it happens |
//! | [`crate::interp::Interpolator::tick`] | info | path done: ticks, time |
//! | [`crate::interp::Interpolator::run`] | warn | the sink refused a setpoint: which one |
//!
//! A binary that enables the feature needs a defmt global logger (e.g.
//! `defmt-rtt`) and links with `-Tdefmt.x`; a library build needs neither.
//! The crate's own unit tests (`cfg(test)`, on the host, where there is no
//! logger) compile the log points out even with the feature, so
//! `cargo test -p firmware-core --features defmt` still links and checks the
//! `defmt::Format` derives; the format strings are checked by the target
//! build (`cargo build -p firmware-core --features defmt --target
//! thumbv7em-none-eabihf`).

macro_rules! log_at {
    ($level:ident, $fmt:literal $(, $arg:expr)* $(,)?) => {{
        #[cfg(all(feature = "defmt", not(test)))]
        {
            defmt::$level!($fmt $(, $arg)*);
        }
        #[cfg(not(all(feature = "defmt", not(test))))]
        {
            if false {
                $(let _ = &$arg;)*
            }
        }
    }};
}

macro_rules! info {
    ($($t:tt)*) => { $crate::log::log_at!(info, $($t)*) };
}

macro_rules! warn_ {
    ($($t:tt)*) => { $crate::log::log_at!(warn, $($t)*) };
}

macro_rules! error {
    ($($t:tt)*) => { $crate::log::log_at!(error, $($t)*) };
}

// `warn` itself would be ambiguous with the built-in attribute in a `use`.
pub(crate) use {error, info, log_at, warn_ as warn};
