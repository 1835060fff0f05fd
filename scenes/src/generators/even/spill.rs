//! Where the candidates wait between the pass that sorts them into partitions of tiles and
//! the passes that eliminate one partition at a time: in memory, or out of core in one file
//! per partition (16 bytes per candidate), each file deleted once its partition is done.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::PathBuf;

use crate::SceneError;

/// One waiting candidate: its position and its index in candidate order.
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub(super) struct Rec {
    pub pos: [f32; 3],
    pub idx: u32,
}

/// Bytes a file spill needs per candidate.
pub(super) const REC_BYTES: u64 = std::mem::size_of::<Rec>() as u64;

/// The partitions' waiting candidates.
pub(super) enum Spill {
    Memory(Vec<Vec<Rec>>),
    Files {
        dir: SpillDir,
        writers: Vec<Option<BufWriter<File>>>,
        counts: Vec<u64>,
    },
}

impl Spill {
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
    pub fn push(&mut self, part: usize, rec: Rec) -> Result<(), SceneError> {
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
    pub fn take(&mut self, part: usize) -> Result<Vec<Rec>, SceneError> {
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
                let mut recs = vec![
                    Rec {
                        pos: [0.0; 3],
                        idx: 0
                    };
                    n
                ];
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
