//! What a size the user typed will allocate, checked before the work starts. A count of rays,
//! pixels or triangles becomes a `Vec` long before anything reads it, and an allocation larger
//! than the machine's memory either aborts the process (`memory allocation of N bytes failed`,
//! exit 134) or grows until the kernel kills it. Each command turns its sizes into a lower bound
//! on the bytes they will take ([`Need`]) and [`check`]s it against the memory available now, so
//! a size that cannot fit is refused at once, naming the option; one that fits is never refused.
//! Ground floor: it imports nothing of trilab but the error type.

use crate::error::{Error, Result};

/// Bytes of one ray (origin, tmin, direction, tmax: `rays::Ray`).
pub const RAY_BYTES: u64 = 32;
/// Bytes of one hit record (t, u, v, triangle id: `rays::Hit`).
pub const HIT_BYTES: u64 = 16;

/// A lower bound on what some sizes will allocate: `count` items of `each` bytes, named by the
/// options that set the count (`--width 100000 --height 100000`) and what the items are.
#[derive(Clone, Debug)]
pub struct Need {
    /// The options and values, as the user typed them.
    pub options: String,
    /// The items, plural (`"32-byte rays"`).
    pub items: &'static str,
    /// How many: `None` when the count itself overflows 64 bits.
    pub count: Option<u64>,
    /// Bytes per item (a lower bound).
    pub each: u64,
}

impl Need {
    pub fn new(options: impl Into<String>, items: &'static str, count: Option<u64>, each: u64) -> Need {
        Need { options: options.into(), items, count, each }
    }

    /// The bytes, `None` past 2^64.
    pub fn bytes(&self) -> Option<u64> {
        self.count?.checked_mul(self.each)
    }
}

/// The memory a new allocation can have now: `TRILAB_MAX_MEMORY` (bytes) when set, else
/// `MemAvailable` of /proc/meminfo (free memory plus what the kernel can reclaim without
/// swapping); `None` where neither says (no check is then made beyond 64-bit overflow).
pub fn available() -> Option<u64> {
    if let Some(v) = std::env::var("TRILAB_MAX_MEMORY").ok().and_then(|v| v.trim().parse().ok()) {
        return Some(v);
    }
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    meminfo_available(&info)
}

fn meminfo_available(info: &str) -> Option<u64> {
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Refuses `needs` when together they take more than the memory available ([`available`]),
/// naming each need's options, its items and the sizes.
pub fn check(needs: &[Need]) -> Result<()> {
    check_against(needs, available())
}

fn check_against(needs: &[Need], available: Option<u64>) -> Result<()> {
    let total = needs.iter().try_fold(0u64, |acc, n| acc.checked_add(n.bytes()?));
    let fits = match (total, available) {
        (None, _) => false,
        (Some(t), Some(a)) => t <= a,
        (Some(_), None) => true,
    };
    if fits {
        return Ok(());
    }
    let what: Vec<String> = needs
        .iter()
        .map(|n| match (n.count, n.bytes()) {
            (Some(c), Some(b)) => format!("{}: {c} {} ({})", n.options, n.items, show_bytes(b)),
            (Some(c), None) => format!("{}: {c} {} (more than 2^64 bytes)", n.options, n.items),
            (None, _) => format!("{}: more than 2^64 {}", n.options, n.items),
        })
        .collect();
    let room = match available {
        Some(a) => format!("the {} of memory available now", show_bytes(a)),
        None => "what 64 bits can count".into(),
    };
    let total = total.map(show_bytes).unwrap_or_else(|| "2^64 bytes".into());
    Err(Error::Usage(match needs {
        [one] => {
            let count = one.count.map(|c| c.to_string()).unwrap_or_else(|| "more than 2^64".into());
            format!(
                "{}: {count} {} take at least {total}, more than {room}; choose a smaller size",
                one.options, one.items
            )
        }
        _ => format!("these sizes take at least {total}, more than {room}; choose smaller ones: {}", what.join("; ")),
    }))
}

/// `bytes` in binary units, three significant digits.
pub fn show_bytes(bytes: u64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
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
    fn meminfo_gives_the_available_bytes() {
        let info = "MemTotal:       24600000 kB\nMemFree:         1000 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(meminfo_available(info), Some(20_000_000 * 1024));
        assert_eq!(meminfo_available("MemTotal: 5 kB\n"), None);
    }

    #[test]
    fn sizes_that_cannot_fit_are_refused_naming_the_option() {
        let gib = 1u64 << 30;
        let rays = |n: u64| Need::new(format!("--random-rays {n}"), "32-byte rays", Some(n), RAY_BYTES);
        // 10^10 rays x 32 B = 298 GiB, against 20 GiB.
        let e = check_against(&[rays(10_000_000_000)], Some(20 * gib)).unwrap_err().to_string();
        assert!(e.contains("--random-rays 10000000000") && e.contains("298.0 GiB") && e.contains("20.0 GiB"), "{e}");
        // What fits is never refused, nor anything where the machine does not say.
        check_against(&[rays(1_000_000)], Some(20 * gib)).unwrap();
        check_against(&[rays(10_000_000_000)], None).unwrap();
        // Needs add up, and an overflowing product is refused even where memory is unknown.
        assert!(check_against(&[rays(400_000_000), rays(400_000_000)], Some(20 * gib)).is_err());
        let e = check_against(&[Need::new("--width 4294967295 --height 4294967295", "rays", None, 32)], None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--width 4294967295") && e.contains("2^64"), "{e}");
        let huge = Need::new("--x", "things", Some(u64::MAX / 2), 4);
        assert!(check_against(&[huge], None).unwrap_err().to_string().contains("at least 2^64 bytes"));
    }

    #[test]
    fn bytes_are_shown_in_binary_units() {
        assert_eq!(show_bytes(512), "512 B");
        assert_eq!(show_bytes(3 << 20), "3.0 MiB");
        assert_eq!(show_bytes(320_000_000_000), "298.0 GiB");
    }
}
