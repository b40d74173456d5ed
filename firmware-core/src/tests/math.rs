//! The 64-bit division by a small divisor the firmware uses instead of the
//! compiler's division routine: the same quotient and remainder as `/` and
//! `%`, at the edges and on a pseudo-random sweep.

use crate::math::div_rem_small;
use std::vec;

#[test]
fn div_rem_small_matches_the_operators() {
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut values = vec![
        0,
        1,
        5,
        6,
        9,
        10,
        11,
        0xffff,
        0x1_0000,
        u64::from(u32::MAX),
        1 << 32,
        u64::MAX - 1,
        u64::MAX,
    ];
    for _ in 0..20_000 {
        // xorshift64*, and its value cut to every width
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        let r = x.wrapping_mul(0x2545_f491_4f6c_dd1d);
        values.push(r >> (r % 64));
    }
    for d in [1u16, 2, 3, 6, 7, 10, 255, 1000, 0x8000, 0xffff] {
        for &n in &values {
            let got = div_rem_small(n, d);
            assert_eq!(
                got,
                Some((n / u64::from(d), (n % u64::from(d)) as u16)),
                "{n} / {d}"
            );
        }
    }
    assert_eq!(div_rem_small(12, 0), None);
}
