//! What the system says about this process: its resident memory now and at its peak (Linux's
//! `/proc/self/status`; `None` elsewhere). Below every stage, like [`crate::output`].

/// Peak resident memory of this process (`VmHWM`), bytes, where the system tells.
pub fn peak_rss_bytes() -> Option<u64> {
    status_kib("VmHWM:").map(|k| k * 1024)
}

/// Resident memory of this process now (`VmRSS`), bytes, where the system tells.
pub fn rss_bytes() -> Option<u64> {
    status_kib("VmRSS:").map(|k| k * 1024)
}

fn status_kib(key: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines()
        .find(|l| l.starts_with(key))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    #[test]
    #[cfg(target_os = "linux")]
    fn the_peak_is_at_least_the_resident_memory_now() {
        let now = super::rss_bytes().expect("VmRSS on Linux");
        let peak = super::peak_rss_bytes().expect("VmHWM on Linux");
        assert!(now > 0 && peak >= now, "{now} {peak}");
    }
}
