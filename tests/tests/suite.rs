//! End-to-end tests across planner-host, firmware-core and sim-harness, one module a topic
//! (each file beside this one).
//!
//! One test binary, not one a file: the library and the firmware's generic code are
//! compiled and linked once for them all, and their tests share both cores to the end
//! (`cargo test -p e2e-tests --test suite TOPIC` runs one topic).

mod butterfly;
mod commands;
mod curve_family;
mod fuzz_corpus;
mod hard_curves;
mod hold;
mod hold_on_the_plan;
mod hostile;
mod line;
mod long_path;
mod noise;
mod override_regressions;
mod step_dir;
mod stream_faults;
mod stream_link;
mod stream_override;
mod stream_starve;
