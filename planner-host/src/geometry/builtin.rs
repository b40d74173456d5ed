//! The built-in toolpaths: the five benchmark curves of `planner-host/curves/`
//! (provenance in its README), compiled into the crate so that the tools and
//! the tests can name them without a file beside the repository.

use crate::geometry::curve::Nurbs;
use crate::geometry::curve_error::CurveError;

/// The built-in curves as `(name, JSON text)`, in alphabetical order.
pub(crate) const CURVES: [(&str, &str); 5] = [
    ("butterfly", include_str!("../../curves/butterfly.json")),
    ("circle", include_str!("../../curves/circle.json")),
    ("fan", include_str!("../../curves/fan.json")),
    ("star", include_str!("../../curves/star.json")),
    ("trident", include_str!("../../curves/trident.json")),
];

/// The names [`by_name`] knows, in alphabetical order.
pub const NAMES: [&str; 5] = ["butterfly", "circle", "fan", "star", "trident"];

/// The built-in Butterfly toolpath: the paper's Table 5, corrected
/// (`planner-host/curves/butterfly.json`).
pub fn butterfly() -> Result<Nurbs, CurveError> {
    Nurbs::from_json_str(CURVES[0].1)
}

/// The built-in curve called `name` (case-insensitive: butterfly, circle,
/// fan, star, trident); `None` for any other name.
pub fn by_name(name: &str) -> Option<Result<Nurbs, CurveError>> {
    json(name).map(Nurbs::from_json_str)
}

/// The JSON text of the built-in curve called `name` (case-insensitive), as
/// it is in `planner-host/curves/`; `None` for any other name.
pub fn json(name: &str) -> Option<&'static str> {
    CURVES
        .iter()
        .find(|(n, _)| n.eq_ignore_ascii_case(name))
        .map(|(_, json)| *json)
}

/// Every built-in curve, in the order of [`NAMES`].
pub fn all() -> Result<Vec<Nurbs>, CurveError> {
    CURVES
        .iter()
        .map(|(_, json)| Nurbs::from_json_str(json))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_loads_and_the_lists_agree() {
        assert_eq!(CURVES.map(|(n, _)| n), NAMES);
        let all = all().unwrap();
        assert_eq!(all.len(), 5);
        for (name, c) in NAMES.iter().zip(&all) {
            assert_eq!(c.name.to_ascii_lowercase(), *name);
            assert_eq!(&by_name(name).unwrap().unwrap(), c);
            assert_eq!(&by_name(&name.to_ascii_uppercase()).unwrap().unwrap(), c);
        }
        assert!(by_name("spiral").is_none());
        assert_eq!(butterfly().unwrap(), all[0]);
    }
}
