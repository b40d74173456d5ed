//! The shared vocabulary of planner and interpolator: the kinematic
//! [`Limits`] (paper eqs. 8–13) and the jerk-limited [`EndSegments`] that
//! start and stop a plan (table section 14).

/// f64 values in the end-segment section when present.
pub const END_LEN: usize = 6;

/// Kinematic limits: tangential (`vbar` mm/s, `abar` mm/s², `jbar` mm/s³,
/// eqs. 11–13) and per axis x, y, z (`v`, `a`, `j`, eqs. 8–10).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Limits {
    /// Tangential velocity, mm/s.
    pub vbar: f64,
    /// Tangential acceleration, mm/s².
    pub abar: f64,
    /// Tangential jerk, mm/s³.
    pub jbar: f64,
    /// Axis velocities, mm/s.
    pub v: [f64; 3],
    /// Axis accelerations, mm/s².
    pub a: [f64; 3],
    /// Axis jerks, mm/s³.
    pub j: [f64; 3],
}

impl Limits {
    /// The 12 values in table order: vbar, abar, jbar, v, a, j.
    pub fn to_array(&self) -> [f64; 12] {
        let [v0, v1, v2] = self.v;
        let [a0, a1, a2] = self.a;
        let [j0, j1, j2] = self.j;
        [
            self.vbar, self.abar, self.jbar, v0, v1, v2, a0, a1, a2, j0, j1, j2,
        ]
    }
    /// The inverse of [`Limits::to_array`].
    pub fn from_array(x: [f64; 12]) -> Self {
        let [vbar, abar, jbar, v0, v1, v2, a0, a1, a2, j0, j1, j2] = x;
        Limits {
            vbar,
            abar,
            jbar,
            v: [v0, v1, v2],
            a: [a0, a1, a2],
            j: [j0, j1, j2],
        }
    }
}

/// Time-domain jerk-limited start and stop segments (section 14).
///
/// Start: s(t) = J₁t³/6, ṡ = J₁t²/2, s̈ = J₁t, s⃛ = J₁ for 0 ≤ t ≤ t₁, so
/// q = ṡ² = (6^{4/3}/4)·J₁^{2/3}·s^{4/3}; it ends at s₁ = J₁t₁³/6 where q joins
/// it C² (q(s₁) = Q₁, q′(s₁) = 4Q₁/(3s₁), q″(s₁) = 4Q₁/(9s₁²)). Stop, the
/// mirror image: s = L − J₂τ³/6 with τ from t₂ down to 0, from s₂ to L.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EndSegments {
    /// End of the start segment s₁, mm.
    pub s_start: f64,
    /// Jerk of the start segment J₁, mm/s³.
    pub jerk_start: f64,
    /// Duration of the start segment t₁, s.
    pub t_start: f64,
    /// Start of the stop segment s₂, mm.
    pub s_stop: f64,
    /// Jerk of the stop segment J₂ (s⃛ = +J₂ while decelerating), mm/s³.
    pub jerk_stop: f64,
    /// Duration of the stop segment t₂, s.
    pub t_stop: f64,
}

impl EndSegments {
    /// The segments that join q with q(s₁) = `q_start` and q(s₂) = `q_stop`
    /// (both > 0) on a path of length `length`: J = 2Q^{3/2}/(9d²) and
    /// t = 3d/√Q with d = s₁ resp. L − s₂.
    pub fn from_q(s_start: f64, q_start: f64, s_stop: f64, q_stop: f64, length: f64) -> Self {
        let seg = |d: f64, q: f64| {
            let v = libm::sqrt(q);
            (2.0 * q * v / (9.0 * d * d), 3.0 * d / v)
        };
        let (jerk_start, t_start) = seg(s_start, q_start);
        let (jerk_stop, t_stop) = seg(length - s_stop, q_stop);
        EndSegments {
            s_start,
            jerk_start,
            t_start,
            s_stop,
            jerk_stop,
            t_stop,
        }
    }

    /// The six values in table order.
    pub fn to_array(&self) -> [f64; END_LEN] {
        [
            self.s_start,
            self.jerk_start,
            self.t_start,
            self.s_stop,
            self.jerk_stop,
            self.t_stop,
        ]
    }

    /// The inverse of [`EndSegments::to_array`].
    pub fn from_array(x: [f64; END_LEN]) -> Self {
        let [s_start, jerk_start, t_start, s_stop, jerk_stop, t_stop] = x;
        EndSegments {
            s_start,
            jerk_start,
            t_start,
            s_stop,
            jerk_stop,
            t_stop,
        }
    }

    /// `[s, ṡ, s̈, s⃛]` at time `t` of the start segment (0 ≤ t ≤ t₁).
    pub fn start_at(&self, t: f64) -> [f64; 4] {
        let j = self.jerk_start;
        [j * t * t * t / 6.0, 0.5 * j * t * t, j * t, j]
    }

    /// `[s, ṡ, s̈, s⃛]` of the stop segment `tau` before the end (0 ≤ τ ≤ t₂)
    /// on a path of length `length`.
    pub fn stop_at(&self, length: f64, tau: f64) -> [f64; 4] {
        let j = self.jerk_stop;
        [
            length - j * tau * tau * tau / 6.0,
            0.5 * j * tau * tau,
            -j * tau,
            j,
        ]
    }

    /// The feed ṡ (mm/s) at arc length `s` inside a segment (from
    /// s = J t³/6: ṡ = ½ J (6s/J)^{2/3}, the stop mirrored from `length`);
    /// `None` on [s₁, s₂], where q is executed.
    pub fn feed_at(&self, s: f64, length: f64) -> Option<f64> {
        let v = |d: f64, j: f64| {
            let t = libm::cbrt(6.0 * d.max(0.0) / j);
            0.5 * j * t * t
        };
        if s < self.s_start {
            Some(v(s, self.jerk_start))
        } else if s > self.s_stop {
            Some(v(length - s, self.jerk_stop))
        } else {
            None
        }
    }

    /// `[q, q′, q″]` the segments impose at s₁ (`stop` false) or s₂ (true):
    /// q = ṡ², q′ = 2s̈, q″ = 2s⃛/ṡ.
    pub fn q_join(&self, length: f64, stop: bool) -> [f64; 3] {
        let [_, v, a, j] = if stop {
            self.stop_at(length, self.t_stop)
        } else {
            self.start_at(self.t_start)
        };
        [v * v, 2.0 * a, 2.0 * j / v]
    }
}
