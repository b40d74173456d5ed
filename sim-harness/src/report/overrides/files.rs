//! The files of one scenario run: its CSV, its feed figure, and its row of
//! the Markdown table.

use std::path::{Path, PathBuf};

use crate::report::overrides::figure::write_feed_figure;
use crate::report::overrides::run::{BoxError, Run};
use crate::report::overrides::table::table_row;

/// Write `<name>.csv`, `<name>_feed.png` and return the Markdown row.
pub fn write_run(out: &Path, run: &Run) -> Result<(String, Vec<PathBuf>), BoxError> {
    let r = &run.result;
    let name = run.spec.name;
    let csv = out.join(format!("{name}.csv"));
    crate::csv::write_csv(&csv, &r.ticks)?;
    let png = out.join(format!("{name}_feed.png"));
    write_feed_figure(&png, run)?;
    let row = table_row(run);
    Ok((row, vec![csv, png]))
}
