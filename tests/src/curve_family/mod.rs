//! A seeded family of random toolpaths, and the sweep that plans each one,
//! runs it through the firmware and checks the setpoints.
//!
//! [`generate`] draws curve `index` of the family named by `seed` from its
//! own SplitMix64 stream: the same pair gives the same curve wherever the
//! platform's `sin`, `cos`, `exp` and `ln` round alike (the draws use them;
//! everything else is IEEE arithmetic).
//! The families ([`Family`]) cover what a CAM system emits and what makes
//! the planner and the firmware work hard:
//!
//! - degree 2 to 5, planar (z = 0) and space curves;
//! - rational weights from 0.05 to 20, independent per control point or
//!   slowly varying;
//! - long exactly-straight runs into tight turns of 0.5 to 5 mm radius;
//! - C1 joins: interior knots of multiplicity degree − 1, where the
//!   curvature jumps;
//! - from tens to a few thousand control points, 50 to 2,000 mm long.
//!
//! Every curve is regular: its parametric speed never falls below 10⁻³ of
//! the mean, its radius of curvature never below 0.05 mm (sampled in every
//! knot span); a draw that fails is redrawn from the same stream.
//!
//! The sweep ([`sweep`]) is shared by the CI test `tests/curve_family.rs`
//! and the example `examples/curve_family.rs`, which runs the full family
//! and prints the worst ratios per family (docs/curve-family.md).

mod rng;
mod shapes;
pub mod sweep;

pub use rng::SplitMix64;

use planner_host::Nurbs;

use shapes::{chord_knots, cross, norm, V3};

/// The kinds of toolpath the generator draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Family {
    /// A smooth planar random walk, weights 1.
    Smooth2d,
    /// A smooth space random walk with drifting turning plane, weights 1.
    Smooth3d,
    /// Straight runs (collinear control points) into arcs of 0.5–5 mm radius.
    StraightTight,
    /// A smooth walk with weights from 0.05 to 20.
    Weights,
    /// A smooth walk with interior knots of multiplicity degree − 1 (C1 joins).
    C1Knots,
    /// 1,000 to 3,000 control points, 500 to 2,000 mm.
    Large,
}

impl Family {
    /// Every family, in report order.
    pub const ALL: [Family; 6] = [
        Family::Smooth2d,
        Family::Smooth3d,
        Family::StraightTight,
        Family::Weights,
        Family::C1Knots,
        Family::Large,
    ];

    /// The family's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Family::Smooth2d => "smooth_2d",
            Family::Smooth3d => "smooth_3d",
            Family::StraightTight => "straight_tight",
            Family::Weights => "weights",
            Family::C1Knots => "c1_knots",
            Family::Large => "large",
        }
    }

    /// The family named `name` ([`Family::name`]).
    pub fn from_name(name: &str) -> Option<Family> {
        Family::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The family of curve `index`: a cycle of eleven, two of each small
    /// family and one large curve, so that any run of curves mixes them.
    pub fn of_index(index: usize) -> Family {
        const CYCLE: [Family; 11] = [
            Family::Smooth2d,
            Family::Smooth3d,
            Family::StraightTight,
            Family::Weights,
            Family::C1Knots,
            Family::Smooth2d,
            Family::Smooth3d,
            Family::StraightTight,
            Family::Weights,
            Family::C1Knots,
            Family::Large,
        ];
        CYCLE[index % CYCLE.len()]
    }
}

