//! What the operating system says about this process and the machine
//! (Linux /proc; None elsewhere).

/// Peak resident memory of process `pid` so far ("VmHWM"), in bytes.
pub fn peak_memory_of(pid: u32) -> Option<u64> {
    status_kib(&format!("/proc/{pid}/status"), "VmHWM:")
}

/// Peak resident memory of this process so far, in bytes.
pub fn peak_memory() -> Option<u64> {
    status_kib("/proc/self/status", "VmHWM:")
}

fn status_kib(path: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kib * 1024)
}

/// Cores available to this process.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// One line naming the machine: CPU model, cores, memory.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let mem = status_kib("/proc/meminfo", "MemTotal:")
        .map(|b| format!(", {:.0} GiB", b as f64 / (1u64 << 30) as f64))
        .unwrap_or_default();
    format!("{cpu}, {} cores{mem}", cores())
}

#[cfg(test)]
mod tests {
    #[cfg(target_os = "linux")]
    #[test]
    fn peak_memory_grows_with_an_allocation() {
        let before = super::peak_memory().unwrap();
        let v = vec![1u8; 64 << 20];
        std::hint::black_box(&v);
        let after = super::peak_memory().unwrap();
        assert!(after >= before && after >= 64 << 20, "{before} -> {after}");
        assert!(super::machine().contains("cores"));
    }
}
