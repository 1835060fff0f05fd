//! Resident memory of this process: current (`memory-stats`) and peak (Linux `VmHWM`).

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
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<u64>().ok())
        })
        .map(|kb| kb * 1024)
        .unwrap_or_else(current_bytes)
}
