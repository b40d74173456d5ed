//! A planned table as a stream of chunks (`firmware_core::stream`, chunk
//! format version 2): [`chunk_table`] cuts a parsed [`Table`] into chunks
//! of about [`ChunkOptions::chunk_mm`] each, losslessly — decoding them
//! ([`decode_chunks`]) gives the table's own q spans (sections 10 and 15)
//! and pieces (sections 11, 12 and 13), word for word. [`StreamSize`]
//! measures the stream in bytes per mm of path, framing included.
//!
//! The chunks carry the table's pieces (fitted per knot span of the
//! path) and commit 0 (s_c = s_b): `crate::stream_hold::set_hold_points`
//! writes the hold points. [`ChunkCutter`] cuts the same chunks from rows
//! that grow as a plan is planned (`crate::stream_pipeline`).

use std::collections::BTreeMap;

use firmware_core::stream::frame::encoded_max_len;
use firmware_core::stream::{
    encode_chunk, Chunk, ChunkEncodeError, ChunkError, ChunkHead, PieceForm, QSpanForm, Stretch,
};
use firmware_core::{F64Array, Table};

/// Words of a piece in section 12.
const PIECE_WORDS: usize = 27;
/// f32 of a piece in section 13.
const PIECE_F32: usize = 7;
/// Values of a q span in sections 10 and 15.
const Q_VALUES: usize = 5;

/// How to cut a table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChunkOptions {
    /// Chunk length, mm: a chunk ends at the first piece break at least
    /// this far from its start (or at L).
    pub chunk_mm: f64,
    /// Send the f32 u form (the reported u) with the pieces. Off by
    /// default: the motors need the positions, and the u form adds six f32
    /// a piece (70 % more on the Butterfly's stream); with it the setpoints
    /// report u, the curve parameter, as a whole table's do.
    pub u_form: bool,
    /// Plan id in every header.
    pub plan_id: u32,
    /// Seq of the first chunk.
    pub first_seq: u32,
    /// Largest chunk, bytes (header, payload, CRC): a longer stretch is
    /// halved (by pieces) until it fits or is one piece. `None`: no bound.
    pub max_chunk_bytes: Option<usize>,
}

impl Default for ChunkOptions {
    fn default() -> Self {
        ChunkOptions {
            chunk_mm: 32.0,
            u_form: false,
            plan_id: 1,
            first_seq: 0,
            max_chunk_bytes: None,
        }
    }
}

/// Why a table could not be cut into chunks.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ChunkTableError {
    /// The table has no pieces or fewer than 4 q control points.
    #[error("the table has no pieces or no q spans")]
    Empty,
    /// The chunk length is not > 0.
    #[error("chunk length {0} mm is not > 0")]
    ChunkLength(f64),
    /// The encoder refused a stretch.
    #[error("chunk {index}: {error:?}")]
    Encode {
        /// Chunk index.
        index: usize,
        /// Why.
        error: ChunkEncodeError,
    },
    /// A chunk did not parse (when decoding).
    #[error("chunk {index}: {error}")]
    Parse {
        /// Chunk index.
        index: usize,
        /// Why.
        error: ChunkError,
    },
    /// Two chunks decoded one q span differently.
    #[error("q span {0} differs between two chunks")]
    SpanDisagrees(u32),
    /// A commit told the s → u map from a later segment than the chunks
    /// had reached: the segments between were never told.
    #[error("the s -> u map was told from segment {told}, the chunks have it up to segment {have}")]
    MapGap {
        /// Segments the chunks have.
        have: usize,
        /// The commit's first segment.
        told: usize,
    },
    /// A commit told a knot vector of q that is not the one before with
    /// knots added past the control points taken (a planner bug, never a
    /// chunk cut on the wrong knots).
    #[error("a commit moved the knots of q before control point {through}")]
    KnotsMoved {
        /// Control points taken.
        through: usize,
    },
}

/// A table's rows, owned: what the chunks carry and what they must decode to.
#[derive(Clone, Debug, PartialEq)]
pub struct TableRows {
    /// q knots (section 8).
    pub q_knots: Vec<f64>,
    /// q control points (section 9).
    pub q_ctrl: Vec<f64>,
    /// Section 10, per q span 3 ..= N − 1.
    pub q_local: Vec<[f32; Q_VALUES]>,
    /// Section 15, per q span.
    pub q_fixed: Vec<[i64; Q_VALUES]>,
    /// Section 11: P + 1 breaks.
    pub breaks: Vec<f64>,
    /// Section 12: 27 words per piece.
    pub words: Vec<[i64; PIECE_WORDS]>,
    /// Section 13: 7 f32 per piece.
    pub u: Vec<[f32; PIECE_F32]>,
}

