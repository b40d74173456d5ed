//! One move as a NURBS piece: lines and circular arcs exactly, helices and
//! spirals by a fitted cubic, NURBS blocks as given; and the two operations
//! that bring pieces to a common degree (Bézier decomposition by knot
//! insertion, then degree elevation of each Bézier segment).
//!
//! Pieces are kept in homogeneous form `(w·x, w·y, w·z, w)` with a clamped
//! knot vector on their own parameter range; [`super::paths`] rescales and
//! concatenates them.
//!
//! - **Line**: degree 2, control points start, midpoint, end, weights 1
//!   (u ∝ arc length).
//! - **Circular arc** (planar, one radius): rational quadratic segments of
//!   equal sweep θ ≤ 90°, middle control point at the tangents'
//!   intersection `c + R/cos(θ/2)·(cos φₘ, sin φₘ)`, weight cos(θ/2)
//!   (Piegl & Tiller §7.5): exact.
//! - **Helix or spiral** (a word on the normal axis, or start and end radii
//!   that differ within LinuxCNC's tolerance): not a rational quadratic, so a
//!   non-rational cubic Hermite fit of r(t) = c + R(t)(cos φ(t), sin φ(t)) +
//!   z(t)·n, R and z linear in t: Bézier segments of equal sweep whose end
//!   points and end tangents are the exact ones (so the joins are tangent),
//!   the segment count doubled until the parametric error |fit(t) − r(t)|,
//!   measured at [`HELIX_CHECKS`] points per segment, is at most half of
//!   [`HELIX_TOL_MM`] (the parametric error bounds the distance to the
//!   helix from above).
//! - **NURBS** (G5.2/G5.3, G6.2): the control points, weights and knots as
//!   read; degree 1 (a G6.2 of order 2) is elevated to 2; a knot vector
//!   that is not clamped is refused.

use std::f64::consts::FRAC_PI_2;

use crate::gcode::{Move, MoveKind};
use crate::geometry::curve::{norm, polygon_length, sub};

/// Largest distance between a fitted helix and the exact helix, mm.
pub const HELIX_TOL_MM: f64 = 1e-4;

/// Points per Bézier segment at which a helix fit is checked.
pub const HELIX_CHECKS: usize = 32;

/// The most segments a helix fit may use before giving up.
const HELIX_MAX_SEGMENTS: usize = 1 << 16;

/// A radius difference below this makes an arc circular, mm.
const SPIRAL_MIN_MM: f64 = 1e-9;

/// A move as one clamped NURBS in homogeneous form.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    /// Degree.
    pub degree: usize,
    /// Clamped knots.
    pub knots: Vec<f64>,
    /// Homogeneous control points `(w·x, w·y, w·z, w)`.
    pub hpoints: Vec<[f64; 4]>,
}

/// Why a move cannot become a piece.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PieceError {
    /// A NURBS block whose knot vector is not clamped at an end.
    #[error("the NURBS knot vector is not clamped (its first and last degree + 1 knots must be equal)")]
    NotClamped,
    /// A move without its geometry (an arc without centre, a NURBS without points).
    #[error("the move has no geometry")]
    NoGeometry,
    /// The helix fit did not reach its tolerance.
    #[error("the helix cannot be fitted within {HELIX_TOL_MM} mm")]
    HelixFit,
}

fn cart(h: [f64; 4]) -> [f64; 3] {
    [h[0] / h[3], h[1] / h[3], h[2] / h[3]]
}

fn homog(p: [f64; 3], w: f64) -> [f64; 4] {
    [p[0] * w, p[1] * w, p[2] * w, w]
}

impl Piece {
    /// The first control point, mm.
    pub fn start(&self) -> [f64; 3] {
        cart(self.hpoints[0])
    }

    /// The last control point, mm.
    pub fn end(&self) -> [f64; 3] {
        cart(self.hpoints[self.hpoints.len() - 1])
    }

    /// Unit tangent at the start: towards the first control point distinct
    /// from the start (the curve is clamped).
    pub fn start_tangent(&self) -> Option<[f64; 3]> {
        let a = self.start();
        self.hpoints[1..].iter().find_map(|&h| unit(sub(cart(h), a)))
    }

    /// Unit tangent at the end (direction of travel).
    pub fn end_tangent(&self) -> Option<[f64; 3]> {
        let b = self.end();
        let n = self.hpoints.len();
        self.hpoints[..n - 1]
            .iter()
            .rev()
            .find_map(|&h| unit(sub(b, cart(h))))
    }

