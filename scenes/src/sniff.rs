//! What a file's first bytes say it is: how a file whose extension lies (a LAS file renamed
//! `.ply`) gets an error naming what it is instead of the expected reader's "not a PLY file".

use std::io::Read as _;
use std::path::Path;

use crate::SceneError;

/// The file formats a file's first bytes identify: (magic, format, its extensions).
pub const MAGICS: &[(&[u8], &str, &str)] = &[
    (b"LASF", "LAS", ".las or .laz"),
    (b"ply", "PLY", ".ply"),
    (b"ASTM-E57", "E57", ".e57"),
    (b"SPLATCOL", "splatbench column", ".sbc"),
    (b"# .PCD", "PCD", ".pcd"),
];

/// Refuses `path` when its first bytes are another known format's than `expected` (a name
/// of [`MAGICS`]), naming what it is and the extension to give it; first bytes that name no
/// known format are left to the reader, whose error says what it expected.
pub fn expect(path: &Path, expected: &str) -> Result<(), SceneError> {
    let mut head = [0u8; 8];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|e| SceneError::io(path, e))?;
    match MAGICS.iter().find(|(m, _, _)| head[..n].starts_with(m)) {
        Some((_, format, ext)) if *format != expected => Err(SceneError::format(
            path,
            format!(
                "this is a {format} file (it starts with {:?}), not a {expected} file as its \
                 extension says: give it the extension {ext}",
                String::from_utf8_lossy(&head[..n])
                    .split(|c: char| c.is_control())
                    .next()
                    .unwrap_or_default()
            ),
        )),
        _ => Ok(()),
    }
}
