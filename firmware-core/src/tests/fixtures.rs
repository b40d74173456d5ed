//! Shared fixtures: a straight-line plan as owned parts, its variants (end
//! segments, override levels), byte offsets into a table, reference
//! integrals of the machining time.

pub(super) use crate::interp::interpolator::Interpolator;
pub(super) use crate::interp::setpoint::{Fault, RunError, Setpoint};
pub(super) use crate::limits::{EndSegments, Limits};
pub(super) use crate::math::source::{F64Array, Point4Array};
pub(super) use crate::output::FnSink;
pub(super) use crate::path::qspline::QSpline;
pub(super) use crate::path::su_map::{SegmentArray, SuSegment};
pub(super) use crate::table::encode::{encode, encoded_len};
pub(super) use crate::table::error::{EncodeError, TableError};
pub(super) use crate::table::layout::{CRC_LEN, DIR_ENTRY_LEN, HEADER_LEN};
pub(super) use crate::table::parts::TableParts;
pub(super) use crate::table::section::Section;
pub(super) use crate::table::view::Table;
use std::vec;
use std::vec::Vec;

pub(super) const L: f64 = 100.0;
pub(super) const LIMITS: Limits = Limits {
    vbar: 166.0,
    abar: 1500.0,
    jbar: 16000.0,
    v: [166.0; 3],
    a: [1500.0; 3],
    j: [16000.0; 3],
};

/// An owned set of parts for a straight line (0,0,0) → (L,0,0), u = s/L.
#[derive(Clone)]
pub(super) struct Owned {
    pub(super) limits: Limits,
    pub(super) length: f64,
    pub(super) time: f64,
    pub(super) degree: u32,
    pub(super) knots: Vec<f64>,
    pub(super) points: Vec<[f64; 4]>,
    pub(super) breaks: Vec<f64>,
    pub(super) segs: Vec<SuSegment>,
    pub(super) q_knots: Vec<f64>,
    pub(super) q_ctrl: Vec<f64>,
    pub(super) ends: Option<EndSegments>,
}

impl Owned {
    pub(super) fn parts(&self) -> TableParts<'_> {
        TableParts {
            limits: self.limits,
            path_length_mm: self.length,
            predicted_time_s: self.time,
            nurbs_degree: self.degree,
            nurbs_knots: &self.knots,
            nurbs_points: &self.points,
            su_breaks: &self.breaks,
            su_segments: &self.segs,
            q_knots: &self.q_knots,
            q_ctrl: &self.q_ctrl,
            ends: self.ends,
            levels: &[],
            pieces: None,
        }
    }
    pub(super) fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let parts = self.parts();
        let mut out = vec![0u8; encoded_len(&parts)];
        let n = encode(&parts, &mut out)?;
        assert_eq!(n, out.len());
        Ok(out)
    }
}

/// Uniform clamped cubic knots on [0, len] for `n` control points.
pub(super) fn q_knots(n: usize, len: f64) -> Vec<f64> {
    let inner = n - 3;
    let mut k = vec![0.0; 4];
    k.extend((1..inner).map(|i| len * i as f64 / inner as f64));
    k.extend([len; 4]);
    k
}

/// q control points [0, f², …, f², 0].
pub(super) fn plateau(n: usize, feed: f64) -> Vec<f64> {
    let mut c = vec![feed * feed; n];
    c[0] = 0.0;
    c[n - 1] = 0.0;
    c
}

pub(super) fn line(degree: u32, q_ctrl: Vec<f64>) -> Owned {
    let (knots, points, breaks, segs) = match degree {
        1 => (
            vec![0.0, 0.0, 1.0, 1.0],
            vec![[0.0, 0.0, 0.0, 1.0], [L, 0.0, 0.0, 1.0]],
            // four segments in the one span, u = s/L
            vec![0.0, 0.25 * L, 0.5 * L, 0.75 * L, L],
            (0..4)
                .map(|j| SuSegment {
                    span: 1,
                    coeffs: [j as f64 / 4.0, 0.25, 0.0, 0.0, 0.0, 0.0],
                })
                .collect(),
        ),
        _ => (
            // quadratic, points at the Greville abscissae: r(u) = L·u exactly
            vec![0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0],
            vec![
                [0.0, 0.0, 0.0, 1.0],
                [0.25 * L, 0.0, 0.0, 1.0],
                [0.75 * L, 0.0, 0.0, 1.0],
                [L, 0.0, 0.0, 1.0],
            ],
            vec![0.0, 0.5 * L, L],
            vec![
                SuSegment {
                    span: 2,
                    coeffs: [0.0, 0.5, 0.0, 0.0, 0.0, 0.0],
                },
                SuSegment {
                    span: 3,
                    coeffs: [0.5, 0.5, 0.0, 0.0, 0.0, 0.0],
                },
            ],
        ),
    };
    let n = q_ctrl.len();
    Owned {
        limits: LIMITS,
        length: L,
        time: 2.5,
        degree,
        knots,
        points,
        breaks,
        segs,
        q_knots: q_knots(n, L),
        q_ctrl,
        ends: None,
    }
}

