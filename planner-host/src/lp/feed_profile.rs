//! The feed limit along a path as a step function of arc length: v̄(s).
//!
//! The paper plans one feed limit v̄ per path, the rows (11) q(s) ≤ v̄².
//! A part program changes its feed inside a run of tangent moves (each `F`
//! applies from its block on). With a profile, row (11) at a point s is
//! q(s) ≤ v̄(s)², and the static caps and the exact check use v̄(s) too.
//! The transitions need no rows of their own: q is a cubic B-spline held to
//! every acceleration and jerk row, so it slows down *before* a block with a
//! lower feed (q must be under the new limit where that block starts) and
//! speeds up only after the block with a higher feed has begun, with
//! jerk-limited ramps. At a break the lower of the two feeds applies, so a
//! check point exactly on the break holds the stricter one.

/// Feed limits on consecutive stretches of a path: `feeds[k]` (mm/s) on
/// [`starts[k]`, `starts[k + 1]`) (mm of arc length), the last up to the
/// path's end.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FeedProfile {
    starts: Vec<f64>,
    feeds: Vec<f64>,
}

/// Why a feed profile was refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FeedProfileError {
    /// No stretch, or the first does not start at s = 0.
    #[error("a feed profile starts at s = 0 and has at least one stretch")]
    Start,
    /// A start not after the one before it, or not finite.
    #[error("feed profile stretch {index} starts at {s_mm} mm: starts must increase")]
    Order {
        /// Stretch index.
        index: usize,
        /// Its start, mm.
        s_mm: f64,
    },
    /// A feed that is not positive and finite.
    #[error("feed profile stretch {index}: feed {feed_mm_s} mm/s must be positive and finite")]
    Feed {
        /// Stretch index.
        index: usize,
        /// The feed, mm/s.
        feed_mm_s: f64,
    },
}

impl FeedProfile {
    /// A profile from `(start s, feed)` pairs, in order, the first at s = 0.
    /// Neighbours with the same feed are merged.
    pub fn new(stretches: &[(f64, f64)]) -> Result<FeedProfile, FeedProfileError> {
        if stretches.first().is_none_or(|&(s, _)| s != 0.0) {
            return Err(FeedProfileError::Start);
        }
        let mut p = FeedProfile {
            starts: Vec::with_capacity(stretches.len()),
            feeds: Vec::with_capacity(stretches.len()),
        };
        for (index, &(s, f)) in stretches.iter().enumerate() {
            if !(f > 0.0 && f.is_finite()) {
                return Err(FeedProfileError::Feed { index, feed_mm_s: f });
            }
            if !s.is_finite() || p.starts.last().is_some_and(|&l| s <= l) {
                return Err(FeedProfileError::Order { index, s_mm: s });
            }
            if p.feeds.last() != Some(&f) {
                p.starts.push(s);
                p.feeds.push(f);
            }
        }
        Ok(p)
    }

    /// One feed from s = 0 on (a plan's v̄; taken as it is).
    pub fn constant(feed_mm_s: f64) -> FeedProfile {
        FeedProfile {
            starts: vec![0.0],
            feeds: vec![feed_mm_s],
        }
    }

    /// The feed limit at `s`: the stretch's holding s; on a break (within
    /// 1e-9 mm) the lower of the two.
    pub fn at(&self, s: f64) -> f64 {
        let k = self.starts.partition_point(|&b| b <= s).saturating_sub(1);
        let mut f = self.feeds[k];
        for j in [k, k + 1] {
            if j > 0 && j < self.starts.len() && (self.starts[j] - s).abs() <= 1e-9 {
                f = f.min(self.feeds[j - 1]).min(self.feeds[j]);
            }
        }
        f
    }

    /// The highest feed limit on [a, b].
    pub fn max_on(&self, a: f64, b: f64) -> f64 {
        let k0 = self.starts.partition_point(|&x| x <= a).saturating_sub(1);
        let k1 = self.starts.partition_point(|&x| x < b).max(k0 + 1);
        self.feeds[k0..k1.min(self.feeds.len())]
            .iter()
            .fold(0.0f64, |m, &f| m.max(f))
    }