    /// The same piece as Bézier segments (every interior knot of
    /// multiplicity `degree`), each elevated to degree `target ≥ degree`.
    pub fn elevated(&self, target: usize) -> Piece {
        if target == self.degree {
            return self.clone();
        }
        let bz = self.decomposed();
        let p = bz.degree;
        let segs = (bz.hpoints.len() - 1) / p;
        let mut breaks = vec![bz.knots[0]];
        for k in 1..=segs {
            breaks.push(bz.knots[k * p + 1]);
        }
        let mut out = Piece {
            degree: target,
            knots: Vec::new(),
            hpoints: Vec::new(),
        };
        for k in 0..segs {
            let mut seg: Vec<[f64; 4]> = bz.hpoints[k * p..=k * p + p].to_vec();
            for _ in p..target {
                seg = elevate_bezier(&seg);
            }
            if k == 0 {
                out.hpoints.extend_from_slice(&seg);
            } else {
                out.hpoints.extend_from_slice(&seg[1..]);
            }
        }
        out.knots.resize(target + 1, breaks[0]);
        for &b in &breaks[1..segs] {
            out.knots.resize(out.knots.len() + target, b);
        }
        out.knots.resize(out.knots.len() + target + 1, breaks[segs]);
        out
    }

    /// Bézier decomposition: knots inserted until every interior knot has
    /// multiplicity `degree` (the curve is unchanged).
    pub fn decomposed(&self) -> Piece {
        let mut c = self.clone();
        let p = c.degree;
        let last = c.knots[c.knots.len() - 1];
        let mut i = p + 1;
        while i < c.knots.len() && c.knots[i] < last {
            let u = c.knots[i];
            let mult = c.knots.iter().filter(|&&k| k == u).count();
            for _ in mult..p {
                c = c.insert_knot(u);
            }
            i = c.knots.iter().rposition(|&k| k == u).unwrap_or(i) + 1;
        }
        c
    }

    /// The piece cut at parameter `u` (strictly inside its range): the part
    /// before and the part after, each clamped, the curve unchanged (`u`
    /// inserted until it has multiplicity `degree`; the control point
    /// there is the curve's point at `u`).
    pub fn split_at(&self, u: f64) -> Option<(Piece, Piece)> {
        let (a, b) = (*self.knots.first()?, *self.knots.last()?);
        if !(u > a && u < b) {
            return None;
        }
        let p = self.degree;
        let mut c = self.clone();
        let mult = c.knots.iter().filter(|&&k| k == u).count();
        for _ in mult..p {
            c = c.insert_knot(u);
        }
        let first = c.knots.iter().position(|&k| k == u)?;
        if first == 0 || first > c.hpoints.len() {
            return None;
        }
        let mut lk = c.knots[..first].to_vec();
        lk.resize(first + p + 1, u);
        let mut rk = vec![u; p + 1];
        rk.extend_from_slice(c.knots.get(first + p..)?);
        let before = Piece {
            degree: p,
            knots: lk,
            hpoints: c.hpoints[..first].to_vec(),
        };
        let after = Piece {
            degree: p,
            knots: rk,
            hpoints: c.hpoints[first - 1..].to_vec(),
        };
        Some((before, after))
    }

    /// Boehm's single knot insertion (Piegl & Tiller A5.1, r = 1) on the
    /// homogeneous points; `u` strictly inside the range.
    fn insert_knot(&self, u: f64) -> Piece {
        let p = self.degree;
        let uk = &self.knots;
        // k: last index with U[k] ≤ u
        let k = uk.iter().rposition(|&x| x <= u).unwrap_or(p);
        let s = uk.iter().filter(|&&x| x == u).count();
        let n = self.hpoints.len();
        let mut q = Vec::with_capacity(n + 1);
        for i in 0..=n {
            if i + p <= k {
                q.push(self.hpoints[i]);
            } else if i + s <= k {
                let a = (u - uk[i]) / (uk[i + p] - uk[i]);
                let (pi, pm) = (self.hpoints[i], self.hpoints[i - 1]);
                q.push(std::array::from_fn(|c| a * pi[c] + (1.0 - a) * pm[c]));
            } else {
                q.push(self.hpoints[i - 1]);
            }
        }
        let mut knots = uk.clone();
        knots.insert(k + 1, u);
        Piece {
            degree: p,
            knots,
            hpoints: q,
        }
    }
}

