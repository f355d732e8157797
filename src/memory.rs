//! Resident memory of this process: the figures behind "memory stays flat" in `tremorscan bench`
//! and in the progress lines of `record` and `replay`.
//!
//! Read from Linux's `/proc/self/status`: `VmRSS` (resident now) and `VmHWM` (the highest it has
//! been). The kernel keeps these counters per CPU, so they are approximate by some pages (tens of
//! kB). Where that file does not exist (other systems) the figures are unknown (`None`), and
//! callers say so rather than print a number.

/// Resident memory now and at its highest so far, bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResidentMemory {
    pub resident_bytes: u64,
    pub peak_bytes: u64,
}

impl ResidentMemory {
    /// This process's figures, or `None` where the system does not report them.
    pub fn now() -> Option<Self> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        parse_status(&status)
    }
}

/// `VmRSS` and `VmHWM` of a `/proc/<pid>/status` text (values in kB).
fn parse_status(text: &str) -> Option<ResidentMemory> {
    let kib = |name: &str| {
        text.lines().find_map(|line| {
            let value = line.strip_prefix(name)?.trim().strip_suffix("kB")?;
            value.trim().parse::<u64>().ok()
        })
    };
    Some(ResidentMemory {
        resident_bytes: kib("VmRSS:")? * 1024,
        peak_bytes: kib("VmHWM:")? * 1024,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn the_status_fields_are_read_in_bytes() {
        let text =
            "Name:\ttremorscan\nVmPeak:\t 999 kB\nVmHWM:\t  450560 kB\nVmRSS:\t  440320 kB\n";
        assert_eq!(
            parse_status(text),
            Some(ResidentMemory {
                resident_bytes: 440_320 * 1024,
                peak_bytes: 450_560 * 1024,
            })
        );
        assert_eq!(parse_status("Name:\tx\nVmRSS:\t12 kB\n"), None, "no VmHWM");
        assert_eq!(parse_status("VmRSS:\tmany kB\nVmHWM:\t1 kB\n"), None);
    }
}
