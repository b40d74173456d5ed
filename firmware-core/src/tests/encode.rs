//! Encode refuses invalid parts and short buffers; error messages.

use std::vec;

use super::fixtures::*;

#[test]
fn encode_refuses_invalid_parts() {
    let check = |f: &dyn Fn(&mut Owned), want: TableError| {
        let mut o = good();
        f(&mut o);
        assert_eq!(o.encode().unwrap_err(), EncodeError::Invalid(want));
    };
    use Section as S;
    use TableError as E;
    check(&|o| o.limits.abar = 0.0, E::Limit { index: 1 });
    check(&|o| o.limits.j[2] = -1.0, E::Limit { index: 11 });
    check(
        &|o| o.limits.v[0] = f64::INFINITY,
        E::NotFinite {
            section: S::Limits,
            index: 3,
        },
    );
    check(&|o| o.length = 0.0, E::PathLength);
    check(
        &|o| o.length = f64::NAN,
        E::NotFinite {
            section: S::Meta,
            index: 0,
        },
    );
    check(&|o| o.time = -1.0, E::PredictedTime);
    check(&|o| o.degree = 0, E::Degree { degree: 0 });
    check(&|o| o.degree = 6, E::Degree { degree: 6 });
    check(
        &|o| o.degree = 3,
        E::Count {
            section: S::NurbsKnots,
            expected: 8,
            found: 7,
        },
    );
    check(
        &|o| o.knots[3] = 1.5,
        E::KnotDecreasing {
            section: S::NurbsKnots,
            index: 4,
        },
    );
    check(
        &|o| o.knots[2] = 0.1,
        E::NotClamped {
            section: S::NurbsKnots,
            index: 2,
        },
    );
    check(
        &|o| o.knots[3] = f64::NAN,
        E::NotFinite {
            section: S::NurbsKnots,
            index: 3,
        },
    );
    check(
        &|o| {
            o.knots = vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0];
            o.points.extend([[L, 0.0, 0.0, 1.0], [L, 0.0, 0.0, 1.0]]);
        },
        E::KnotMultiplicity {
            section: S::NurbsKnots,
            index: 5,
        },
    );
    check(&|o| o.points[1][3] = -0.5, E::Weight { index: 1 });
    check(&|o| o.points[2][3] = 0.0, E::Weight { index: 2 });
    check(
        &|o| o.points[2][1] = f64::NAN,
        E::NotFinite {
            section: S::NurbsPoints,
            index: 9,
        },
    );
    check(
        &|o| o.points.truncate(2),
        E::Count {
            section: S::NurbsPoints,
            expected: 3,
            found: 2,
        },
    );
    // q
    check(
        &|o| o.q_ctrl[3] = f64::NAN,
        E::NotFinite {
            section: S::QCtrl,
            index: 3,
        },
    );
    check(
        &|o| {
            o.q_ctrl.pop();
        },
        E::Count {
            section: S::QKnots,
            expected: 15,
            found: 16,
        },
    );
    check(
        &|o| o.q_ctrl.truncate(3),
        E::Count {
            section: S::QCtrl,
            expected: 4,
            found: 3,
        },
    );
    check(
        &|o| o.q_knots.swap(5, 6),
        E::KnotDecreasing {
            section: S::QKnots,
            index: 6,
        },
    );
    check(
        &|o| o.q_knots[0] = -1.0,
        E::NotClamped {
            section: S::QKnots,
            index: 1,
        },
    );
    check(
        &|o| o.q_knots[4..8].copy_from_slice(&[20.0; 4]),
        E::KnotMultiplicity {
            section: S::QKnots,
            index: 7,
        },
    );
    check(
        &|o| o.q_knots.iter_mut().for_each(|k| *k *= 0.5),
        E::KnotRange { section: S::QKnots },
    );
    check(&|o| o.q_ctrl[4] = -1.0, E::QNegative { index: 4 });
    check(
        &|o| o.q_ctrl[4] = 2.01 * o.limits.vbar * o.limits.vbar,
        E::QAboveVbar { index: 4 },
    );
    check(&|o| o.limits.vbar = 30.0, E::QAboveVbar { index: 1 });
    check(&|o| o.q_ctrl[0] = 1.0, E::QEndNotZero { index: 0 });
    check(&|o| o.q_ctrl[11] = 1e-300, E::QEndNotZero { index: 11 });
    check(&|o| o.q_ctrl[1] = 0.0, E::QFlatEnd { index: 1 });
    check(&|o| o.q_ctrl[10] = 0.0, E::QFlatEnd { index: 10 });
    // s → u map
    check(&|o| o.breaks[1] = 0.0, E::SuBreak { index: 1 });
    check(&|o| o.breaks[0] = 1e-9, E::SuBreak { index: 0 });
    check(&|o| o.breaks[2] = 99.0, E::SuBreak { index: 2 });
    check(
        &|o| o.breaks[1] = f64::NAN,
        E::NotFinite {
            section: S::SuBreaks,
            index: 1,
        },
    );
    check(
        &|o| o.breaks.push(200.0),
        E::Count {
            section: S::SuBreaks,
            expected: 3,
            found: 4,
        },
    );
    check(&|o| o.segs[0].span = 1, E::SuSpan { segment: 0, span: 1 });
    check(&|o| o.segs[1].span = 4, E::SuSpan { segment: 1, span: 4 });
    check(&|o| o.segs[0].span = 3, E::SuOutsideSpan { segment: 0 });
    check(
        &|o| {
            o.segs[1].coeffs[0] = 0.5 + 1e-6;
            o.segs[1].coeffs[1] = 0.5 - 1e-6;
        },
        E::SuDiscontinuous { segment: 1 },
    );
    check(
        &|o| {
            o.segs[0].coeffs[0] = 1e-6;
            o.segs[0].coeffs[1] = 0.5 - 1e-6;
        },
        E::SuEnds { segment: 0 },
    );
    check(&|o| o.segs[1].coeffs[1] = 0.4, E::SuEnds { segment: 1 });
    check(&|o| o.segs[1].coeffs[1] = 0.6, E::SuOutsideSpan { segment: 1 });
    check(
        &|o| o.segs[1].coeffs[5] = f64::INFINITY,
        E::NotFinite {
            section: S::SuCoeffs,
            index: 11,
        },
    );
    check(
        &|o| {
            o.segs.clear();
            o.breaks.truncate(1);
        },
        E::Count {
            section: S::SuSpans,
            expected: 1,
            found: 0,
        },
    );
    // a last break or q knot within the tolerance of L is fine
    let mut o = good();
    o.breaks[2] = L * (1.0 - 1e-12);
    let n = o.q_knots.len();
    o.q_knots[n - 4..].copy_from_slice(&[L * (1.0 + 1e-12); 4]);
    o.encode().unwrap();
}

#[test]
fn encode_buffer_too_small() {
    let o = good();
    let parts = o.parts();
    let n = encoded_len(&parts);
    let mut out = vec![0u8; n - 1];
    assert_eq!(
        encode(&parts, &mut out),
        Err(EncodeError::BufferTooSmall {
            needed: n,
            available: n - 1
        })
    );
    let mut out = vec![0u8; n + 10];
    assert_eq!(encode(&parts, &mut out), Ok(n));
    assert!(Table::parse(&out[..n]).is_ok());
}

#[test]
fn errors_display() {
    use std::string::ToString;
    let s = TableError::NotFinite {
        section: Section::QCtrl,
        index: 3,
    }
    .to_string();
    assert!(s.contains("QCtrl") && s.contains('3'), "{s}");
    let s = EncodeError::Invalid(TableError::BadMagic).to_string();
    assert!(s.contains("magic"), "{s}");
}