impl std::fmt::Display for Family {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One generated toolpath.
#[derive(Debug, Clone)]
pub struct Case {
    /// Its index in the family.
    pub index: usize,
    /// What kind of toolpath it is.
    pub family: Family,
    /// Whether it leaves the z = 0 plane.
    pub space: bool,
    /// The toolpath, named `fam<seed>_<index>_<family>`.
    pub curve: Nurbs,
    /// Its length, mm (sampled chords, within 0.1 %).
    pub length_mm: f64,
    /// Draws rejected as irregular before this one.
    pub redraws: usize,
}

/// Least parametric speed allowed, relative to the mean speed.
pub const MIN_REL_SPEED: f64 = 1e-3;

/// Least radius of curvature allowed, mm.
pub const MIN_RADIUS_MM: f64 = 0.05;

/// Shortest and longest accepted length, mm.
pub const LENGTH_MM: (f64, f64) = (40.0, 2100.0);

/// Curve `index` of the family named by `seed`.
pub fn generate(seed: u64, index: usize) -> Case {
    let family = Family::of_index(index);
    let mut rng = SplitMix64::new(seed ^ (index as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
    // a few draws of the stream's start decorrelate neighbouring indices
    for _ in 0..4 {
        rng.next_u64();
    }
    let mut redraws = 0;
    loop {
        let (curve, space) = draw(&mut rng, family);
        if let Some(curve) = curve {
            if let Some(length_mm) = regular_length(&curve) {
                let mut curve = curve;
                curve.name = format!("fam{seed}_{index}_{}", family.name());
                return Case {
                    index,
                    family,
                    space,
                    curve,
                    length_mm,
                    redraws,
                };
            }
        }
        redraws += 1;
    }
}

/// One draw of `family`: the curve (None when the parts do not validate)
/// and whether it is a space curve.
fn draw(rng: &mut SplitMix64, family: Family) -> (Option<Nurbs>, bool) {
    let space = match family {
        Family::Smooth2d => false,
        Family::Smooth3d => true,
        _ => rng.chance(0.5),
    };
    let degree = match family {
        Family::C1Knots => rng.int(3, 5),
        _ => rng.int(2, 5),
    };
    let pts: Vec<V3> = match family {
        Family::StraightTight => shapes::straight_tight(rng, space),
        Family::Large => {
            let n = rng.int(1000, 3000);
            let h = rng.range(0.5, 1.2).min(2000.0 / n as f64);
            shapes::wander(rng, n, h * n as f64, space)
        }
        _ => {
            let length = rng.log_range(50.0, 800.0);
            let h = rng.log_range(0.8, 10.0);
            let n = ((length / h).round() as usize).clamp(degree + 8, 1000);
            shapes::wander(rng, n, length, space)
        }
    };
    let n = pts.len();
    let weights = match family {
        Family::Weights if rng.chance(0.4) => (0..n).map(|_| rng.log_range(0.05, 20.0)).collect(),
        Family::Weights => {
            // log-weight as a slowly varying process over the whole range
            let (lo, hi) = (0.05f64.ln(), 20f64.ln());
            let mut lw = rng.range(lo, hi);
            let corr = rng.range(0.8, 0.98);
            (0..n)
                .map(|_| {
                    lw = (lw + (1.0 - corr) * rng.normal() * (hi - lo)).clamp(lo, hi);
                    lw.exp()
                })
                .collect()
        }
        Family::C1Knots | Family::Large if rng.chance(0.5) => {
            (0..n).map(|_| rng.log_range(0.5, 2.0)).collect()
        }
        _ => vec![1.0; n],
    };
    let mut knots = chord_knots(&pts, degree);
    if family == Family::C1Knots {
        c1_joins(rng, &mut knots, degree);
    }
    (Nurbs::new(degree, knots, weights, pts).ok(), space)
}

/// Turn 1 to 5 interior knots into knots of multiplicity `p − 1` (by moving
/// the next `p − 2` knots onto them), where the curve is only C1.
fn c1_joins(rng: &mut SplitMix64, knots: &mut [f64], p: usize) {
    let m = p - 1;
    let (first, end) = (p + 1, knots.len() - p - 1); // interior knots: [first, end)
    if end < first + m + 2 {
        return;
    }
    let wanted = rng.int(1, 5);
    let mut taken = vec![false; knots.len()];
    for _ in 0..wanted * 4 {
        if taken.iter().filter(|&&t| t).count() >= wanted * m {
            break;
        }
        let i = rng.int(first + 1, end - m - 1);
        // distinct from its neighbours and clear of earlier joins
        if (i - 1..=i + m).any(|j| taken[j]) || knots[i] <= knots[i - 1] || knots[i + m] <= knots[i] {
            continue;
        }
        let v = knots[i];
        for j in i..i + m {
            knots[j] = v;
            taken[j] = true;
        }
    }
}

/// The curve's length if it is regular (see the module docs), else None.
fn regular_length(c: &Nurbs) -> Option<f64> {
    const PER_SPAN: usize = 24;
    let (u0, u1) = c.u_range();
    let (mut length, mut min_speed, mut min_radius) = (0.0, f64::INFINITY, f64::INFINITY);
    for (span, a, b) in c.spans() {
        let mut prev: Option<V3> = None;
        for k in 0..=PER_SPAN {
            let u = a + (b - a) * k as f64 / PER_SPAN as f64;
            let d = c.derivs_in_span(span, u, 2);
            let speed = norm(d[1]);
            min_speed = min_speed.min(speed);
            let bend = norm(cross(d[1], d[2]));
            if bend > 0.0 {
                min_radius = min_radius.min(speed.powi(3) / bend);
            }
            if let Some(q) = prev {
                length += norm(shapes::sub(d[0], q));
            }
            prev = Some(d[0]);
        }
    }
    let mean_speed = length / (u1 - u0);
    let ok = min_speed > MIN_REL_SPEED * mean_speed
        && min_radius >= MIN_RADIUS_MM
        && (LENGTH_MM.0..=LENGTH_MM.1).contains(&length);
    ok.then_some(length)
}
