//! Writing result files atomically: a temporary file beside the target,
//! then a rename, so a reader never sees a half-written table.
//!
//! Only a regular file (or a new one) is replaced so. A target that is not
//! a regular file — `/dev/null`, a FIFO, a terminal — is written in place:
//! a rename would replace the device itself (run as root, `-o /dev/null`
//! left a regular file there, which every later program writing to or
//! reading from `/dev/null` then shared: compiler probes read earlier
//! diagnostics back as their input). A symbolic link keeps pointing where it
//! did: the file it points to is the one replaced.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::plan::error::PlanError;

/// Write `bytes` to `path` atomically: a temporary file beside it, then a
/// rename, so a reader never sees a half-written table (see the module
/// docs for targets that are not regular files).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), PlanError> {
    write_file_atomic(path, bytes).map_err(|source| PlanError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// [`write_atomic`] with a plain I/O error, for other writers of result files.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if is_special(path) {
        return std::fs::OpenOptions::new()
            .write(true)
            .open(path)?
            .write_all(bytes);
    }
    let path = &resolved(path);
    let tmp = temp_beside(path, "");
    let result = (|| {
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

/// A temporary file's path beside `path` (hidden, with this process's id),
/// ending in `ext` (for writers that pick the format by extension).
pub fn temp_beside(path: &Path, ext: &str) -> PathBuf {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    dir.join(format!(".{name}.{}.tmp{ext}", std::process::id()))
}

/// Put the finished temporary file `tmp` in the place of `path`: renamed
/// over it (a regular file, a new one, or the file a symbolic link points
/// to), or copied into it and removed when `path` is not a regular file.
/// `tmp` is removed on failure.
pub fn replace_with(tmp: &Path, path: &Path) -> std::io::Result<()> {
    let result = if is_special(path) {
        std::fs::read(tmp).and_then(|bytes| {
            std::fs::OpenOptions::new()
                .write(true)
                .open(path)?
                .write_all(&bytes)
        })
    } else {
        std::fs::rename(tmp, resolved(path))
    };
    let _ = std::fs::remove_file(tmp);
    result
}

/// `path` exists and is neither a regular file nor a directory (following
/// symbolic links): a device, a FIFO, a socket.
fn is_special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// The file a symbolic link at `path` points to (the link stays), else `path`.
fn resolved(path: &Path) -> PathBuf {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
        }
        _ => path.to_path_buf(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("feedlp-atomic-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A regular file is replaced whole, a symbolic link keeps pointing at
    /// the file it did (which holds the new bytes), and no temporary file is
    /// left behind.
    #[test]
    fn a_file_is_replaced_and_a_link_kept() {
        let d = dir("link");
        let file = d.join("table.bin");
        std::fs::write(&file, b"old table").unwrap();
        write_file_atomic(&file, b"new").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"new");
        #[cfg(unix)]
        {
            let link = d.join("latest.bin");
            std::os::unix::fs::symlink(&file, &link).unwrap();
            write_file_atomic(&link, b"through the link").unwrap();
            assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
            assert_eq!(std::fs::read(&file).unwrap(), b"through the link");
        }
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A FIFO (as `/dev/null` or a pipe to another program) is written
    /// into, not replaced: the reader gets the bytes and the FIFO stays one.
    #[cfg(unix)]
    #[test]
    fn a_fifo_is_written_into_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let d = dir("fifo");
        let fifo = d.join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
        assert!(made.success());
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(&fifo).unwrap())
        };
        write_file_atomic(&fifo, b"streamed").unwrap();
        assert_eq!(reader.join().unwrap(), b"streamed");
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        // and a finished temporary file handed over the same way
        let tmp = temp_beside(&fifo, ".png");
        std::fs::write(&tmp, b"picture").unwrap();
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(&fifo).unwrap())
        };
        replace_with(&tmp, &fifo).unwrap();
        assert_eq!(reader.join().unwrap(), b"picture");
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        assert!(!tmp.exists());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