    /// The lowest feed limit on [a, b].
    pub fn min_on(&self, a: f64, b: f64) -> f64 {
        let k0 = self.starts.partition_point(|&x| x <= a).saturating_sub(1);
        let k1 = self.starts.partition_point(|&x| x < b).max(k0 + 1);
        self.feeds[k0..k1.min(self.feeds.len())]
            .iter()
            .fold(f64::INFINITY, |m, &f| m.min(f))
    }

    /// The highest feed limit of the profile.
    pub fn max(&self) -> f64 {
        self.feeds.iter().fold(0.0f64, |m, &f| m.max(f))
    }

    /// Where the feed changes (the starts after the first), mm.
    pub fn breaks(&self) -> &[f64] {
        &self.starts[1..]
    }

    /// The stretches as `(start s, feed)`.
    pub fn stretches(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.starts.iter().copied().zip(self.feeds.iter().copied())
    }

    /// Every feed multiplied by `alpha` (> 0): a feedrate override level.
    pub fn scaled(&self, alpha: f64) -> FeedProfile {
        FeedProfile {
            starts: self.starts.clone(),
            feeds: self.feeds.iter().map(|f| f * alpha).collect(),
        }
    }

    /// This profile on [0, `at`), `after`'s from `at` on: a feed changed
    /// at `at` (a feedrate override taking effect there).
    pub fn switched_at(&self, at: f64, after: &FeedProfile) -> FeedProfile {
        let mut pairs: Vec<(f64, f64)> = self.stretches().filter(|&(s, _)| s < at).collect();
        // (the stretch of `after` holding `at`, not the lower on a break)
        let from = after.stretches().take_while(|&(s, _)| s <= at).last();
        pairs.extend(from.map(|(_, f)| (at.max(0.0), f)));
        pairs.extend(after.stretches().filter(|&(s, _)| s > at));
        FeedProfile::new(&pairs).unwrap_or_else(|_| after.clone())
    }

    /// Every feed capped at `cap`.
    pub fn capped(&self, cap: f64) -> FeedProfile {
        let pairs: Vec<(f64, f64)> = self.stretches().map(|(s, f)| (s, f.min(cap))).collect();
        FeedProfile::new(&pairs).unwrap_or_else(|_| self.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_profile_is_a_step_function_with_the_lower_feed_on_its_breaks() {
        let p = FeedProfile::new(&[(0.0, 10.0), (5.0, 20.0), (8.0, 20.0), (9.0, 4.0)]).unwrap();
        assert_eq!(p.breaks(), &[5.0, 9.0]);
        assert_eq!(p.at(0.0), 10.0);
        assert_eq!(p.at(4.999), 10.0);
        assert_eq!(p.at(5.0), 10.0);
        assert_eq!(p.at(5.001), 20.0);
        assert_eq!(p.at(9.0), 4.0);
        assert_eq!(p.at(100.0), 4.0);
        assert_eq!(p.max_on(0.0, 4.0), 10.0);
        assert_eq!(p.max_on(4.0, 6.0), 20.0);
        assert_eq!(p.min_on(6.0, 10.0), 4.0);
        assert_eq!(p.min_on(0.0, 5.0), 10.0);
        assert_eq!(p.max(), 20.0);
        assert_eq!(p.scaled(0.5).at(6.0), 10.0);
        assert_eq!(p.capped(15.0).at(6.0), 15.0);
        let q = p.switched_at(6.0, &p.scaled(0.5));
        assert_eq!(q.breaks(), &[5.0, 6.0, 9.0]);
        assert_eq!((q.at(5.5), q.at(7.0), q.at(10.0)), (20.0, 10.0, 2.0));
        assert_eq!(p.switched_at(0.0, &p.scaled(2.0)), p.scaled(2.0));
    }

    #[test]
    fn bad_profiles_are_refused_with_what_is_wrong() {
        assert_eq!(FeedProfile::new(&[]), Err(FeedProfileError::Start));
        assert_eq!(FeedProfile::new(&[(1.0, 5.0)]), Err(FeedProfileError::Start));
        assert_eq!(
            FeedProfile::new(&[(0.0, 5.0), (0.0, 6.0)]),
            Err(FeedProfileError::Order { index: 1, s_mm: 0.0 })
        );
        assert_eq!(
            FeedProfile::new(&[(0.0, 5.0), (1.0, 0.0)]),
            Err(FeedProfileError::Feed {
                index: 1,
                feed_mm_s: 0.0
            })
        );
    }
}
