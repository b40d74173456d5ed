//! The override of an active profile at one point (§4.1–§4.3, Algorithms 1
//! and 2): indices, skip conditions, where the transition ends, retries.

use std::time::Instant;

use crate::feed_override::config::REACH_TOL_Q;
use crate::feed_override::context::OverrideContext;
use crate::feed_override::outcome::{Case, OverrideError, OverrideOutcome, OverrideProfile, SkipReason};
use crate::feed_override::transition;
use crate::lp::basis_rows::{BasisRow, ORDER};
use crate::lp::problem::LpError;

impl OverrideContext {
    /// The override of `active_ctrl` (the profile active at level
    /// `active_level`, possibly an earlier override) at arc length `s_mm`
    /// to level `target_level` (see the module docs).
    pub fn compute(
        &self,
        active_level: u16,
        active_ctrl: &[f64],
        s_mm: f64,
        target_level: u16,
    ) -> Result<OverrideOutcome, OverrideError> {
        let t0 = Instant::now();
        let n = self.knots.len() - ORDER;
        let count = self.profiles.len();
        let level = |id: u16| {
            self.profiles
                .get(usize::from(id))
                .ok_or(OverrideError::UnknownLevel { level: id, count })
        };
        let (act, tgt) = (level(active_level)?, level(target_level)?);
        if !(s_mm >= 0.0 && s_mm <= self.length) {
            return Err(OverrideError::SOutOfRange {
                s_mm,
                length_mm: self.length,
            });
        }
        if active_ctrl.len() != n {
            return Err(OverrideError::ActiveLength {
                got: active_ctrl.len(),
                want: n,
            });
        }
        if let Some((index, &value)) = active_ctrl.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(OverrideError::BadActive { index, value });
        }
        if active_level == target_level {
            return Ok(OverrideOutcome::Skip(SkipReason::SameLevel));
        }
        let accel = tgt.vbar > act.vbar;
        let f_cur = act.vbar;
        // the active profile at the Greville points (it may be an override)
        let q_a: Vec<f64> = self.grev_basis.iter().map(|b| b.apply(0, active_ctrl)).collect();
        let a_a: Vec<f64> = self
            .grev_basis
            .iter()
            .map(|b| 0.5 * b.apply(1, active_ctrl))
            .collect();
        let f = |q: f64| q.max(0.0).sqrt();
        let big_k = n - 1;
        let (abar, jbar) = (self.limits.abar, self.limits.jbar);
        let arclen = |fs: f64, fe: f64, a_s: f64| {
            transition::arc_len(fs, fe, a_s.clamp(-abar, abar), abar, jbar)
                .map(|t| t.length_mm * self.config.arclen_scale)
                .unwrap_or(f64::INFINITY)
        };
        // (the active profile's feed near the override point: from its span
        // over three windows' worth, where Algorithm 2 may still move it)
        let near = {
            let first = BasisRow::at(&self.knots, s_mm).map_or(0, |b| b.first);
            let lo = first.saturating_sub(ORDER - 1).min(active_ctrl.len());
            let hi = (first + 1)
                .saturating_add(3 * self.config.max_window_ctrl)
                .min(active_ctrl.len());
            &active_ctrl[lo..hi.max(lo)]
        };
        let Some(win_limits) = self.window_limits(active_level, near, target_level) else {
            return Err(OverrideError::UnknownLevel {
                level: target_level,
                count,
            });
        };
        let caps = if act.vbar > tgt.vbar { &act.caps } else { &tgt.caps };
        let (mut retries_grow, mut retries_extreme, mut lp_count) = (0u32, 0u32, 0u32);
        let mut s_o = s_mm;
        let mut last_err: Option<LpError> = None;
        // every override point tried ended with the window at the buffer's size
        let mut always_capped = true;
        loop {
            // (19): the span of the override point, I_l
            let Some(span) = BasisRow::at(&self.knots, s_o) else {
                return Err(OverrideError::SOutOfRange {
                    s_mm: s_o,
                    length_mm: self.length,
                });
            };
            let mut i_l = span.first + ORDER - 1;
            if let Some(sj) = act.start_join_last {
                // inside the start segment the join's control points stay
                i_l = i_l.max(sj);
            }
            if i_l + 2 >= n {
                return Ok(OverrideOutcome::Skip(SkipReason::EndOfPath));
            }
            // (20): J_s
            let s_il = self.knots[i_l + ORDER - 1];
            let j_s = self.greville.partition_point(|&g| g < s_il);
            if j_s >= big_k {
                return Ok(OverrideOutcome::Skip(SkipReason::EndOfPath));
            }
            // (21): the final deceleration
            if q_a[j_s..].windows(2).all(|w| w[0] > w[1]) {
                return Ok(OverrideOutcome::Skip(SkipReason::FinalDeceleration));
            }
            if accel {
                let top = q_a[j_s..].iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                if top < f_cur * f_cur * (1.0 - REACH_TOL_Q) {
                    return Ok(OverrideOutcome::Skip(SkipReason::NeverReachesFeed));
                }
            }
            let (fa_js, aa_js) = (f(q_a[j_s]), a_a[j_s]);
            // Case I / Case II / acceleration: I_t
            let (case, i_t, estimate) = if !accel && fa_js <= f(tgt.q_g[j_s]) {
                (Case::DecelI, i_l + ORDER, None)
            } else {
                // J_l: the first k where the active profile no longer differs
                // in the direction of the change
                let done = |k: usize| {
                    if accel {
                        q_a[k] >= tgt.q_g[k] * (1.0 - 1e-3)
                    } else {
                        q_a[k] <= tgt.q_g[k]
                    }
                };
                let j_l = (j_s + 1..=big_k).find(|&k| done(k)).unwrap_or(big_k);
                // Algorithm 1
                let mut j_k = j_l;
                let mut est = None;
                for k in j_s + 1..=j_l {
                    let ft = f(tgt.q_g[k]);
                    let len = if fa_js > ft {
                        arclen(fa_js, ft, aa_js)
                    } else {
                        arclen(ft, fa_js, tgt.a_g[k])
                    };
                    if len < self.greville[k] - self.greville[j_s] {
                        j_k = k;
                        est = Some(len);
                        break;
                    }
                }
                let j_e = j_l.min(j_k);
                if j_e >= big_k {
                    return Ok(OverrideOutcome::Skip(SkipReason::TooLittlePath));
                }
                let g_e = self.greville[j_e];
                let Some(i_t) = self.knots.iter().position(|&u| u >= g_e) else {
                    return Ok(OverrideOutcome::Skip(SkipReason::TooLittlePath));
                };
                let case = if accel { Case::Accel } else { Case::DecelII };
                (case, i_t.max(i_l + ORDER), est)
            };
            if i_t >= big_k - 1 {
                return Ok(OverrideOutcome::Skip(SkipReason::TooLittlePath));
            }
            // the window's free control points must stay before the target's stop join
            let last_free_max = match tgt.stop_join_first {
                Some(sj) => sj.saturating_sub(1),
                None => n.saturating_sub(ORDER),
            };
            if i_t - 1 > last_free_max {
                return Ok(OverrideOutcome::Skip(if tgt.stop_join_first.is_some() {
                    SkipReason::InStopJoin
                } else {
                    SkipReason::TooLittlePath
                }));
            }
            // The largest I_m: the free control points stay before the target's
            // stop join, and the profile (I_m − first control points, the 3
            // context ones included) fits the firmware's window buffer.
            let first = i_l - 2;
            let i_m_join = last_free_max + 1;
            let i_m_buf = first + self.config.max_window_ctrl;
            let i_m_max = i_m_join.min(i_m_buf);
            let mut i_m = i_t.min(i_m_max);
            let mut grown = 0;
            // the buffer cannot hold even the shortest window here
            let mut at_cap = i_m < i_l + ORDER;
            while !at_cap {
                match self.window(active_ctrl, tgt, i_l, i_m, &win_limits, caps) {
                    Ok((full, lps)) => {
                        lp_count += lps;
                        let profile = OverrideProfile {
                            level: target_level,
                            first: first as u32,
                            ctrl: full[first..i_m].to_vec(),
                            splice_s_mm: self.knots[first + ORDER - 1],
                            merge_s_mm: self.knots[i_m + ORDER - 1],
                            case,
                            retries_grow,
                            retries_extreme,
                            arclen_estimate_mm: estimate,
                            transition_len_mm: self.transition_len(&full, &tgt.ctrl, first, i_m),
                            full_ctrl: full,
                            lp_count,
                            compute_time_s: t0.elapsed().as_secs_f64(),
                            override_s_mm: s_o,
                        };
                        return Ok(OverrideOutcome::Profile(profile));
                    }
                    Err((e, lps)) => {
                        lp_count += lps;
                        last_err = Some(e);
                    }
                }
                if i_m >= i_m_max {
                    at_cap = i_m >= i_m_buf;
                    break;
                }
                if grown >= self.config.max_grow {
                    break;
                }
                let step = self.config.grow_min.max((i_m - i_l) / 2);
                grown += 1;
                retries_grow += 1;
                i_m = (i_m + step).min(i_m_max);
            }
            if !at_cap {
                always_capped = false;
            }
            // Algorithm 2: the nearest local extreme of the active feed after J_s
            if retries_extreme as usize >= self.config.max_extreme {
                break;
            }
            let j_ext = if a_a[j_s] < 0.0 {
                (j_s + 1..=big_k).find(|&k| a_a[k] >= 0.0)
            } else {
                (j_s + 1..=big_k).find(|&k| a_a[k] <= 0.0)
            };
            let Some(j_ext) = j_ext else { break };
            retries_extreme += 1;
            s_o = self.greville[j_ext];
        }
        match last_err {
            Some(source) if !always_capped => Err(OverrideError::LpFailed {
                retries_grow,
                retries_extreme,
                source,
            }),
            _ => Ok(OverrideOutcome::Skip(SkipReason::WindowTooLong)),
        }
    }
}
