//! The planner's tests, one module a topic (each file beside this one): curves, G-code,
//! programs, the CLI, replans and the chunk stream.
//!
//! One test binary, not one a file: the library and the firmware's generic code are
//! compiled and linked once for them all, and their tests share both cores to the end
//! (`cargo test -p planner-host --test suite TOPIC` runs one topic).

mod certified;
mod chord_fit;
mod cli;
mod feed_profile;
mod gcode;
mod gcode_robust;
mod program_cli;
mod replan;
mod short_paths;
mod stream;
mod stream_feeding;
mod stream_hold_presses;
mod stream_pipeline;
mod stream_splice;
mod stream_tick;
mod support;
