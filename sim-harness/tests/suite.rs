//! The simulation's tests, one module a topic (each file beside this one): the CLI, whole
//! programs, the line and streamed programs.
//!
//! One test binary, not one a file: the library and the firmware's generic code are
//! compiled and linked once for them all, and their tests share both cores to the end
//! (`cargo test -p sim-harness --test suite TOPIC` runs one topic).

mod cli;
mod program;
mod sim_line;
mod stream_program;
