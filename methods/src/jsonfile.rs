//! JSON files of a build (`method.json`, `build.json`, each method's own): written through a
//! temporary file and a rename, read with errors naming the file. Below [`crate::method`] and
//! [`crate::store`], which both use it.

use std::path::Path;

use crate::MethodError;

/// Writes `value` as pretty JSON to `path` through a temporary file and a rename, so a reader
/// never sees a half-written file.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), MethodError> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| MethodError::io(path, std::io::Error::other(e)))?;
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text).map_err(|e| MethodError::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| MethodError::io(path, e))
}

/// Reads JSON from `path`; a missing file is an I/O error, bad contents are `Corrupt`, both
/// naming the file.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, MethodError> {
    let text = std::fs::read_to_string(path).map_err(|e| MethodError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| MethodError::corrupt(path, e.to_string()))
}
