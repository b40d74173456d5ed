//! One scenario's row of the Markdown table: fates of the override
//! commands, latencies, host compute times, ratios to the limits.

/// `a / b` of a (median, max) pair scaled and rounded, `–` if none.
pub(crate) fn fmt_opt(x: Option<(f64, f64)>, scale: f64, digits: usize) -> String {
    match x {
        Some((a, b)) => format!("{:.*} / {:.*}", digits, a * scale, digits, b * scale),
        None => "–".into(),
    }
}

/// The Markdown header of the report table.
pub const TABLE_HEAD: &str = "| scenario | time s | active/superseded/skipped/failed/commands | refusals | latency ms (median / max) | host compute ms (median / max) | Case II / retries | transition / ArcLen (median / max) | feed err after merge mm/s | acc / jerk / tacc / tjerk (pad-rest) | max step / v·T | ends at r(1) |\n|---|---|---|---|---|---|---|---|---|---|---|---|";

/// Order statistics of a sample: (median, max); `None` if empty.
pub fn median_max(v: &[f64]) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let med = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Some((med, v[n - 1]))
}
