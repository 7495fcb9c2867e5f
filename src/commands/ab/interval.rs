//! The ratio of two sides' kernel times with a confidence interval, from few rounds: paired
//! where each round timed the two sides of a cell back to back ([`Ratio::paired`]), else
//! Welch's unpaired interval below (sides that timed whole rounds apart: a worker of
//! protocol 1).
//!
//! Welch's t on log times: d = mean(ln b) - mean(ln a), its standard error
//! se = sqrt(s_a^2 / n_a + s_b^2 / n_b), the Welch-Satterthwaite degrees of freedom, and the
//! interval exp(d +- t_{(1+level)/2, df} se) for the ratio of geometric means B/A (Welch,
//! "The generalization of Student's problem when several different population variances are
//! involved", Biometrika 34, 1947). Why this statistic for a handful of rounds: timings are
//! positive with multiplicative noise, so their logs are close to symmetric and a ratio becomes
//! a difference; Student's t, not the normal, pays for estimating the spread from 5-10 rounds;
//! and Welch does not assume the two drivers are equally noisy (a new driver may well not be).
//! The interleaved, balanced order (A B B A ...) keeps a slow drift of the host out of d.

use statrs::distribution::{ContinuousCDF, StudentsT};

/// Rounds a side an interval needs before its verdict judges time. With 2 or 3 the interval
/// rests on one or two degrees of freedom: wide when the rounds differ (t = 12.7 at one), and
/// of zero width when they happen to agree to the nanosecond, a verdict of chance either way.
pub const MIN_JUDGED_ROUNDS: usize = 4;

/// B/A with its interval.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Ratio {
    /// exp(mean ln b - mean ln a): the ratio of geometric means.
    pub ratio: f64,
    pub low: f64,
    pub high: f64,
    /// The interval's level (0.95).
    pub level: f64,
    pub rounds_a: usize,
    pub rounds_b: usize,
}

impl Ratio {
    /// Welch's interval for B/A at `level` from the sides' times (each all positive, at least
    /// two rounds a side); `None` otherwise.
    pub fn welch(a: &[f64], b: &[f64], level: f64) -> Option<Ratio> {
        if a.len() < 2 || b.len() < 2 || a.iter().chain(b).any(|&t| !(t > 0.0 && t.is_finite())) {
            return None;
        }
        let (ma, va) = mean_var(a);
        let (mb, vb) = mean_var(b);
        let (na, nb) = (a.len() as f64, b.len() as f64);
        let d = mb - ma;
        let (ea, eb) = (va / na, vb / nb);
        let se = (ea + eb).sqrt();
        let half = if se == 0.0 {
            0.0
        } else {
            let df = (ea + eb).powi(2) / (ea * ea / (na - 1.0) + eb * eb / (nb - 1.0));
            let t = StudentsT::new(0.0, 1.0, df).ok()?.inverse_cdf(0.5 + level / 2.0);
            t * se
        };
        Some(Ratio {
            ratio: d.exp(),
            low: (d - half).exp(),
            high: (d + half).exp(),
            level,
            rounds_a: a.len(),
            rounds_b: b.len(),
        })
    }

    /// The paired interval for B/A at `level` from `d`, each pair's ln(b) - ln(a) (a cell's two
    /// sides timed back to back, so the moment's load on the host is common to both and cancels
    /// in the difference): exp(mean d +- t_{(1+level)/2, n-1} sd(d) / sqrt(n)), Student's t on
    /// the differences ("The probable error of a mean", Biometrika 6, 1908). `None` with fewer
    /// than two pairs or a difference that is not finite.
    pub fn paired(d: &[f64], level: f64) -> Option<Ratio> {
        if d.len() < 2 || d.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let n = d.len() as f64;
        let m = d.iter().sum::<f64>() / n;
        let var = d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
        let half = if var == 0.0 {
            0.0
        } else {
            StudentsT::new(0.0, 1.0, n - 1.0).ok()?.inverse_cdf(0.5 + level / 2.0) * (var / n).sqrt()
        };
        Some(Ratio {
            ratio: m.exp(),
            low: (m - half).exp(),
            high: (m + half).exp(),
            level,
            rounds_a: d.len(),
            rounds_b: d.len(),
        })
    }

