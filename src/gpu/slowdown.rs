//! A planted slowdown of one kernel, for tests of the regression gate: with
//! `TRILAB_INJECT_SLOWDOWN=NAME:N`, every ray-casting dispatch of a kernel whose name contains
//! `NAME` is recorded `N` times between its timestamps (the same rays, the same hits, so every
//! count and correctness figure is unchanged and only its time grows, about `N` times). This is
//! what a kernel that slowed alone looks like to `trilab compare`, made without editing a shader.

use crate::error::{Error, Result};

/// The environment variable `gpu::cast_rays` reads.
pub const INJECT_SLOWDOWN_ENV: &str = "TRILAB_INJECT_SLOWDOWN";

/// Most repeats: a planted slowdown is a test's, not a way to run for hours.
const MAX_REPEATS: u32 = 64;

/// `NAME:N`: dispatches of kernels whose name contains `NAME` run `N` times.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Slowdown {
    pub kernel: String,
    pub repeats: u32,
}

impl std::str::FromStr for Slowdown {
    type Err = Error;

    fn from_str(s: &str) -> Result<Slowdown> {
        let bad = || {
            Error::Usage(format!(
                "{INJECT_SLOWDOWN_ENV}=`{s}`: expected NAME:N, a kernel name (or part of one, such as \
                 raycast.unit.closest) and 2 <= N <= {MAX_REPEATS} repeats of its dispatches"
            ))
        };
        let (kernel, n) = s.trim().rsplit_once(':').ok_or_else(bad)?;
        let repeats: u32 = n.trim().parse().map_err(|_| bad())?;
        if kernel.trim().is_empty() || !(2..=MAX_REPEATS).contains(&repeats) {
            return Err(bad());
        }
        Ok(Slowdown { kernel: kernel.trim().to_owned(), repeats })
    }
}

impl Slowdown {
    /// The slowdown the environment asks for, if any.
    pub fn from_env() -> Result<Option<Slowdown>> {
        match std::env::var(INJECT_SLOWDOWN_ENV) {
            Ok(v) if !v.trim().is_empty() => v.parse().map(Some),
            _ => Ok(None),
        }
    }

    /// How many times a dispatch of `kernel` is recorded: 1 unless it is the one slowed.
    pub fn repeats_for(this: Option<&Slowdown>, kernel: &str) -> u32 {
        this.filter(|s| kernel.contains(&s.kernel)).map_or(1, |s| s.repeats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_name_and_repeats_and_refuses_the_rest() {
        let s: Slowdown = "raycast.unit.closest:3".parse().unwrap();
        assert_eq!(s, Slowdown { kernel: "raycast.unit.closest".into(), repeats: 3 });
        assert_eq!(Slowdown::repeats_for(Some(&s), "raycast.unit.closest_bvh4"), 3);
        assert_eq!(Slowdown::repeats_for(Some(&s), "raycast.mt.closest"), 1);
        assert_eq!(Slowdown::repeats_for(None, "raycast.unit.closest"), 1);
        for bad in ["raycast.unit", ":3", "x:1", "x:0", "x:65", "x:two"] {
            let e = bad.parse::<Slowdown>().unwrap_err().to_string();
            assert!(e.contains(INJECT_SLOWDOWN_ENV) && e.contains("NAME:N"), "{bad}: {e}");
        }
    }
}