/// Degree elevation of one Bézier segment by one:
/// Qᵢ = i/(p+1)·Pᵢ₋₁ + (1 − i/(p+1))·Pᵢ.
pub fn elevate_bezier(pts: &[[f64; 4]]) -> Vec<[f64; 4]> {
    let p = pts.len() - 1;
    let mut q = Vec::with_capacity(p + 2);
    q.push(pts[0]);
    for i in 1..=p {
        let a = i as f64 / (p + 1) as f64;
        q.push(std::array::from_fn(|c| a * pts[i - 1][c] + (1.0 - a) * pts[i][c]));
    }
    q.push(pts[p]);
    q
}

fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm(a);
    (n > 1e-12).then(|| [a[0] / n, a[1] / n, a[2] / n])
}

/// The angle between two unit vectors, rad (robust near 0 and π).
pub fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    norm(cross).atan2(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
}

/// A straight piece, degree 2.
pub fn line(a: [f64; 3], b: [f64; 3]) -> Piece {
    let m = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])];
    Piece {
        degree: 2,
        knots: vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        hpoints: vec![homog(a, 1.0), homog(m, 1.0), homog(b, 1.0)],
    }
}

/// The exact geometry of an arc move: r(t), t ∈ [0, 1], and dr/dt.
#[derive(Debug, Clone, Copy)]
pub struct ArcPath {
    /// Centre (its normal coordinate is the start's).
    pub center: [f64; 3],
    /// Axis indices: first, second, normal.
    pub axes: [usize; 3],
    /// Start angle, rad, from the first axis toward the second.
    pub phi0: f64,
    /// Signed sweep, rad (positive: G3).
    pub sweep: f64,
    /// Radius at the start and at the end, mm.
    pub r0: f64,
    /// Radius at the end, mm.
    pub r1: f64,
    /// Normal coordinate at the start and at the end, mm.
    pub z0: f64,
    /// Normal coordinate at the end, mm.
    pub z1: f64,
}

impl ArcPath {
    /// The arc of move `m` (an arc move with its geometry).
    pub fn of(m: &Move) -> Option<ArcPath> {
        let a = m.arc.as_ref()?;
        let n = a.normal.index();
        let (i, j) = match n {
            2 => (0, 1),
            1 => (2, 0),
            _ => (1, 2),
        };
        let phi0 = (m.start[j] - a.center[j]).atan2(m.start[i] - a.center[i]);
        let sweep = if a.turns >= 0 { a.sweep_rad } else { -a.sweep_rad };
        Some(ArcPath {
            center: a.center,
            axes: [i, j, n],
            phi0,
            sweep,
            r0: a.radius_mm,
            r1: a.end_radius_mm,
            z0: m.start[n],
            z1: a.helical_end_mm,
        })
    }

    /// True when the arc is a plane circle (one radius, no helix).
    pub fn is_circular(&self) -> bool {
        (self.r1 - self.r0).abs() <= SPIRAL_MIN_MM && (self.z1 - self.z0).abs() <= SPIRAL_MIN_MM
    }

    /// r(t) and dr/dt.
    pub fn eval(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let [i, j, n] = self.axes;
        let phi = self.phi0 + self.sweep * t;
        let r = self.r0 + (self.r1 - self.r0) * t;
        let (s, c) = phi.sin_cos();
        let mut p = [0.0; 3];
        let mut d = [0.0; 3];
        p[i] = self.center[i] + r * c;
        p[j] = self.center[j] + r * s;
        p[n] = self.z0 + (self.z1 - self.z0) * t;
        d[i] = (self.r1 - self.r0) * c - r * s * self.sweep;
        d[j] = (self.r1 - self.r0) * s + r * c * self.sweep;
        d[n] = self.z1 - self.z0;
        (p, d)
    }

    /// Arc length, mm (exact for a circle; by 64-point quadrature otherwise).
    pub fn length(&self) -> f64 {
        if self.is_circular() {
            return self.r0 * self.sweep.abs();
        }
        let n = 256;
        (0..n)
            .map(|k| {
                let t = (k as f64 + 0.5) / n as f64;
                norm(self.eval(t).1) / n as f64
            })
            .sum()
    }
}

/// An arc move as a piece: exact rational quadratics for a circle, a fitted
/// cubic for a helix or spiral (see the module docs). `start` and `end` are
/// put exactly at the move's points.
pub fn arc(m: &Move) -> Result<Piece, PieceError> {
    let a = ArcPath::of(m).ok_or(PieceError::NoGeometry)?;
    let mut piece = if a.is_circular() { circular(&a) } else { helix(&a)? };
    let last = piece.hpoints.len() - 1;
    piece.hpoints[0] = homog(m.start, piece.hpoints[0][3]);
    piece.hpoints[last] = homog(m.end, piece.hpoints[last][3]);
    Ok(piece)
}