    /// Half the interval's width on the log scale, a fraction: how precisely the ratio is known
    /// (0.02 is about +-2 %).
    pub fn half_width(&self) -> f64 {
        (self.high / self.low).ln() / 2.0
    }

    /// The verdict at `threshold` (a fraction: 0.05 for 5 %); [`Verdict::TooFewRounds`] with
    /// fewer than [`MIN_JUDGED_ROUNDS`] a side.
    pub fn verdict(&self, threshold: f64) -> Verdict {
        if self.rounds_a.min(self.rounds_b) < MIN_JUDGED_ROUNDS {
            Verdict::TooFewRounds
        } else if self.low > 1.0 + threshold {
            Verdict::HurtBeyondThreshold
        } else if self.low > 1.0 {
            Verdict::Hurt
        } else if self.high < 1.0 {
            Verdict::Helped
        } else {
            Verdict::Same
        }
    }
}

/// What a cell's interval says about B against A (time: higher is slower).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// The whole interval below 1: B is faster.
    Helped,
    /// The interval holds 1.
    Same,
    /// The whole interval above 1, not all of it past the threshold.
    Hurt,
    /// The whole interval above 1 + threshold: fails the run.
    HurtBeyondThreshold,
    /// Fewer than [`MIN_JUDGED_ROUNDS`] rounds a side: the ratio is shown, time not judged.
    TooFewRounds,
}

impl Verdict {
    /// Whether it says the time moved (helped or hurt).
    pub fn moved(self) -> bool {
        matches!(self, Verdict::Helped | Verdict::Hurt | Verdict::HurtBeyondThreshold)
    }
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Verdict::Helped => "helped",
            Verdict::Same => "no change",
            Verdict::Hurt => "hurt",
            Verdict::HurtBeyondThreshold => "HURT beyond threshold",
            Verdict::TooFewRounds => "not judged (fewer than 4 rounds)",
        })
    }
}

