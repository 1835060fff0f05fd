//! Writing a file so that a failure leaves nothing half-written: through a temporary file in
//! the same directory, renamed into place once written and flushed (the PLY and LAS writers).

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::SceneError;

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` through a temporary file in the same directory that is renamed into place
/// only after `write` succeeded and the data was flushed; on failure the temporary file is
/// removed and `path` is untouched. Returns the size of the written file.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(File) -> Result<(), SceneError>,
) -> Result<u64, SceneError> {
    let name = path
        .file_name()
        .ok_or_else(|| SceneError::format(path, "the output path has no file name"))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = dir.join(tmp_name);
    let result = (|| {
        let file = File::create(&tmp).map_err(|e| SceneError::io(path, e))?;
        write(file)?;
        let len = std::fs::metadata(&tmp)
            .map_err(|e| SceneError::io(path, e))?
            .len();
        std::fs::rename(&tmp, path).map_err(|e| SceneError::io(path, e))?;
        Ok(len)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Flushes a buffered file to disk, reporting errors against `path`.
pub fn finish(w: BufWriter<File>, path: &Path) -> Result<(), SceneError> {
    let file = w
        .into_inner()
        .map_err(|e| SceneError::io(path, e.into_error()))?;
    file.sync_data().map_err(|e| SceneError::io(path, e))
}
