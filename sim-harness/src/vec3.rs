//! Three-vectors for the harness's measurements (positions and
//! derivatives in mm): the metrics' projection, the programmed contour's
//! distances and the joins between a program's paths. The checker
//! ([`crate::check`]) keeps its own, as a reference independent of the rest.

/// a − b.
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// a · b.
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// |a|.
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// |a − b|, mm.
pub(crate) fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(sub(a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_3_4_12_triangle_and_a_right_angle() {
        let (a, b) = ([1.0, -2.0, 5.0], [4.0, 2.0, 17.0]);
        assert_eq!(sub(b, a), [3.0, 4.0, 12.0]);
        assert_eq!(dist(a, b), 13.0);
        assert_eq!(dist(b, a), 13.0);
        assert_eq!(norm([0.0, -5.0, 0.0]), 5.0);
        assert_eq!(dot([1.0, 2.0, 0.0], [-2.0, 1.0, 7.0]), 0.0);
    }
}