impl TableRows {
    /// The rows of a parsed table.
    pub fn of(t: &Table) -> TableRows {
        let breaks: Vec<f64> = t.piece_breaks().iter().collect();
        let np = breaks.len().saturating_sub(1);
        let nq = t.q_ctrl().len().saturating_sub(3);
        let (w, f, ql, qf) = (t.piece_f64(), t.piece_f32(), t.q_local(), t.q_fixed());
        TableRows {
            q_knots: t.q_knots().iter().collect(),
            q_ctrl: t.q_ctrl().iter().collect(),
            q_local: (0..nq)
                .map(|i| std::array::from_fn(|k| ql.get(Q_VALUES * i + k).unwrap_or(0.0)))
                .collect(),
            q_fixed: (0..nq)
                .map(|i| std::array::from_fn(|k| qf.get_i64(Q_VALUES * i + k).unwrap_or(0)))
                .collect(),
            words: (0..np)
                .map(|j| std::array::from_fn(|k| w.get_i64(PIECE_WORDS * j + k).unwrap_or(0)))
                .collect(),
            u: (0..np)
                .map(|j| std::array::from_fn(|k| f.get(PIECE_F32 * j + k).unwrap_or(0.0)))
                .collect(),
            breaks,
        }
    }

    /// The stretch of pieces `j0 .. j1` with the q spans that meet
    /// [breaks[j0], breaks[j1]] (a span ending exactly at the start is
    /// repeated, so empty spans there are not lost).
    fn stretch(&self, j0: usize, j1: usize, u_form: bool) -> Option<Stretch<'_>> {
        let (sa, sb) = (*self.breaks.get(j0)?, *self.breaks.get(j1)?);
        let n = self.q_ctrl.len();
        // (the knots rise: the first span i ≥ 3 whose end U_{i+1} reaches
        // sa, and the last whose start U_i is below sb, by bisection, not a
        // scan of a long path's knots at every chunk)
        let knots = self.q_knots.get(..n + 1)?;
        let i0 = 3 + knots.get(4..)?.partition_point(|&u| u < sa);
        if i0 >= n {
            return None;
        }
        let i1 = (3 + knots.get(3..n)?.partition_point(|&u| u < sb)).checked_sub(1)?;
        if i1 < 3 {
            return None;
        }
        let i1 = i1.max(i0);
        Some(Stretch {
            first_span: u32::try_from(i0).ok()?,
            q_knots: self.q_knots.get(i0 - 2..=i1 + 3)?,
            q_ctrl: self.q_ctrl.get(i0 - 3..=i1)?,
            q_ends_spline: i1 + 1 == n,
            breaks: self.breaks.get(j0..=j1)?,
            words: self.words.get(j0..j1)?,
            u_form: if u_form { Some(self.u.get(j0..j1)?) } else { None },
        })
    }
}

/// Cut `table` into chunks (each a complete chunk, not yet framed).
pub fn chunk_table(table: &Table, opts: &ChunkOptions) -> Result<Vec<Vec<u8>>, ChunkTableError> {
    chunk_rows(&TableRows::of(table), opts)
}

/// Cut a table's rows into chunks.
pub fn chunk_rows(rows: &TableRows, opts: &ChunkOptions) -> Result<Vec<Vec<u8>>, ChunkTableError> {
    let mut cutter = ChunkCutter::new(opts)?;
    let p = rows.words.len();
    if p == 0 || rows.q_ctrl.len() < 4 {
        return Err(ChunkTableError::Empty);
    }
    cutter.cut(rows, true)
}

/// Cuts rows into chunks as they become final ([`chunk_rows`] at once):
/// each [`ChunkCutter::cut`] takes the rows known so far and returns the
/// chunks that no row still to come can change. A chunk ends at the first
/// piece break at least [`ChunkOptions::chunk_mm`] from its start, so it is
/// final once a break that far is known; fed the rows of a growing plan the
/// cutter writes the same chunks, byte for byte, as [`chunk_rows`] on the
/// finished rows.
#[derive(Clone, Debug)]
pub struct ChunkCutter {
    opts: ChunkOptions,
    /// The next chunk's first piece.
    j0: usize,
    /// Chunks written.
    index: usize,
    /// The last chunk was written.
    done: bool,
    buf: Vec<u8>,
}

