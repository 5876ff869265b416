//! Memory guards for sizes that come from files and flags. A count a user typed or a header
//! declared (steps, cells, nodes) is checked before anything is allocated for it: its byte size
//! must not overflow and must fit in the memory the process can get (`MemAvailable` plus free
//! swap on Linux, and less under an address-space limit or a control group's memory limit). Failing either gives an [`InputError`] naming the source, never an abort.

use super::InputError;

/// Bytes the machine can still give this process: the least of `MemAvailable + SwapFree`
/// (`/proc/meminfo`), the room left under the process's address-space limit (`ulimit -v`:
/// `/proc/self/limits` less the current `VmSize`) and under its control group's memory limit
/// (cgroup v2 `memory.max - memory.current`, or v1 `memory.limit_in_bytes -
/// memory.usage_in_bytes`); `None` where none is known (other systems), in which case only
/// overflow is checked and allocation failures are caught by `try_reserve`.
pub fn available_bytes() -> Option<u64> {
    available().map(|(b, _)| b)
}

/// [`available_bytes`] with the limit that sets it (`"memory"`, `"address-space limit"`,
/// `"control-group limit"`), for messages.
pub fn available() -> Option<(u64, &'static str)> {
    [
        (machine_bytes(), "memory"),
        (rlimit_room(), "address-space limit (ulimit -v)"),
        (cgroup_room(), "control-group memory limit"),
    ]
    .into_iter()
    .filter_map(|(b, what)| b.map(|b| (b, what)))
    .min_by_key(|(b, _)| *b)
}

/// A `/proc`-style `Name:   N kB` field of `text`, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line[name.len()..].trim().trim_end_matches("kB").trim().parse().ok()?;
    kib.checked_mul(1024)
}

/// `MemAvailable + SwapFree`.
fn machine_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    Some(kib_field(&text, "MemAvailable:")?.saturating_add(kib_field(&text, "SwapFree:").unwrap_or(0)))
}

/// The address-space limit less the current virtual size (`None` when unlimited or unknown).
fn rlimit_room() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits.lines().find(|l| l.starts_with("Max address space"))?;
    // Columns: name (three words), soft limit, hard limit, units.
    let soft: u64 = line.split_whitespace().nth(3)?.parse().ok()?;
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    Some(soft.saturating_sub(kib_field(&status, "VmSize:").unwrap_or(0)))
}

/// The control group's memory limit less its usage (`None` when unlimited or unknown).
fn cgroup_room() -> Option<u64> {
    let read = |p: &str| -> Option<u64> { std::fs::read_to_string(p).ok()?.trim().parse().ok() };
    // cgroup v2: the process's group from /proc/self/cgroup ("0::/path").
    if let Some(rel) = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|t| t.lines().find_map(|l| l.strip_prefix("0::").map(str::to_string)))
    {
        let dir = format!("/sys/fs/cgroup{}", rel.trim_end_matches('/'));
        if let (Some(max), Some(cur)) = (
            read(&format!("{dir}/memory.max")),
            read(&format!("{dir}/memory.current")),
        ) {
            return Some(max.saturating_sub(cur));
        }
        if let (Some(max), Some(cur)) = (read("/sys/fs/cgroup/memory.max"), read("/sys/fs/cgroup/memory.current")) {
            return Some(max.saturating_sub(cur));
        }
    }
    // cgroup v1 (a limit near 2^63 means none).
    let max = read("/sys/fs/cgroup/memory/memory.limit_in_bytes").filter(|&m| m < 1 << 62)?;
    let cur = read("/sys/fs/cgroup/memory/memory.usage_in_bytes").unwrap_or(0);
    Some(max.saturating_sub(cur))
}

/// The bytes of `count` items of `bytes_each` bytes, checked against overflow and against
/// [`available_bytes`]. `what` names the source in the error (`"--steps 10000000000"`,
/// `"mesh.msh line 5: 1e12 nodes"`).
pub fn check(what: &str, count: usize, bytes_each: usize) -> Result<usize, InputError> {
    let bytes = count.checked_mul(bytes_each).ok_or_else(|| {
        InputError::out_of_memory(format!(
            "{what}: {count} items of {bytes_each} bytes overflow the address space"
        ))
    })?;
    if let Some((free, limit)) = available() {
        if bytes as u64 > free {
            return Err(InputError::out_of_memory(format!(
                "{what}: needs {} of memory, the process has {} available (its {limit})",
                human(bytes as u64),
                human(free)
            )));
        }
    }
    Ok(bytes)
}

/// A byte count for messages (`12.3 GiB`).
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overflow_and_absurd_sizes_are_errors_naming_the_source() {
        let e = check("--steps 18446744073709551615", usize::MAX, 8).unwrap_err();
        assert!(e.message().contains("--steps 18446744073709551615"), "{e}");
        assert!(e.message().contains("overflow"), "{e}");
        if available_bytes().is_some() {
            let e = check("header", 1 << 50, 24).unwrap_err();
            assert!(e.message().contains("available"), "{e}");
        }
        assert_eq!(check("small", 10, 8).unwrap(), 80);
    }

    #[test]
    fn human_sizes() {
        assert_eq!(human(512), "512 B");
        assert_eq!(human(3 << 30), "3.0 GiB");
    }
}