fn circular(a: &ArcPath) -> Piece {
    let segs = ((a.sweep.abs() / FRAC_PI_2) - 1e-9).ceil().max(1.0) as usize;
    let theta = a.sweep / segs as f64;
    let w = (theta / 2.0).cos();
    let [i, j, n] = a.axes;
    let mut hp = Vec::with_capacity(2 * segs + 1);
    let at = |phi: f64, r: f64| {
        let mut p = [0.0; 3];
        p[i] = a.center[i] + r * phi.cos();
        p[j] = a.center[j] + r * phi.sin();
        p[n] = a.z0;
        p
    };
    hp.push(homog(at(a.phi0, a.r0), 1.0));
    for k in 0..segs {
        let mid = a.phi0 + theta * (k as f64 + 0.5);
        hp.push(homog(at(mid, a.r0 / w), w));
        hp.push(homog(at(a.phi0 + theta * (k + 1) as f64, a.r0), 1.0));
    }
    let mut knots = vec![0.0; 3];
    for k in 1..segs {
        let u = k as f64 / segs as f64;
        knots.extend([u, u]);
    }
    knots.extend([1.0; 3]);
    Piece {
        degree: 2,
        knots,
        hpoints: hp,
    }
}

fn helix(a: &ArcPath) -> Result<Piece, PieceError> {
    let mut segs = ((a.sweep.abs() / (FRAC_PI_2 / 4.0)).ceil() as usize).max(1);
    while segs <= HELIX_MAX_SEGMENTS {
        let h = 1.0 / segs as f64;
        let mut hp = Vec::with_capacity(3 * segs + 1);
        let mut worst: f64 = 0.0;
        for k in 0..segs {
            let (t0, t1) = (k as f64 * h, (k + 1) as f64 * h);
            let (p0, d0) = a.eval(t0);
            let (p3, d3) = a.eval(t1);
            let p1: [f64; 3] = std::array::from_fn(|c| p0[c] + h / 3.0 * d0[c]);
            let p2: [f64; 3] = std::array::from_fn(|c| p3[c] - h / 3.0 * d3[c]);
            let bz = [p0, p1, p2, p3];
            for m in 1..HELIX_CHECKS {
                let tau = m as f64 / HELIX_CHECKS as f64;
                let fit = bezier3(&bz, tau);
                worst = worst.max(norm(sub(fit, a.eval(t0 + tau * h).0)));
            }
            if k == 0 {
                hp.push(homog(p0, 1.0));
            }
            hp.extend([homog(p1, 1.0), homog(p2, 1.0), homog(p3, 1.0)]);
        }
        if worst <= 0.5 * HELIX_TOL_MM {
            let mut knots = vec![0.0; 4];
            for k in 1..segs {
                let u = k as f64 * h;
                knots.extend([u, u, u]);
            }
            knots.extend([1.0; 4]);
            return Ok(Piece {
                degree: 3,
                knots,
                hpoints: hp,
            });
        }
        segs *= 2;
    }
    Err(PieceError::HelixFit)
}

fn bezier3(b: &[[f64; 3]; 4], t: f64) -> [f64; 3] {
    let s = 1.0 - t;
    let c = [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t];
    std::array::from_fn(|k| c[0] * b[0][k] + c[1] * b[1][k] + c[2] * b[2][k] + c[3] * b[3][k])
}

/// Arc length cut from a NURBS end whose first (or last) two control points
/// coincide, mm: there the curve stands still (dC/du = 0), which no
/// arc-length parametrisation can follow ([`trim_still_ends`]).
pub const STILL_END_TRIM_MM: f64 = 2e-4;

/// A NURBS whose first two control points coincide (LinuxCNC's trident
/// samples list the current point again as their first G5.2 point) stands
/// still at its start: |dC/du| = 0 there, the s → u map is singular and the
/// planner refuses the curve. The piece is split by knot insertion where it
/// has run [`STILL_END_TRIM_MM`] (measured as a chord), the first part is
/// dropped, and the second part's first control point is put back on the
/// curve's start, so that the piece still starts exactly where the program
/// says and now moves from there at once. The curve moves by at most about
/// [`STILL_END_TRIM_MM`] near that end (the programmed-geometry check
/// allows 1 µm); the last two control points are treated the same way.
pub fn trim_still_ends(piece: Piece) -> Piece {
    let piece = trim_still_start(piece);
    reversed(&trim_still_start(reversed(&piece)))
}