impl ChunkCutter {
    /// A cutter at the start of a plan.
    pub fn new(opts: &ChunkOptions) -> Result<Self, ChunkTableError> {
        if opts.chunk_mm.is_nan() || opts.chunk_mm <= 0.0 {
            return Err(ChunkTableError::ChunkLength(opts.chunk_mm));
        }
        Ok(ChunkCutter {
            opts: *opts,
            j0: 0,
            index: 0,
            done: false,
            buf: Vec::new(),
        })
    }

    /// Chunks written so far.
    pub fn chunks(&self) -> usize {
        self.index
    }

    /// Drop from `rows` the pieces already cut into chunks (the cutter then
    /// counts from the first piece kept): a host cutting a plan as it grows
    /// keeps only the pieces of the chunk in progress. The q knots and
    /// control points stay (8 bytes each per control point).
    pub fn forget_cut(&mut self, rows: &mut TableRows) {
        let j0 = self.j0.min(rows.words.len());
        rows.words.drain(..j0);
        rows.u.drain(..j0.min(rows.u.len()));
        rows.breaks.drain(..j0.min(rows.breaks.len()));
        self.j0 -= j0;
    }

    /// The chunks of `rows` that are final: `rows` holds the pieces known
    /// (its breaks one more, the last the end of the last piece) and the
    /// q control points final over them; `all`: every piece of the plan
    /// (the rest is cut, its last chunk flagged last).
    pub fn cut(&mut self, rows: &TableRows, all: bool) -> Result<Vec<Vec<u8>>, ChunkTableError> {
        let p = rows.words.len();
        let mut out = vec![];
        if self.done {
            return Ok(out);
        }
        let mut cuts = vec![];
        let mut j0 = self.j0;
        while j0 < p {
            let mut j1 = j0 + 1;
            while j1 < p
                && j1 - j0 < usize::from(u16::MAX)
                && rows.breaks[j1] < rows.breaks[j0] + self.opts.chunk_mm
            {
                j1 += 1;
            }
            // (a cut that reached the last piece known is final only if its
            // end is as far as a chunk goes, or nothing follows)
            let ended = j1 < p
                || j1 - j0 >= usize::from(u16::MAX)
                || rows
                    .breaks
                    .get(j1)
                    .is_some_and(|&b| b >= rows.breaks[j0] + self.opts.chunk_mm);
            if !(ended || all) {
                break;
            }
            cuts.push((j0, j1));
            j0 = j1;
        }
        self.j0 = j0;
        // halve stretches over the byte bound (the header's size does not depend on its fields)
        if let Some(max) = self.opts.max_chunk_bytes {
            let mut fitted = Vec::with_capacity(cuts.len());
            let mut todo: Vec<(usize, usize)> = cuts.into_iter().rev().collect();
            while let Some((j0, j1)) = todo.pop() {
                let head = ChunkHead {
                    seq: 0,
                    plan_id: 0,
                    commit: 0,
                    first: false,
                    last: false,
                    splice: false,
                };
                if j1 - j0 > 1
                    && self
                        .encode(rows, (j0, j1), head, self.index + fitted.len())?
                        .len()
                        > max
                {
                    let mid = j0 + (j1 - j0) / 2;
                    todo.push((mid, j1));
                    todo.push((j0, mid));
                } else {
                    fitted.push((j0, j1));
                }
            }
            cuts = fitted;
        }
        let n = cuts.len();
        for (k, &jj) in cuts.iter().enumerate() {
            let index = self.index;
            let last = all && k + 1 == n;
            let head = ChunkHead {
                seq: self.opts.first_seq.wrapping_add(index as u32),
                plan_id: self.opts.plan_id,
                commit: 0,
                first: index == 0,
                last,
                splice: false,
            };
            out.push(self.encode(rows, jj, head, index)?);
            self.index += 1;
            self.done = last;
        }
        Ok(out)
    }

    fn encode(
        &mut self,
        rows: &TableRows,
        (j0, j1): (usize, usize),
        head: ChunkHead,
        index: usize,
    ) -> Result<Vec<u8>, ChunkTableError> {
        let stretch = rows
            .stretch(j0, j1, self.opts.u_form)
            .ok_or(ChunkTableError::Empty)?;
        // a generous bound: every value at its widest encoding
        let bound = 64 + 10 * (stretch.q_knots.len() + stretch.q_ctrl.len()) + 320 * stretch.words.len();
        self.buf.resize(bound, 0);
        let len = encode_chunk(&head, &stretch, &mut self.buf)
            .map_err(|error| ChunkTableError::Encode { index, error })?;
        Ok(self.buf[..len].to_vec())
    }
}

