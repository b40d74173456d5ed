//! The curve file format: JSON with keys `degree`, `knots`, `weights`,
//! `control_points` and an optional `name` (the format of the benchmark
//! curves in `planner-host/curves/`), parsed into a validated [`Nurbs`].
//! Every error names the offending field as it is spelled in the file.

use std::path::Path;

use serde_json::Value;

use crate::geometry::curve::Nurbs;
use crate::geometry::curve_error::CurveError;

fn json_num(v: &Value, field: impl Fn() -> String) -> Result<f64, CurveError> {
    match v {
        Value::Number(n) => n.as_f64().ok_or_else(|| CurveError::Field {
            field: field(),
            message: format!("{n} is not representable as a 64-bit float"),
        }),
        Value::String(s) => Err(CurveError::Field {
            field: field(),
            message: format!(
                "must be a number, got the string {s:?} (JSON has no NaN or infinity; numbers must be finite)"
            ),
        }),
        other => Err(CurveError::Field {
            field: field(),
            message: format!("must be a number, got {}", kind(other)),
        }),
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn json_array<'a>(
    obj: &'a serde_json::Map<String, Value>,
    key: &'static str,
) -> Result<&'a [Value], CurveError> {
    match obj.get(key) {
        Some(Value::Array(a)) => Ok(a),
        Some(other) => Err(CurveError::Field {
            field: key.into(),
            message: format!("must be an array, got {}", kind(other)),
        }),
        None => Err(CurveError::Field {
            field: key.into(),
            message: "missing (required key)".into(),
        }),
    }
}

fn json_floats(obj: &serde_json::Map<String, Value>, key: &'static str) -> Result<Vec<f64>, CurveError> {
    json_array(obj, key)?
        .iter()
        .enumerate()
        .map(|(i, v)| json_num(v, || format!("{key}[{i}]")))
        .collect()
}

impl Nurbs {
    /// Parse the curve JSON format: keys `degree`, `knots`,
    /// `weights`, `control_points` (`[[x, y, z], …]` in mm, Cartesian;
    /// `[x, y]` gets z = 0) and optional `name`; other keys are ignored.
    /// The curve is validated.
    pub fn from_json_str(text: &str) -> Result<Nurbs, CurveError> {
        let mut c = Self::parse(text, "<string>")?;
        if c.name.is_empty() {
            c.name = "curve".into();
        }
        Ok(c)
    }

    /// Read and parse a curve file (see [`Nurbs::from_json_str`]); errors
    /// carry the path. Without a `name` key the file stem is the name.
    pub fn load(path: &Path) -> Result<Nurbs, CurveError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| CurveError::Io {
            path: shown.clone(),
            source,
        })?;
        let mut c = Self::parse(&text, &shown).map_err(|e| match e {
            e @ CurveError::Json { .. } => e,
            e => CurveError::InFile {
                path: shown.clone(),
                source: Box::new(e),
            },
        })?;
        if c.name.is_empty() {
            c.name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
        }
        Ok(c)
    }

    fn parse(text: &str, path: &str) -> Result<Nurbs, CurveError> {
        let v: Value = serde_json::from_str(text).map_err(|source| CurveError::Json {
            path: path.to_string(),
            source,
        })?;
        let Value::Object(obj) = &v else {
            return Err(CurveError::Field {
                field: "(top level)".into(),
                message: format!("must be an object, got {}", kind(&v)),
            });
        };
        let name = match obj.get("name") {
            None | Some(Value::Null) => String::new(),
            Some(Value::String(s)) => s.clone(),
            Some(other) => {
                return Err(CurveError::Field {
                    field: "name".into(),
                    message: format!("must be a string, got {}", kind(other)),
                })
            }
        };
        let degree = match obj.get("degree") {
            None => {
                return Err(CurveError::Field {
                    field: "degree".into(),
                    message: "missing (required key)".into(),
                })
            }
            // an integral float such as 3.0 is accepted too
            Some(d) => match d.as_u64().or_else(|| {
                d.as_f64()
                    .filter(|x| x.fract() == 0.0 && *x >= 0.0)
                    .map(|x| x as u64)
            }) {
                Some(d) => usize::try_from(d).unwrap_or(usize::MAX),
                None => {
                    return Err(CurveError::Field {
                        field: "degree".into(),
                        message: format!("must be an integer from 2 to 5, got {d}"),
                    })
                }
            },
        };
        let knots = json_floats(obj, "knots")?;
        let weights = json_floats(obj, "weights")?;
        let raw = json_array(obj, "control_points")?;
        let mut points = Vec::with_capacity(raw.len());
        for (i, p) in raw.iter().enumerate() {
            let Value::Array(xyz) = p else {
                return Err(CurveError::Field {
                    field: format!("control_points[{i}]"),
                    message: format!("must be an array [x, y, z] (mm), got {}", kind(p)),
                });
            };
            if !(2..=3).contains(&xyz.len()) {
                return Err(CurveError::Field {
                    field: format!("control_points[{i}]"),
                    message: format!("must be [x, y] or [x, y, z] (mm), got {} numbers", xyz.len()),
                });
            }
            let mut q = [0.0; 3];
            for (j, c) in xyz.iter().enumerate() {
                q[j] = json_num(c, || format!("control_points[{i}][{j}]"))?;
            }
            points.push(q);
        }
        let c = Nurbs {
            name,
            degree,
            knots,
            weights,
            points,
        };
        c.validate()?;
        Ok(c)
    }
}
