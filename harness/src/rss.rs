//! Resident memory of this process: current (`memory-stats`), peak (Linux `VmHWM`) and, on
//! Linux, the current set by kind (`RssAnon`, `RssFile`, `RssShmem`).

/// Current resident set size, bytes (0 if unknown).
pub fn current_bytes() -> u64 {
    memory_stats::memory_stats()
        .map(|m| m.physical_mem as u64)
        .unwrap_or(0)
}

/// Peak resident set size, bytes (Linux `VmHWM`; the current size elsewhere).
pub fn peak_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| status_bytes(&s, "VmHWM:"))
        .unwrap_or_else(current_bytes)
}

/// A `/proc/self/status` field given in kB (`name` with its colon), in bytes.
fn status_bytes(status: &str, name: &str) -> Option<u64> {
    status
        .lines()
        .find(|l| l.starts_with(name))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<u64>().ok())
        .map(|kb| kb * 1024)
}

/// The current resident set by kind, bytes (Linux `/proc/self/status`; `None` elsewhere).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Breakdown {
    /// Anonymous memory: the heap, stacks, private mappings (a software rasteriser's GPU
    /// buffers among them).
    pub anon: u64,
    /// File-backed pages: the binary, libraries and memory-mapped files (a repository or a
    /// scene read through a mapping).
    pub file: u64,
    /// Shared memory (`memfd`, `shm`: some drivers' buffers).
    pub shmem: u64,
}

impl Breakdown {
    /// The larger of each kind (maxima over frames: their sum may exceed any one moment's).
    pub fn max(self, o: Self) -> Self {
        Self {
            anon: self.anon.max(o.anon),
            file: self.file.max(o.file),
            shmem: self.shmem.max(o.shmem),
        }
    }

    /// Parses `/proc/self/status` text; `None` without the three fields.
    pub fn parse(status: &str) -> Option<Self> {
        Some(Self {
            anon: status_bytes(status, "RssAnon:")?,
            file: status_bytes(status, "RssFile:")?,
            shmem: status_bytes(status, "RssShmem:")?,
        })
    }
}

/// The current resident set by kind (Linux only).
pub fn breakdown() -> Option<Breakdown> {
    Breakdown::parse(&std::fs::read_to_string("/proc/self/status").ok()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_status_fields_are_read_in_bytes_and_their_maxima_kept() {
        let s =
            "Name:\tx\nVmHWM:\t  900 kB\nRssAnon:\t  100 kB\nRssFile:\t 20 kB\nRssShmem:\t 3 kB\n";
        let a = Breakdown::parse(s).unwrap();
        assert_eq!((a.anon, a.file, a.shmem), (102_400, 20_480, 3_072));
        assert_eq!(Breakdown::parse("RssAnon:\t1 kB\n"), None);
        let b = Breakdown {
            anon: 1,
            file: 50_000,
            shmem: 0,
        };
        assert_eq!(
            a.max(b),
            Breakdown {
                anon: 102_400,
                file: 50_000,
                shmem: 3_072
            }
        );
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn this_process_has_a_breakdown() {
        let b = breakdown().unwrap();
        assert!(b.anon > 0 && b.file > 0, "{b:?}");
    }
}
