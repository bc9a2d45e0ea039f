//! Process memory figures for `info` and, later, the benchmarks.

/// Peak resident set size of this process in bytes (`VmHWM` in `/proc/self/status`), or `None`
/// where that is unavailable (not Linux, no procfs).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_status_kib(&status, "VmHWM:").map(|kib| kib * 1024)
}

/// The peak resident set size for a report line: "123 MiB", or "unknown".
pub fn peak_rss_text(peak: Option<u64>) -> String {
    peak.map_or("unknown".to_owned(), |b| {
        format!("{:.0} MiB", b as f64 / (1 << 20) as f64)
    })
}

/// The value of a `Key:   1234 kB` line of `/proc/<pid>/status`, in KiB.
fn parse_status_kib(status: &str, key: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with(key))?;
    let mut fields = line[key.len()..].split_whitespace();
    let value = fields.next()?.parse::<u64>().ok()?;
    match fields.next() {
        Some("kB") | None => Some(value),
        Some(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vmhwm() {
        let status =
            "Name:\tpathlight\nVmPeak:\t  20000 kB\nVmHWM:\t    5120 kB\nVmRSS:\t 4000 kB\n";
        assert_eq!(parse_status_kib(status, "VmHWM:"), Some(5120));
        assert_eq!(parse_status_kib(status, "VmSwap:"), None);
        assert_eq!(parse_status_kib("VmHWM:\tlots kB\n", "VmHWM:"), None);
    }

    #[test]
    fn peak_rss_is_plausible_on_linux() {
        if cfg!(target_os = "linux") && std::path::Path::new("/proc/self/status").exists() {
            let bytes = peak_rss_bytes().expect("VmHWM in /proc/self/status");
            assert!(bytes > 64 * 1024, "peak RSS {bytes} bytes");
        }
    }
}
