//! What the stream tests share: a built-in curve planned and cut into
//! chunks.

use firmware_core::Table;
use planner_host::builtin;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};

/// A built-in curve's table and its chunks of about `chunk_mm` (u form
/// sent).
pub fn in_chunks(name: &str, chunk_mm: f64) -> (Vec<u8>, Vec<Vec<u8>>) {
    let curve = builtin::by_name(name).unwrap().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let opts = ChunkOptions {
        chunk_mm,
        u_form: true,
        ..ChunkOptions::default()
    };
    let table = Table::parse(&out.table_bytes).unwrap();
    let chunks = chunk_table(&table, &opts).unwrap();
    (out.table_bytes, chunks)
}
