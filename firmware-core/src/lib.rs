//! firmware-core: the servo-rate interpolator of a time-optimal feedrate plan.
//!
//! The host (planner-host) plans the squared feedrate q(s) = ṡ² as a cubic
//! B-spline over arc length (Petráček, Vlček & Švéda 2022, §2.1) and writes
//! it, with the NURBS toolpath and an s → u map, into one binary table. This
//! crate validates that table and turns it into position setpoints at servo
//! rate. `#![no_std]`, no heap, no `unsafe`, no panic path in parse or tick.
//!
//! # Layers, bottom up
//!
//! - [`basis`]: B-spline basis functions and derivatives on a knot window
//!   (Piegl & Tiller A2.2/A2.3), shared with the host.
//! - [`array`](mod@array): [`array::F64Array`] and friends, read-only indexed sources:
//!   host slices, or zero-copy little-endian views ([`array::LeF64`],
//!   [`array::LeU32`], [`array::LePoint4`]) into table bytes.
//! - [`table`]: the binary format, defined once: [`table::TableParts`] and
//!   [`table::encode`] on the host, [`table::Table::parse`] on the target —
//!   header, directory, CRC-32, every value checked before any motion.
//! - Evaluators over any [`array::F64Array`]:
//!   - [`qspline`]: q, q′, q″, q‴ from the span-local power form
//!     ([`qspline::QCursor`] moves span by span);
//!   - [`sumap`]: u(s), quintics in a local τ per segment ([`sumap::SuCursor`]);
//!   - [`nurbs`]: the rational curve r(u) in homogeneous coordinates on a
//!     known knot span ([`nurbs::NurbsCursor`]).
//! - [`fast`]: the servo-rate fast path — span- and piece-local f32 forms of
//!   q, u(s) and r(u) (derived by [`table::encode`], checked by
//!   [`table::Table::parse`]), evaluated with a fixed number of f32
//!   operations.
//! - [`interp`]: [`interp::Interpolator::tick`] — one order-4 Taylor step of
//!   s(t) from q (eqs. 1, 4, 5), then u(s), then r(u): a [`interp::Setpoint`].
//! - [`splice`]: feedrate override — host transition profiles into the
//!   table's override levels, checked and queued by
//!   [`interp::Interpolator::offer_override`], spliced in C² on q span entry
//!   (paper §4, `docs/override-design.md`); capacities are const generics
//!   (`Interpolator::<3, 64>::new_sized`; [`interp::Interpolator::new`] has none).
//! - [`hold`]: feed hold and resume — the firmware time-scales the active
//!   profile (ṡ = λ√q) to a stop and back without the host
//!   ([`interp::Interpolator::hold`], [`interp::Interpolator::resume`]).
//! - [`output`]: [`output::SetpointSink`], the trait setpoints leave through;
//!   with the `embedded-hal` feature, `output::hal`: an SPI frame sink and a
//!   sync-strobe sink on embedded-hal 1.0 traits (examples).
//!
//! # Example
//!
//! ```no_run
//! use firmware_core::{interp::Interpolator, table::Table};
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
//!   [`table::TableError`]), interpolator created (L, predicted time, period,
//!   sizes) or refused, fault (the [`interp::Fault`] and the tick), path
//!   done (ticks), sink refused a setpoint. Nothing is logged per tick on the
//!   normal path. A binary needs a defmt global logger; without the feature
//!   the log points compile to nothing.
//! - `serde`: Serialize/Deserialize for [`table::Limits`] and
//!   [`table::SuSegment`].
//! - `embedded-hal`: `output::hal`, example sinks on embedded-hal 1.0 — each
//!   setpoint as a 20-byte CRC-16 frame (u16 sequence, i32 nm, u32 µm/s) to
//!   an `SpiDevice`, and a strobe `OutputPin` toggled per setpoint.
//!
//! Units throughout: mm, s, mm/s, mm/s², mm/s³; q in (mm/s)². The table and
//! the reference evaluators are f64; the tick accumulates s in Q40 fixed
//! point and evaluates q, √q and the position in fixed point, the small
//! corrections in f32 (see [`fast`] and [`interp`]; issue 3: ~1,270 Thumb
//! instructions a tick on a Cortex-M4F, setpoint noise σ < 1e-12 mm).
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate throughout: it is true for NaN, which must fail
// every validity check.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(test)]
extern crate std;

pub mod array;
pub mod basis;
pub mod digest;
pub mod dryrun;
pub mod fast;
pub mod hold;
pub mod interp;
mod log;
pub mod nurbs;
pub mod output;
pub mod qspline;
pub mod splice;
pub mod sumap;
pub mod table;

#[cfg(test)]
mod tests;
