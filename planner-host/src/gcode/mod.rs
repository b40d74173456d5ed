//! A G-code reader: RS274/NGC part programs, as LinuxCNC reads them, for a
//! 3-axis machine, to a list of canonical moves in mm and mm/s.
//!
//! The layers, each a file, from text to moves:
//!
//! - [`lex`]: lines to blocks — comments, block delete, `%`, case and
//!   spaces, then words and parameter assignments (written by hand; the
//!   module says why the `gcode` crate is not used);
//! - [`expr`] and [`params`]: values — numbers, `#` parameters, bracketed
//!   expressions and functions;
//! - [`interp`]: the modal state and the blocks' execution, in LinuxCNC's
//!   order, to moves: all of them ([`read_str`]), or each handed on as its
//!   block is read ([`read_str_each`], for a program streamed as it is
//!   read);
//! - [`moves`]: the canonical moves and the program summary;
//! - [`error`]: the typed errors, each with its line and word.
//!
//! What is read: G0, G1, G2/G3 (IJK and R, full circles, P turns, helices)
//! in G17/G18/G19, G5.2/G5.3 and G6.2 NURBS, G20/G21, G90/G91,
//! G90.1/G91.1, G61/G61.1/G64 P Q (kept on every move), F in units per
//! minute (G94), N, comments, `/`, `%`, numbered and named parameters,
//! expressions, M0/M1/M2/M30. S, T, M3–M9 and M6 are listed and move
//! nothing; G40, G49, G54, G80, G94, G97, G98/G99 are accepted as the
//! states they already are. Anything else that would move the machine or
//! change the geometry (O-words, G93, G41/G42, A/B/C, canned cycles, G92,
//! G28/G30, G55+, G10, …) is refused with a [`GcodeError`] naming the line
//! and the word. `docs/gcode.md` has the full list and the comparison with
//! LinuxCNC's own interpreter (`tools/rs274-compare.py`).

pub mod error;
pub mod expr;
pub mod interp;
pub mod lex;
pub mod moves;
pub mod params;

pub use error::GcodeError;
pub use interp::{read_bytes, read_str, read_str_each, ReadOptions};
pub use moves::{ArcGeometry, Axis, Move, MoveKind, NoteWord, NurbsGeometry, PathControl, Plane, Program};
