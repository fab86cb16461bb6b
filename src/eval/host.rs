//! The machine a benchmark ran on, as its page states it beside every figure: CPU, cores,
//! kernel and the load when the run started (the machine may be shared with builds).

/// One line: CPU model, cores, kernel, load average.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .map(|s| format!("Linux {}", s.trim()))
        .unwrap_or_else(|_| std::env::consts::OS.into());
    // The machine may be shared (parallel builds): the load explains the tails.
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_owned))
        .map(|l| format!(", load average {l} when the run started"))
        .unwrap_or_default();
    format!("{cpu}, {cores} cores, {kernel}{load}")
}
