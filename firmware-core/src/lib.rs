//! firmware-core: the servo-rate interpolator of a time-optimal feedrate plan.
//!
//! The host (planner-host) plans the squared feedrate q(s) = ṡ² as a cubic
//! B-spline over arc length (Petráček, Vlček & Švéda 2022, §2.1) and writes
//! it, with the NURBS toolpath and an s → u map, into one binary table. This
//! crate validates that table and turns it into position setpoints at servo
//! rate. `#![no_std]`, no heap, no `unsafe`, no panic path in parse or tick.
//!
//! # Layers, bottom up (folders follow the data from table to setpoint)
//!
//! - `limits` (re-exported here): [`Limits`] and [`EndSegments`], the
//!   vocabulary planner and interpolator share.
//! - [`math`]: [`math::basis`], B-spline basis functions and derivatives on a
//!   knot window and the knot-span search (Piegl & Tiller A2.1–A2.3), shared
//!   with the host; [`math::source`], read-only indexed number sources
//!   ([`F64Array`] and friends): host slices, or zero-copy little-endian
//!   views ([`math::source::LeF64`], [`math::source::LeU32`],
//!   [`math::source::LePoint4`]) into table bytes.
//! - [`path`], the f64 reference evaluators over any [`F64Array`]:
//!   - [`path::qspline`]: q, q′, q″, q‴ from the span-local power form
//!     ([`path::qspline::QCursor`] moves span by span);
//!   - [`path::su_map`]: u(s), quintics in a local τ per segment
//!     ([`SuSegment`], [`path::su_map::SuCursor`]);
//!   - [`path::nurbs`]: the rational curve r(u) in homogeneous coordinates
//!     on a known knot span ([`path::nurbs::NurbsCursor`]).
//! - `servo_forms` (crate-private): the servo-rate forms — span- and
//!   piece-local fixed-point and f32 forms of q, u(s) and r(u), fitted on
//!   the host by [`encode`], checked by [`Table::parse`], evaluated on the
//!   tick with a fixed number of integer and f32 operations.
//! - [`table`]: the binary format, defined once: [`TableParts`] and
//!   [`encode`] on the host, [`Table::parse`] on the target — header,
//!   directory, CRC-32, every value checked before any motion, stage by
//!   stage ([`table::layout`] names every offset).
//! - [`interp`]: [`Interpolator::tick`] — one order-4 Taylor step of
//!   s(t) from q (eqs. 1, 4, 5), then u(s), then r(u): a [`Setpoint`].
//! - [`feed_override`]: feedrate override — host transition profiles
//!   ([`OverrideProfile`]) into the table's override levels, checked and
//!   queued by [`Interpolator::offer_override`], spliced in C² on q span
//!   entry (paper §4, `docs/override-design.md`); capacities are const
//!   generics (`Interpolator::<3, 64>::new_sized`; [`Interpolator::new`]
//!   has none).
//! - [`feed_hold`]: feed hold and resume — the firmware time-scales the
//!   active profile (ṡ = λ√q) to a stop and back without the host
//!   ([`Interpolator::hold`], [`Interpolator::resume`], [`HoldState`]).
//! - [`output`]: [`SetpointSink`], the trait setpoints leave through; with
//!   the `embedded-hal` feature, `output::hal`: an SPI frame sink and a
//!   sync-strobe sink on embedded-hal 1.0 traits (examples).
//! - [`stream`]: the plan in chunks (format version 2) for streaming:
//!   [`stream::Chunk`] decodes to the tick's q-span and piece forms,
//!   [`stream::ChunkRing`] holds received chunks, [`stream::frame`] the
//!   COBS link framing (not yet read by the tick).
//! - [`digest`] (the run digest host and MCU compare) and [`dry_run`] (the
//!   invariant checker behind the fuzz targets).
//!
//! # Example
//!
//! ```no_run
//! use firmware_core::{Interpolator, Table};
//! # fn servo_write(_: [f64; 3]) {}
//! # let bytes: &[u8] = &[];
//! let table = Table::parse(bytes).expect("table refused before any motion");
//! let mut ip = Interpolator::new(table, 250e-6).expect("period > 0");
//! while !ip.is_done() {
//!     match ip.tick() {
//!         Ok(sp) => servo_write(sp.pos_mm),
//!         Err(fault) => panic!("{fault:?}"),
//!     }
//! }
//! ```
//!
//! # Features
//!
//! - `defmt`: `defmt::Format` on the public data and error types, and a few
//!   log points (internal `log` module): table refused (the
//!   [`TableError`]), interpolator created (L, predicted time, period,
//!   sizes) or refused, fault (the [`Fault`] and the tick), path
//!   done (ticks), sink refused a setpoint. Nothing is logged per tick on the
//!   normal path. A binary needs a defmt global logger; without the feature
//!   the log points compile to nothing.
//! - `serde`: Serialize/Deserialize for [`Limits`], [`EndSegments`] and
//!   [`SuSegment`].
//! - `embedded-hal`: `output::hal`, example sinks on embedded-hal 1.0 — each
//!   setpoint as a 20-byte CRC-16 frame (u16 sequence, i32 nm, u32 µm/s) to
//!   an `SpiDevice`, and a strobe `OutputPin` toggled per setpoint.
//!
//! Units throughout: mm, s, mm/s, mm/s², mm/s³; q in (mm/s)². The table and
//! the reference evaluators are f64; the tick accumulates s in Q40 fixed
//! point and evaluates q, √q and the position in fixed point, the small
//! corrections in f32 (see [`interp`]; the fixed-point tick costs ~1,270 Thumb
//! instructions on a Cortex-M4F, with setpoint noise σ < 1e-12 mm).
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate throughout: it is true for NaN, which must fail
// every validity check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(test)]
extern crate std;

pub mod digest;
pub mod dry_run;
pub mod feed_hold;
pub mod feed_override;
pub mod interp;
mod limits;
mod log;
pub mod math;
pub mod output;
pub mod path;
pub(crate) mod servo_forms;
pub mod stream;
pub mod table;

#[cfg(test)]
mod tests;

pub use crate::feed_hold::{HoldError, HoldState, HoldStats};
pub use crate::feed_override::{Accepted, OverrideError, OverrideProfile};
pub use crate::interp::{Fault, InterpError, Interpolator, RunError, Setpoint};
pub use crate::limits::{EndSegments, Limits};
pub use crate::math::source::F64Array;
pub use crate::output::SetpointSink;
pub use crate::path::su_map::SuSegment;
pub use crate::table::{encode, encoded_len, EncodeError, LevelParts, Table, TableError, TableParts};
