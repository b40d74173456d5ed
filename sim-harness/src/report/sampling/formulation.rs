//! How the plan LP is posed: the q ≤ q̂ bound and the objective weights,
//! by name (`paper`, `default`, `BOUND/OBJECTIVE`).

use planner_host::lp::{Objective, QhatBound};

/// How the plan LP is posed: the q ≤ q̂ bound and the objective weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Formulation {
    /// How stage 2 is kept under the pseudo-jerk.
    pub qhat_bound: QhatBound,
    /// Objective weights.
    pub objective: Objective,
}

impl Formulation {
    /// The paper as printed: no q ≤ q̂ bound, uniform weights c = 1.
    pub const PAPER: Formulation = Formulation {
        qhat_bound: QhatBound::None,
        objective: Objective::Uniform,
    };
    /// This project's default: a ≤ â, weights c·a = ∫q ds.
    pub const DEFAULT: Formulation = Formulation {
        qhat_bound: QhatBound::ControlPoints,
        objective: Objective::Integral,
    };

    /// Short name: `paper`, `default` or `BOUND/OBJECTIVE`.
    pub fn name(&self) -> String {
        if *self == Self::PAPER {
            "paper".into()
        } else if *self == Self::DEFAULT {
            "default".into()
        } else {
            format!("{}/{}", self.qhat_bound, self.objective)
        }
    }

    /// Name with its meaning, for headings.
    pub fn label(&self) -> String {
        format!(
            "{} (q̂ bound `{}`, objective `{}`)",
            self.name(),
            self.qhat_bound,
            self.objective
        )
    }
}

/// `paper`, `default` or `BOUND/OBJECTIVE` (e.g. `none/integral`).
impl std::str::FromStr for Formulation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "paper" => Ok(Self::PAPER),
            "default" => Ok(Self::DEFAULT),
            t => {
                let (b, o) = t.split_once('/').ok_or_else(|| {
                    format!("unknown formulation `{s}`: expected paper, default or BOUND/OBJECTIVE")
                })?;
                Ok(Formulation {
                    qhat_bound: b.parse()?,
                    objective: o.parse()?,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::sampling::qhat::DECOMP;

    #[test]
    fn formulation_names_parse_back() {
        for f in DECOMP {
            assert_eq!(f.name().parse::<Formulation>().unwrap(), f);
        }
        assert!("nonsense".parse::<Formulation>().is_err());
        assert!("none/whatever".parse::<Formulation>().is_err());
    }
}