fn mean_var(xs: &[f64]) -> (f64, f64) {
    let l: Vec<f64> = xs.iter().map(|x| x.ln()).collect();
    let n = l.len() as f64;
    let m = l.iter().sum::<f64>() / n;
    (m, l.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_known_ratio_is_inside_its_interval_and_the_width_follows_the_t_quantile() {
        // ln a = {0, 0.1, -0.1}, ln b = ln a + ln 2: d = ln 2 exactly, s^2 = 0.01 each side,
        // se = sqrt(0.01/3 * 2), df = 4, t_0.975,4 = 2.7764451.
        let a: Vec<f64> = [0.0f64, 0.1, -0.1].iter().map(|x| x.exp()).collect();
        let b: Vec<f64> = a.iter().map(|x| 2.0 * x).collect();
        let r = Ratio::welch(&a, &b, 0.95).unwrap();
        assert!((r.ratio - 2.0).abs() < 1e-12, "{r:?}");
        let half = 2.7764451 * (0.02f64 / 3.0).sqrt();
        assert!((r.half_width() - half).abs() < 1e-6, "{} vs {half}", r.half_width());
        assert!((r.low - 2.0 * (-half).exp()).abs() < 1e-6);
        // Three rounds a side: the ratio is known, time is not judged.
        assert_eq!(r.verdict(0.05), Verdict::TooFewRounds);
        let a4: Vec<f64> = [0.0f64, 0.1, -0.1, 0.05].iter().map(|x| x.exp()).collect();
        let b4: Vec<f64> = a4.iter().map(|x| 2.0 * x).collect();
        assert_eq!(Ratio::welch(&a4, &b4, 0.95).unwrap().verdict(0.05), Verdict::HurtBeyondThreshold);
        let back = Ratio::welch(&b4, &a4, 0.95).unwrap();
        assert!((back.ratio - 0.5).abs() < 1e-12 && back.verdict(0.05) == Verdict::Helped);
    }

    #[test]
    fn fewer_than_four_rounds_are_not_judged_even_when_they_agree_exactly() {
        // Two pairs with the same difference: a zero-width interval at 1.5, which would read as
        // "HURT beyond threshold" from two samples.
        let r = Ratio::paired(&[1.5f64.ln(), 1.5f64.ln()], 0.95).unwrap();
        assert_eq!((r.low, r.high), (r.ratio, r.ratio));
        assert_eq!(r.verdict(0.05), Verdict::TooFewRounds);
        assert!(!Verdict::TooFewRounds.moved());
        let four = Ratio::paired(&[1.5f64.ln(); 4], 0.95).unwrap();
        assert_eq!(four.verdict(0.05), Verdict::HurtBeyondThreshold);
    }

    #[test]
    fn noise_around_one_is_no_change_and_bad_input_has_no_interval() {
        let a = [1.00, 1.04, 0.97, 1.02, 0.99];
        let b = [1.01, 0.98, 1.03, 0.99, 1.00];
        assert_eq!(Ratio::welch(&a, &b, 0.95).unwrap().verdict(0.05), Verdict::Same);
        assert!(Ratio::welch(&a[..1], &b, 0.95).is_none());
        assert!(Ratio::welch(&[1.0, 0.0], &b, 0.95).is_none());
        // Identical constant times: a zero-width interval at 1.
        let r = Ratio::welch(&[2.0; 4], &[2.0; 4], 0.95).unwrap();
        assert_eq!((r.low, r.high, r.verdict(0.05)), (1.0, 1.0, Verdict::Same));
    }

    #[test]
    fn the_paired_interval_is_student_s_t_on_the_differences() {
        // d = ln 1.1 + {0, 0.02, -0.02, 0.01, -0.01}: mean ln 1.1, sd sqrt(0.001/4), n = 5,
        // t_0.975,4 = 2.7764451.
        let d: Vec<f64> = [0.0, 0.02, -0.02, 0.01, -0.01].iter().map(|x| 1.1f64.ln() + x).collect();
        let r = Ratio::paired(&d, 0.95).unwrap();
        assert!((r.ratio - 1.1).abs() < 1e-12, "{r:?}");
        let half = 2.7764451 * (0.001f64 / 4.0 / 5.0).sqrt();
        assert!((r.half_width() - half).abs() < 1e-6, "{} vs {half}", r.half_width());
        assert_eq!((r.rounds_a, r.rounds_b, r.verdict(0.05)), (5, 5, Verdict::HurtBeyondThreshold));
        // A load that moves both sides of every pair alike is not in the differences: the same
        // ratio, however large the moves.
        let a = [1.0, 3.0, 0.5, 2.0];
        let b: Vec<f64> = a.iter().map(|x| x * 1.1).collect();
        let d: Vec<f64> = a.iter().zip(&b).map(|(x, y): (&f64, &f64)| y.ln() - x.ln()).collect();
        let r = Ratio::paired(&d, 0.95).unwrap();
        assert!((r.ratio - 1.1).abs() < 1e-12 && r.half_width() < 1e-12, "{r:?}");
        assert!(Ratio::welch(&a, &b, 0.95).unwrap().verdict(0.05) == Verdict::Same, "unpaired, the moves hide it");
        assert!(Ratio::paired(&d[..1], 0.95).is_none() && Ratio::paired(&[0.0, f64::NAN], 0.95).is_none());
    }

    /// At the 95 % level, A against A calls about 5 % of cells changed: checked here by
    /// simulation on log-normal noise (a seeded generator, 4000 cells of 5 rounds a side).
    #[test]
    fn the_false_alarm_rate_matches_the_level() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let mut normal = || {
            // Box-Muller.
            let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let cells = 4000;
        let mut alarms = 0;
        for _ in 0..cells {
            let a: Vec<f64> = (0..5).map(|_| (0.05 * normal()).exp()).collect();
            let b: Vec<f64> = (0..5).map(|_| (0.05 * normal()).exp()).collect();
            if Ratio::welch(&a, &b, 0.95).unwrap().verdict(0.05) != Verdict::Same {
                alarms += 1;
            }
        }
        let rate = alarms as f64 / cells as f64;
        // Welch's test is close to exact here: 5 % +- about 1 % (3 sigma of a binomial).
        assert!((0.035..0.065).contains(&rate), "false-alarm rate {rate}");
    }
}
