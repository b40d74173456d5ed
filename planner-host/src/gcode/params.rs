//! The parameter store: numbered parameters `#1`‥`#5602` and named
//! parameters `#<name>`.
//!
//! As in LinuxCNC: a numbered parameter never set reads 0; a named
//! parameter never set is an error (LinuxCNC: "Named parameter not
//! defined"); names are read without spaces and without case. Parameters
//! are only the values a program computes with: the system parameters that
//! hold offsets (#5161 and up) are refused as assignment targets, since
//! writing them would move the coordinate systems.

use std::collections::HashMap;

/// The highest numbered parameter LinuxCNC keeps (RS274NGC_MAX_PARAMETERS − 1).
pub const MAX_NUMBERED: u32 = 5602;

/// The first system parameter (home positions, offsets, tool data).
pub const FIRST_SYSTEM: u32 = 5000;

/// A parameter reference.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamKey {
    /// `#7`.
    Numbered(u32),
    /// `#<name>` (lower case, no spaces).
    Named(String),
}

impl std::fmt::Display for ParamKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParamKey::Numbered(n) => write!(f, "#{n}"),
            ParamKey::Named(s) => write!(f, "#<{s}>"),
        }
    }
}

/// Numbered and named parameter values.
#[derive(Debug, Clone, Default)]
pub struct Params {
    numbered: HashMap<u32, f64>,
    named: HashMap<String, f64>,
}

impl Params {
    /// The value: a numbered parameter never set is 0, a named one `None`.
    pub fn get(&self, key: &ParamKey) -> Option<f64> {
        match key {
            ParamKey::Numbered(n) => Some(self.numbered.get(n).copied().unwrap_or(0.0)),
            ParamKey::Named(s) => self.named.get(s).copied(),
        }
    }

    /// Whether a named parameter has a value (the EXISTS function);
    /// numbered parameters always exist.
    pub fn exists(&self, key: &ParamKey) -> bool {
        match key {
            ParamKey::Numbered(_) => true,
            ParamKey::Named(s) => self.named.contains_key(s),
        }
    }

    /// Set a value.
    pub fn set(&mut self, key: ParamKey, value: f64) {
        match key {
            ParamKey::Numbered(n) => {
                self.numbered.insert(n, value);
            }
            ParamKey::Named(s) => {
                self.named.insert(s, value);
            }
        }
    }
}
