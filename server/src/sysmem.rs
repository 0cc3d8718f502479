//! How much memory this process may use: the cgroup's limit where there is one (a container's
//! `memory.max`), else the machine's total, from `/proc`. The server's memory budget and the
//! build's default sample limit are fractions of it.

/// The memory this process may use, bytes: the lower of the cgroup v2 limit and the machine's
/// total; `None` where neither can be read (not Linux, or `/proc` and `/sys` hidden).
pub fn usable_memory() -> Option<u64> {
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok());
    let machine = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        s.lines()
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map(|kb| kb * 1024)
    });
    match (cgroup, machine) {
        (Some(c), Some(m)) => Some(c.min(m)),
        (Some(x), None) | (None, Some(x)) => Some(x),
        (None, None) => None,
    }
}