/// What a stream of chunks decodes to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decoded {
    /// Every q span, by knot-span index (each once: spans sent in two
    /// chunks must decode alike).
    pub q_spans: BTreeMap<u32, QSpanForm>,
    /// Every piece, in order.
    pub pieces: Vec<PieceForm>,
}

/// Parse and decode `chunks` in order.
pub fn decode_chunks(chunks: &[Vec<u8>]) -> Result<Decoded, ChunkTableError> {
    let mut d = Decoded::default();
    for (index, bytes) in chunks.iter().enumerate() {
        let c = Chunk::parse(bytes).map_err(|error| ChunkTableError::Parse { index, error })?;
        for q in c.q_spans() {
            if let Some(old) = d.q_spans.insert(q.span, q) {
                if old != q {
                    return Err(ChunkTableError::SpanDisagrees(q.span));
                }
            }
        }
        d.pieces.extend(c.pieces());
    }
    Ok(d)
}

/// Where decoded chunks first differ from the table's rows (`None`: equal,
/// word for word; without the u form, word 0 and section 13 are not compared).
pub fn first_difference(rows: &TableRows, d: &Decoded, u_form: bool) -> Option<String> {
    if d.pieces.len() != rows.words.len() {
        return Some(format!(
            "{} pieces decoded, {} in the table",
            d.pieces.len(),
            rows.words.len()
        ));
    }
    for (j, p) in d.pieces.iter().enumerate() {
        let (a, b) = (rows.breaks[j], rows.breaks[j + 1]);
        if p.start.to_bits() != a.to_bits() || p.end.to_bits() != b.to_bits() {
            return Some(format!(
                "piece {j}: breaks {}..{} against {a}..{b}",
                p.start, p.end
            ));
        }
        let w = &rows.words[j];
        let from = if u_form { 0 } else { 1 };
        if p.words[from..] != w[from..] {
            return Some(format!("piece {j}: words {:?} against {:?}", p.words, w));
        }
        if u_form && p.u.map(f32::to_bits) != rows.u[j].map(f32::to_bits) {
            return Some(format!("piece {j}: u form {:?} against {:?}", p.u, rows.u[j]));
        }
    }
    let want: Vec<u32> = (3..rows.q_ctrl.len() as u32).collect();
    let got: Vec<u32> = d.q_spans.keys().copied().collect();
    if got != want {
        return Some(format!("q spans {got:?} decoded, {want:?} in the table"));
    }
    for (&i, q) in &d.q_spans {
        let k = i as usize - 3;
        if q.local.map(f32::to_bits) != rows.q_local[k].map(f32::to_bits) || q.fixed != rows.q_fixed[k] {
            return Some(format!(
                "q span {i}: {q:?} against {:?} {:?}",
                rows.q_local[k], rows.q_fixed[k]
            ));
        }
    }
    None
}

/// Bytes of a stream of chunks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StreamSize {
    /// Chunks.
    pub chunks: usize,
    /// Bytes of the chunks (header, payload, CRC).
    pub chunk_bytes: usize,
    /// Bytes on the link: each chunk in a DATA frame (kind, COBS, delimiter).
    pub framed_bytes: usize,
    /// Of the chunk bytes: the q parts (knots and control points).
    pub q_bytes: usize,
    /// Of the chunk bytes: the pieces (with their u form, if sent).
    pub piece_bytes: usize,
}

impl StreamSize {
    /// The sizes of `chunks`.
    pub fn of(chunks: &[Vec<u8>]) -> StreamSize {
        StreamSize {
            chunks: chunks.len(),
            chunk_bytes: chunks.iter().map(Vec::len).sum(),
            framed_bytes: chunks.iter().map(|c| framed_len(c)).sum(),
            q_bytes: infos(chunks).map(|i| i.q_part_len()).sum(),
            piece_bytes: infos(chunks).map(|i| i.piece_part_len()).sum(),
        }
    }
}

fn infos(chunks: &[Vec<u8>]) -> impl Iterator<Item = firmware_core::stream::ChunkInfo> + '_ {
    chunks
        .iter()
        .filter_map(|c| Chunk::parse(c).ok().map(|c| *c.info()))
}

/// Bytes of `chunk` in a DATA frame on the link.
pub fn framed_len(chunk: &[u8]) -> usize {
    let mut out = vec![0u8; encoded_max_len(chunk.len() + 1)];
    firmware_core::stream::frame::encode_data(chunk, &mut out).unwrap_or(out.len())
}
