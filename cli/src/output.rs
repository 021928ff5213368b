//! Output files written whole or not at all: into a temporary file next to the target,
//! renamed over it only when everything was written. A failed or interrupted run leaves
//! an existing file as it was (and at most a hidden `.NAME.PID.tmp.EXT` file behind on a
//! kill, never a half-written NAME).

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// The temporary file for `path`: hidden, in the same directory (so that the rename is
/// atomic), with the same extension (the figure writers choose the format by it).
#[must_use]
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_stem()
        .map_or_else(|| "output".into(), |s| s.to_string_lossy().into_owned());
    let ext = path
        .extension()
        .map_or_else(String::new, |e| format!(".{}", e.to_string_lossy()));
    path.with_file_name(format!(".{name}.{}.tmp{ext}", std::process::id()))
}

/// Checks now that `path` can be written (its directory exists and takes a new file), so
/// that a long run does not fail at its end. Leaves nothing behind.
///
/// # Errors
/// The reason, phrased for the user (`cannot write /x/y.csv: No such file or directory`).
pub fn check_writable(path: &Path) -> Result<(), String> {
    let tmp = temporary_path(path);
    File::create(&tmp).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let _ = std::fs::remove_file(&tmp);
    Ok(())
}

/// Writes `path` through `write`, which fills the temporary file at the path it is given;
/// renames it over `path` on success, removes it on failure.
///
/// # Errors
/// `write`'s error, or the rename's, phrased for the user.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), String> {
    let tmp = temporary_path(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|e| format!("cannot write {}: {e}", path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// [`write_atomically`] for text written through a buffered writer.
///
/// # Errors
/// As [`write_atomically`].
pub fn write_text(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), String> {
    write_atomically(path, |tmp| {
        let err = |e: std::io::Error| format!("cannot write {}: {e}", path.display());
        let mut w = BufWriter::new(File::create(tmp).map_err(err)?);
        write(&mut w).map_err(err)?;
        w.into_inner()
            .map_err(|e| err(e.into_error()))?
            .sync_all()
            .map_err(err)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("run.csv");
        std::fs::write(&p, "old\n").unwrap();
        let r = write_text(&p, |w| {
            writeln!(w, "half")?;
            Err(std::io::Error::other("interrupted"))
        });
        assert!(r.unwrap_err().contains("interrupted"));
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "old\n");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_text(&p, |w| writeln!(w, "new")).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "new\n");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn unwritable_places_are_found_before_the_work() {
        let e = check_writable(Path::new("/nonexistent/x.csv")).unwrap_err();
        assert!(e.starts_with("cannot write /nonexistent/x.csv: "), "{e}");
        assert!(temporary_path(Path::new("a/b.png"))
            .to_string_lossy()
            .ends_with(".tmp.png"));
    }
}
