//! Shared fixtures of the stream tests: a table's rows as owned vectors,
//! and a cutter that writes them as chunks of about `mm` each (the host's
//! is `planner_host::stream::chunk_table`; this one keeps firmware-core's
//! tests free of the planner).

pub(super) use super::fixtures::{good, line, plateau};
pub(super) use crate::stream::layout::{field, HEADER_LEN as CHUNK_HEADER_LEN};
pub(super) use crate::stream::{
    encode_chunk, Chunk, ChunkEncodeError, ChunkError, ChunkHead, ChunkRing, Malformed, PieceForm, QSpanForm,
    StreamError, Stretch,
};
pub(super) use crate::table::{crc32, Table};
use std::vec;
use std::vec::Vec;

use crate::math::source::F64Array;

/// A table's rows, owned.
pub(super) struct Rows {
    pub(super) knots: Vec<f64>,
    pub(super) ctrl: Vec<f64>,
    pub(super) breaks: Vec<f64>,
    pub(super) words: Vec<[i64; 27]>,
    pub(super) u: Vec<[f32; 7]>,
    pub(super) q_local: Vec<[f32; 5]>,
    pub(super) q_fixed: Vec<[i64; 5]>,
}

pub(super) fn rows(t: &Table) -> Rows {
    let w = t.piece_f64();
    let f = t.piece_f32();
    let breaks: Vec<f64> = t.piece_breaks().iter().collect();
    let np = breaks.len() - 1;
    let nq = t.q_ctrl().len() - 3;
    Rows {
        knots: t.q_knots().iter().collect(),
        ctrl: t.q_ctrl().iter().collect(),
        words: (0..np)
            .map(|j| core::array::from_fn(|k| w.get_i64(27 * j + k).unwrap()))
            .collect(),
        u: (0..np)
            .map(|j| core::array::from_fn(|k| f.get(7 * j + k).unwrap()))
            .collect(),
        q_local: (0..nq)
            .map(|i| core::array::from_fn(|k| t.q_local().get(5 * i + k).unwrap()))
            .collect(),
        q_fixed: (0..nq)
            .map(|i| core::array::from_fn(|k| t.q_fixed().get_i64(5 * i + k).unwrap()))
            .collect(),
        breaks,
    }
}

/// Chunk boundaries (piece indices) of about `mm` each.
pub(super) fn cuts(breaks: &[f64], mm: f64) -> Vec<(usize, usize)> {
    let p = breaks.len() - 1;
    let mut out = vec![];
    let mut j0 = 0;
    while j0 < p {
        let mut j1 = j0 + 1;
        while j1 < p && breaks[j1] < breaks[j0] + mm {
            j1 += 1;
        }
        out.push((j0, j1));
        j0 = j1;
    }
    out
}

/// The stretch of pieces `j0..j1` with the q spans that meet it.
pub(super) fn stretch(r: &Rows, (j0, j1): (usize, usize), u_form: bool) -> Stretch<'_> {
    let (sa, sb) = (r.breaks[j0], r.breaks[j1]);
    let n = r.ctrl.len();
    let i0 = (3..n).find(|&i| r.knots[i + 1] >= sa).unwrap();
    let i1 = (3..n).rev().find(|&i| r.knots[i] < sb).unwrap().max(i0);
    Stretch {
        first_span: i0 as u32,
        q_knots: &r.knots[i0 - 2..=i1 + 3],
        q_ctrl: &r.ctrl[i0 - 3..=i1],
        q_ends_spline: i1 == n - 1,
        breaks: &r.breaks[j0..=j1],
        words: &r.words[j0..j1],
        u_form: u_form.then(|| &r.u[j0..j1]),
    }
}

/// The table as chunks of about `mm`, seq from `seq0`.
pub(super) fn chunk_table(t: &Table, mm: f64, u_form: bool, plan_id: u32, seq0: u32) -> Vec<Vec<u8>> {
    let r = rows(t);
    let c = cuts(&r.breaks, mm);
    let n = c.len();
    c.iter()
        .enumerate()
        .map(|(k, &jj)| {
            let head = ChunkHead {
                seq: seq0.wrapping_add(k as u32),
                plan_id,
                commit: 0,
                first: k == 0,
                last: k + 1 == n,
                splice: false,
            };
            let mut out = vec![0u8; 1 << 20];
            let len = encode_chunk(&head, &stretch(&r, jj, u_form), &mut out).unwrap();
            out.truncate(len);
            out
        })
        .collect()
}

/// The fixture line's table.
pub(super) fn line_table() -> Vec<u8> {
    good().encode().unwrap()
}

/// A longer, denser line (more pieces and q spans).
pub(super) fn dense_table() -> Vec<u8> {
    line(2, plateau(40, 120.0)).encode().unwrap()
}

/// Recompute a chunk's CRC after editing it.
pub(super) fn reseal(b: &mut [u8]) {
    let n = b.len() - 4;
    let crc = crc32(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
}

/// A chunk of `payload` with a header that agrees with its length.
pub(super) fn hand_chunk(payload: &[u8], n_q: u16, n_p: u16) -> Vec<u8> {
    let mut b = vec![0u8; CHUNK_HEADER_LEN];
    b[..2].copy_from_slice(b"FC");
    b[field::VERSION] = crate::stream::layout::VERSION;
    b[field::S_B..field::S_B + 8].copy_from_slice(&(1i64 << 40).to_le_bytes());
    b[field::N_Q..field::N_Q + 2].copy_from_slice(&n_q.to_le_bytes());
    b[field::N_P..field::N_P + 2].copy_from_slice(&n_p.to_le_bytes());
    b[field::PAYLOAD_LEN..field::PAYLOAD_LEN + 4].copy_from_slice(&(payload.len() as u32).to_le_bytes());
    b.extend_from_slice(payload);
    b.extend_from_slice(&[0; 4]);
    reseal(&mut b);
    b
}

/// `chunk` as a splice (the flag set), with sequence number `seq`.
pub(super) fn as_splice(chunk: &[u8], seq: u32) -> Vec<u8> {
    let mut b = chunk.to_vec();
    b[field::FLAGS] |= crate::stream::layout::flags::SPLICE;
    b[field::SEQ..field::SEQ + 4].copy_from_slice(&seq.to_le_bytes());
    reseal(&mut b);
    b
}

/// `chunk` with sequence number `seq` (and its flags otherwise).
pub(super) fn with_seq(chunk: &[u8], seq: u32) -> Vec<u8> {
    let mut b = chunk.to_vec();
    b[field::SEQ..field::SEQ + 4].copy_from_slice(&seq.to_le_bytes());
    reseal(&mut b);
    b
}