fn reversed(p: &Piece) -> Piece {
    let (a, b) = (p.knots[0], p.knots[p.knots.len() - 1]);
    Piece {
        degree: p.degree,
        knots: p.knots.iter().rev().map(|&u| a + b - u).collect(),
        hpoints: p.hpoints.iter().rev().copied().collect(),
    }
}

fn trim_still_start(piece: Piece) -> Piece {
    let p = piece.degree;
    let (p0, p1) = (piece.start(), cart(piece.hpoints[1]));
    let scale = 1.0 + norm(p0);
    if norm(sub(p1, p0)) > 1e-12 * scale || piece.hpoints.len() <= p + 1 && p < 2 {
        return piece;
    }
    let Some(curve) = piece_curve(&piece) else {
        return piece;
    };
    let (a, b) = (piece.knots[0], piece.knots[piece.knots.len() - 1]);
    // the parameter where the chord from the start reaches the trim length
    let chord = |u: f64| norm(sub(curve.point(u), p0));
    let mut hi = a + (b - a) * 1e-3;
    while chord(hi) < STILL_END_TRIM_MM && hi < b {
        hi = (a + 2.0 * (hi - a)).min(b);
    }
    if chord(hi) < STILL_END_TRIM_MM {
        return piece;
    }
    let mut lo = a;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chord(mid) < STILL_END_TRIM_MM {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let eps = hi;
    if !(eps > a && eps < piece.knots[p + 1]) {
        return piece;
    }
    let mut c = piece.clone();
    for _ in 0..p {
        c = c.insert_knot(eps);
    }
    // knots now: a (p+1 times), eps (p times), ...; the point at eps is
    // control point p, where the right part starts
    let mut knots = vec![eps; p + 1];
    knots.extend_from_slice(&c.knots[2 * p + 1..]);
    let mut hpoints = c.hpoints[p..].to_vec();
    hpoints[0] = homog(p0, hpoints[0][3]);
    Piece {
        degree: p,
        knots,
        hpoints,
    }
}

fn piece_curve(p: &Piece) -> Option<crate::geometry::curve::Nurbs> {
    let w: Vec<f64> = p.hpoints.iter().map(|h| h[3]).collect();
    let pts = p.hpoints.iter().map(|&h| cart(h)).collect();
    crate::geometry::curve::Nurbs::new(p.degree, p.knots.clone(), w, pts).ok()
}

/// A NURBS move as a piece (degree 1 elevated to 2; ends where the curve
/// stands still trimmed, [`trim_still_ends`]).
pub fn nurbs(m: &Move) -> Result<Piece, PieceError> {
    let g = m.nurbs.as_ref().ok_or(PieceError::NoGeometry)?;
    let p = g.degree;
    let k = &g.knots;
    if p == 0 || k.len() < 2 * (p + 1) || g.control_points.len() != g.weights.len() {
        return Err(PieceError::NoGeometry);
    }
    let last = k.len() - 1;
    if k[..=p].iter().any(|&x| x != k[0]) || k[last - p..].iter().any(|&x| x != k[last]) {
        return Err(PieceError::NotClamped);
    }
    let piece = Piece {
        degree: p,
        knots: k.clone(),
        hpoints: g
            .control_points
            .iter()
            .zip(&g.weights)
            .map(|(&pt, &w)| homog(pt, w))
            .collect(),
    };
    Ok(trim_still_ends(if p < 2 { piece.elevated(2) } else { piece }))
}

/// The piece of a move: a line for a rapid or a line, [`arc`], [`nurbs`].
pub fn of_move(m: &Move) -> Result<Piece, PieceError> {
    match m.kind {
        MoveKind::Rapid | MoveKind::Line => Ok(line(m.start, m.end)),
        MoveKind::Arc => arc(m),
        MoveKind::Nurbs => nurbs(m),
    }
}

/// Length of a move, mm: exact for lines and arcs, the control polygon's
/// for a NURBS (an upper bound, used only to find moves too short to plan).
pub fn move_length(m: &Move) -> f64 {
    match m.kind {
        MoveKind::Rapid | MoveKind::Line => norm(sub(m.end, m.start)),
        MoveKind::Arc => ArcPath::of(m).map_or(0.0, |a| a.length()),
        MoveKind::Nurbs => m
            .nurbs
            .as_ref()
            .map_or(0.0, |g| polygon_length(&g.control_points)),
    }
}