pub(super) fn good() -> Owned {
    line(2, plateau(12, 50.0))
}

pub(super) fn fix_crc(b: &mut [u8]) {
    let n = b.len() - CRC_LEN;
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
}

pub(super) fn entry(idx: usize) -> usize {
    HEADER_LEN + idx * DIR_ENTRY_LEN
}

/// A table with one extra section of kind `kind` spliced in before the CRC.
pub(super) fn with_extra_section(bytes: &[u8], kind: u16, payload: &[u8]) -> Vec<u8> {
    let count = u16::from_le_bytes([bytes[12], bytes[13]]) as usize;
    let dir_end = entry(count);
    let body_end = bytes.len() - CRC_LEN;
    let mut out = Vec::new();
    out.extend_from_slice(&bytes[..dir_end]);
    out.extend_from_slice(&[0u8; DIR_ENTRY_LEN]); // new entry
    out.extend_from_slice(&bytes[dir_end..body_end]);
    while out.len() % 8 != 0 {
        out.push(0);
    }
    let ext_off = out.len();
    out.extend_from_slice(payload);
    out.extend_from_slice(&[0u8; CRC_LEN]);
    // shift the old sections by one entry
    for i in 0..count {
        let o = u32::from_le_bytes(out[entry(i) + 8..entry(i) + 12].try_into().unwrap());
        out[entry(i) + 8..entry(i) + 12].copy_from_slice(&(o + DIR_ENTRY_LEN as u32).to_le_bytes());
    }
    let e = entry(count);
    out[e..e + 2].copy_from_slice(&kind.to_le_bytes());
    out[e + 4..e + 8].copy_from_slice(&((payload.len() / 8) as u32).to_le_bytes());
    out[e + 8..e + 12].copy_from_slice(&(ext_off as u32).to_le_bytes());
    out[e + 12..e + 16].copy_from_slice(&(payload.len() as u32).to_le_bytes());
    out[12..14].copy_from_slice(&((count + 1) as u16).to_le_bytes());
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    fix_crc(&mut out);
    out
}

/// ∫₀ᴸ ds/√q by Gauss–Legendre after s = σ² (and L − s = σ²) at the ends,
/// which removes the 1/√ singularities of a simple zero.
pub(super) fn time_by_quadrature(knots: &[f64], ctrl: &[f64]) -> f64 {
    let q = QSpline::new(knots, ctrl).unwrap();
    let len = *knots.last().unwrap();
    let half = 0.5 * len;
    let (x, w) = (
        [
            -0.906_179_845_938_664,
            -0.538_469_310_105_683,
            0.0,
            0.538_469_310_105_683,
            0.906_179_845_938_664,
        ],
        [
            0.236_926_885_056_189,
            0.478_628_670_499_366,
            0.568_888_888_888_889,
            0.478_628_670_499_366,
            0.236_926_885_056_189,
        ],
    );
    let smax = half.sqrt();
    let panels = 4000;
    let h = smax / panels as f64;
    let mut total = 0.0;
    for side in [0, 1] {
        for k in 0..panels {
            let a = k as f64 * h;
            for (xi, wi) in x.iter().zip(w.iter()) {
                let sig = a + 0.5 * h * (1.0 + xi);
                let s = if side == 0 { sig * sig } else { len - sig * sig };
                let qv = q.eval(s).unwrap()[0].max(1e-300);
                total += 0.5 * h * wi * 2.0 * sig / qv.sqrt();
            }
        }
    }
    total
}

pub(super) fn run_all<const Q: usize, const W: usize>(ip: &mut Interpolator<'_, Q, W>) -> Vec<Setpoint> {
    let mut v = Vec::new();
    let n = ip
        .run(&mut FnSink(|sp: &Setpoint| -> Result<(), ()> {
            v.push(*sp);
            Ok(())
        }))
        .unwrap();
    assert_eq!(n as usize, v.len());
    v
}

