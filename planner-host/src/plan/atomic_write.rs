//! Writing result files atomically: a temporary file beside the target,
//! then a rename, so a reader never sees a half-written table.

use std::path::Path;

use crate::plan::error::PlanError;

/// Write `bytes` to `path` atomically: a temporary file beside it, then a
/// rename, so a reader never sees a half-written table.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), PlanError> {
    write_file_atomic(path, bytes).map_err(|source| PlanError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// [`write_atomic`] with a plain I/O error, for other writers of result files.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        use std::io::Write;
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
