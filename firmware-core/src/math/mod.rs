//! Numbers underneath everything: B-spline basis functions ([`basis`]),
//! the read-only number sources the evaluators read through ([`source`])
//! and the quadrature rule of the arc length integrals ([`quadrature`]);
//! a 64-bit division by a small divisor without the division routine
//! ([`div_rem_small`]).

pub mod basis;
pub mod quadrature;
pub mod source;

/// n / d and n % d for a small divisor, by long division in 16-bit digits
/// through the M4's 32-bit hardware divide: the compiler would call the
/// 64-bit division routine (~1 KB of flash, and the only users of it are
/// the chunk decoder's ÷ m! and the firmware's decimal printing). `None`
/// for d = 0.
pub fn div_rem_small(n: u64, d: u16) -> Option<(u64, u16)> {
    let d = u32::from(d);
    let (mut q, mut r) = (0u64, 0u32);
    for k in (0..4).rev() {
        // r < d ≤ 2¹⁶ − 1: cur < 2³²
        let cur = (r << 16) | ((n >> (16 * k)) as u32 & 0xffff);
        let qd = cur.checked_div(d)?;
        r = cur - qd * d;
        q |= u64::from(qd) << (16 * k);
    }
    Some((q, r as u16))
}