/// Byte offset of the section of `kind` (from the directory).
pub(super) fn section_offset(bytes: &[u8], kind: u16) -> usize {
    let count = u16::from_le_bytes([bytes[12], bytes[13]]) as usize;
    (0..count)
        .map(entry)
        .find(|&e| u16::from_le_bytes([bytes[e], bytes[e + 1]]) == kind)
        .map(|e| u32::from_le_bytes(bytes[e + 8..e + 12].try_into().unwrap()) as usize)
        .unwrap()
}

/// `o` with q adjusted to join jerk-limited start and stop segments C² at
/// its first and last interior knots (control points 1, 2 and N−2, N−3 solve
/// the two join equations), and the segments in the table.
pub(super) fn with_ends(mut o: Owned) -> Owned {
    let n = o.q_ctrl.len();
    let (s1, s2) = (o.q_knots[4], o.q_knots[n - 1]);
    // d signed: q′ = 4q/(3d), q″ = 4q/(9d²) (d < 0 at the stop)
    for (s, d, idx) in [(s1, s1, [1, 2]), (s2, s2 - L, [n - 2, n - 3])] {
        let res = |c: &[f64]| {
            let e = QSpline::new(&o.q_knots[..], c).unwrap().eval(s).unwrap();
            [e[1] - 4.0 * e[0] / (3.0 * d), e[2] - 4.0 * e[0] / (9.0 * d * d)]
        };
        let r0 = res(&o.q_ctrl);
        let col = |i: usize| {
            let mut c = o.q_ctrl.clone();
            c[i] += 1.0;
            let r = res(&c);
            [r[0] - r0[0], r[1] - r0[1]]
        };
        let (a, b) = (col(idx[0]), col(idx[1]));
        let det = a[0] * b[1] - a[1] * b[0];
        o.q_ctrl[idx[0]] -= (r0[0] * b[1] - r0[1] * b[0]) / det;
        o.q_ctrl[idx[1]] -= (a[0] * r0[1] - a[1] * r0[0]) / det;
    }
    assert!(o.q_ctrl.iter().all(|&c| c >= 0.0), "{:?}", o.q_ctrl);
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let (q1, q2) = (q.eval(s1).unwrap()[0], q.eval(s2).unwrap()[0]);
    o.ends = Some(EndSegments::from_q(s1, q1, s2, q2, L));
    o
}

/// ∫ ds/√q on [a, b] where q > 0 (Simpson, fine).
pub(super) fn time_between(o: &Owned, a: f64, b: f64) -> f64 {
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let n = 20000;
    let h = (b - a) / n as f64;
    let f = |s: f64| 1.0 / q.eval(s).unwrap()[0].sqrt();
    let mut sum = f(a) + f(b);
    for k in 1..n {
        sum += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

/// An override level as the tests write it: α, control points, end segments.
pub(super) type OwnedLevel = (f64, Vec<f64>, Option<EndSegments>);

/// Level α of `o`: q scaled by α² (a valid plan for the feed limit α·v̄; the
/// end-segment joins are linear in q, so the same s₁, s₂ join it C²).
pub(super) fn scaled_level(o: &Owned, alpha: f64) -> OwnedLevel {
    let ctrl: Vec<f64> = o.q_ctrl.iter().map(|c| alpha * alpha * c).collect();
    let ends = o.ends.map(|e| {
        let q = QSpline::new(&o.q_knots[..], &ctrl[..]).unwrap();
        let (q1, q2) = (q.eval(e.s_start).unwrap()[0], q.eval(e.s_stop).unwrap()[0]);
        EndSegments::from_q(e.s_start, q1, e.s_stop, q2, o.length)
    });
    (alpha, ctrl, ends)
}

pub(super) fn encode_levels(o: &Owned, levels: &[OwnedLevel]) -> Result<Vec<u8>, EncodeError> {
    use crate::table::parts::LevelParts;
    let lp: Vec<LevelParts> = levels
        .iter()
        .map(|(alpha, ctrl, ends)| LevelParts {
            alpha: *alpha,
            ctrl,
            ends: *ends,
        })
        .collect();
    let parts = TableParts {
        levels: &lp,
        pieces: None,
        ..o.parts()
    };
    let mut out = vec![0u8; encoded_len(&parts)];
    let n = encode(&parts, &mut out)?;
    assert_eq!(n, out.len());
    Ok(out)
}
