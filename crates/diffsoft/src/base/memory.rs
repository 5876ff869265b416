//! Memory guards for sizes that come from files and flags. A count a user typed or a header
//! declared (steps, cells, nodes) is checked before anything is allocated for it: its byte size
//! must not overflow and must fit in the memory the machine can give (`MemAvailable` plus free
//! swap on Linux). Failing either gives an [`InputError`] naming the source, never an abort.

use super::InputError;

/// Bytes the machine can still give this process: `MemAvailable + SwapFree` from
/// `/proc/meminfo`, or `None` where that is unknown (other systems), in which case only overflow
/// is checked and allocation failures are caught by `try_reserve`.
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(name))?;
        let kib: u64 = line[name.len()..].trim().trim_end_matches("kB").trim().parse().ok()?;
        kib.checked_mul(1024)
    };
    Some(field("MemAvailable:")?.saturating_add(field("SwapFree:").unwrap_or(0)))
}

/// The bytes of `count` items of `bytes_each` bytes, checked against overflow and against
/// [`available_bytes`]. `what` names the source in the error (`"--steps 10000000000"`,
/// `"mesh.msh line 5: 1e12 nodes"`).
pub fn check(what: &str, count: usize, bytes_each: usize) -> Result<usize, InputError> {
    let bytes = count.checked_mul(bytes_each).ok_or_else(|| {
        InputError::new(format!(
            "{what}: {count} items of {bytes_each} bytes overflow the address space"
        ))
    })?;
    if let Some(free) = available_bytes() {
        if bytes as u64 > free {
            return Err(InputError::new(format!(
                "{what}: needs {} of memory, the machine has {} available",
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
