//! Where the candidates wait between the pass that sorts them into partitions of tiles and
//! the passes that eliminate one partition at a time: in memory, or out of core in one file
//! per partition (a record per candidate), each file deleted once its partition is done.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::PathBuf;

use crate::SceneError;

/// The partitions' waiting candidates, records of type `R`.
pub(super) enum Spill<R> {
    Memory(Vec<Vec<R>>),
    Files {
        dir: SpillDir,
        writers: Vec<Option<BufWriter<File>>>,
        counts: Vec<u64>,
    },
}

impl<R: bytemuck::Pod> Spill<R> {
    /// `parts` partitions held in memory.
    pub fn memory(parts: usize) -> Self {
        Spill::Memory(vec![Vec::new(); parts])
    }

    /// `parts` partitions in files under the new directory `dir` (removed with the spill).
    pub fn files(dir: PathBuf, parts: usize) -> Result<Self, SceneError> {
        std::fs::create_dir_all(&dir).map_err(|e| SceneError::io(&dir, e))?;
        let dir = SpillDir(dir);
        let writers = (0..parts)
            .map(|p| {
                let path = dir.part(p);
                File::create(&path)
                    .map(|f| Some(BufWriter::with_capacity(1 << 20, f)))
                    .map_err(|e| SceneError::io(&path, e))
            })
            .collect::<Result<_, _>>()?;
        Ok(Spill::Files {
            dir,
            writers,
            counts: vec![0; parts],
        })
    }

    /// Adds `rec` to partition `part`.
    pub fn push(&mut self, part: usize, rec: R) -> Result<(), SceneError> {
        match self {
            Spill::Memory(parts) => {
                parts[part].push(rec);
                Ok(())
            }
            Spill::Files {
                dir,
                writers,
                counts,
            } => {
                let w = writers[part].as_mut().ok_or_else(|| {
                    SceneError::format(dir.part(part), "spill partition written after it was read")
                })?;
                counts[part] += 1;
                w.write_all(bytemuck::bytes_of(&rec))
                    .map_err(|e| SceneError::io(dir.part(part), e))
            }
        }
    }

    /// Partition `part`'s candidates, in the order they were pushed; its file is deleted.
    pub fn take(&mut self, part: usize) -> Result<Vec<R>, SceneError> {
        match self {
            Spill::Memory(parts) => Ok(std::mem::take(&mut parts[part])),
            Spill::Files {
                dir,
                writers,
                counts,
            } => {
                let path = dir.part(part);
                if let Some(w) = writers[part].take() {
                    w.into_inner()
                        .map_err(|e| SceneError::io(&path, e.into_error()))?;
                }
                let n = usize::try_from(counts[part]).map_err(|_| {
                    SceneError::format(&path, "spill partition larger than memory can address")
                })?;
                let mut recs = vec![R::zeroed(); n];
                File::open(&path)
                    .and_then(|mut f| f.read_exact(bytemuck::cast_slice_mut(&mut recs)))
                    .map_err(|e| SceneError::io(&path, e))?;
                std::fs::remove_file(&path).map_err(|e| SceneError::io(&path, e))?;
                Ok(recs)
            }
        }
    }
}

/// A spill directory, removed with everything in it when dropped (also on error).
pub(super) struct SpillDir(PathBuf);

impl SpillDir {
    fn part(&self, p: usize) -> PathBuf {
        self.0.join(format!("part-{p:05}.bin"))
    }
}

impl Drop for SpillDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
