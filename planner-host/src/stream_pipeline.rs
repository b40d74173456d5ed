//! The plan cut into chunks while it is planned: fed each
//! [`Commit`](crate::plan::Commit) of windowed planning
//! ([`crate::plan::plan_curve_committing`]), a [`ChunkPipeline`] fits the
//! pieces whose knot-span group q is now final over
//! (`firmware_core::table::fit_pieces`, the table's own fit) and cuts the
//! chunks no later commit can change ([`ChunkCutter`]). The chunks are those
//! [`crate::stream::chunk_table`] cuts from the finished table, byte for byte
//! (`planner-host/tests/stream_pipeline.rs`), so the host can send the first
//! while the rest of the path is still being planned.
//!
//! Why the pieces can be fitted early: a piece's length follows the feed √q
//! where it starts (`servo_forms::fit`), so a group's pieces read q only
//! on the group's own arc length [s₀, s₁), and q there depends on the
//! control points of its knot spans alone — final once a window has
//! committed them.

use firmware_core::table::{fit_pieces, piece_group_bounds, FittedPiece, TableParts};
use firmware_core::{EndSegments, SuSegment};

use crate::geometry::curve::Nurbs;
use crate::plan::Commit;
use crate::stream::{ChunkCutter, ChunkOptions, ChunkTableError, TableRows};

/// What the chunks of a plan need besides q: the path and its s → u map.
#[derive(Clone, Debug)]
pub struct PathParts {
    /// NURBS degree.
    pub degree: u32,
    /// NURBS knots.
    pub knots: Vec<f64>,
    /// Homogeneous control points (w·x, w·y, w·z, w).
    pub points: Vec<[f64; 4]>,
    /// The s → u map's breaks.
    pub su_breaks: Vec<f64>,
    /// The s → u map's segments.
    pub su_segments: Vec<SuSegment>,
}

/// Chunks from commits (see the module docs).
pub struct ChunkPipeline {
    path: PathParts,
    rows: TableRows,
    /// Each knot-span group's [s₀, s₁), mm.
    groups: Vec<(f64, f64)>,
    /// The next group to fit.
    next_group: usize,
    cutter: ChunkCutter,
    /// The end segments as last told.
    ends: Option<EndSegments>,
    /// The last commit came.
    finished: bool,
}

impl ChunkPipeline {
    /// A pipeline for `curve`, started by its first commit (which brings
    /// the knots of q and the s → u map).
    pub fn new(curve: &Nurbs, first: &Commit, opts: &ChunkOptions) -> Result<Self, ChunkTableError> {
        let path = PathParts {
            degree: curve.degree as u32,
            knots: curve.knots.clone(),
            points: curve.to_homogeneous_table(),
            su_breaks: first.su_breaks.to_vec(),
            su_segments: first.su_segments.to_vec(),
        };
        let rows = TableRows {
            q_knots: first.knots.to_vec(),
            q_ctrl: first.ctrl.to_vec(),
            q_local: vec![],
            q_fixed: vec![],
            breaks: vec![],
            words: vec![],
            u: vec![],
        };
        let mut groups = vec![];
        {
            let parts = table_parts(&path, &rows.q_knots, &rows.q_ctrl);
            piece_group_bounds(&parts, |s0, s1| groups.push((s0, s1)));
        }
        Ok(ChunkPipeline {
            path,
            rows,
            groups,
            next_group: 0,
            cutter: ChunkCutter::new(opts)?,
            ends: None,
            finished: false,
        })
    }

    /// Take a commit: the chunks that became final (in order, none twice).
    pub fn commit(&mut self, c: &Commit) -> Result<Vec<Vec<u8>>, ChunkTableError> {
        if self.finished {
            return Ok(vec![]);
        }
        let n = self.rows.q_ctrl.len().min(c.ctrl.len());
        let through = c.through.min(n.saturating_sub(1));
        self.rows.q_ctrl[..=through].copy_from_slice(&c.ctrl[..=through]);
        if c.last {
            self.rows.q_ctrl[..n].copy_from_slice(&c.ctrl[..n]);
        }
        self.ends = c.ends;
        // q is final below U_{through+1}
        let final_to = if c.last {
            f64::INFINITY
        } else {
            self.rows.q_knots.get(through + 1).copied().unwrap_or(0.0)
        };
        let lo = self.next_group;
        let mut hi = lo;
        while self.groups.get(hi).is_some_and(|&(_, s1)| s1 <= final_to) {
            hi += 1;
        }
        if hi > lo {
            let mut fitted: Vec<FittedPiece> = Vec::new();
            {
                let parts = table_parts(&self.path, &self.rows.q_knots, &self.rows.q_ctrl);
                fit_pieces(&parts, (lo, hi), |p| fitted.push(p));
            }
            // the breaks: every piece's start, then the end of the last
            self.rows.breaks.pop();
            for p in &fitted {
                let d = p.data.as_ref().ok_or(ChunkTableError::Empty)?;
                self.rows.breaks.push(p.start);
                self.rows.words.push(std::array::from_fn(|k| d.words[k] as i64));
                self.rows
                    .u
                    .push(std::array::from_fn(|k| d.f32s.get(k).copied().unwrap_or(0.0)));
            }
            self.rows.breaks.push(self.groups[hi - 1].1);
            self.next_group = hi;
        }
        self.finished = c.last;
        if self.rows.words.is_empty() {
            return Ok(vec![]);
        }
        self.cutter.cut(&self.rows, c.last)
    }

    /// The end segments as the last commit told them.
    pub fn ends(&self) -> Option<EndSegments> {
        self.ends
    }

    /// The path's parts.
    pub fn path(&self) -> &PathParts {
        &self.path
    }

    /// Chunks cut so far.
    pub fn chunks(&self) -> usize {
        self.cutter.chunks()
    }
}

/// Table parts for the piece fit: only the path, the s → u map and q are read.
fn table_parts<'a>(path: &'a PathParts, q_knots: &'a [f64], q_ctrl: &'a [f64]) -> TableParts<'a> {
    TableParts {
        limits: crate::limits::TABLE1,
        path_length_mm: path.su_breaks.last().copied().unwrap_or(0.0),
        predicted_time_s: 0.0,
        nurbs_degree: path.degree,
        nurbs_knots: &path.knots,
        nurbs_points: &path.points,
        su_breaks: &path.su_breaks,
        su_segments: &path.su_segments,
        q_knots,
        q_ctrl,
        ends: None,
        levels: &[],
        pieces: None,
    }
}
