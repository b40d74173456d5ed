//! Values: numbers, parameters, bracketed expressions and functions, read
//! from a cleaned line (lower case, no spaces, no comments) the way
//! LinuxCNC's `read_real_value` reads them (`interp_read.cc`).
//!
//! - A number: an optional sign, digits and one decimal point, no exponent.
//! - `#7`, `##7`, `#[2+5]`, `#<name>`: a parameter's value as it was before
//!   the line (assignments on a line take effect after the line is read).
//! - `[a + b * c]`: the binary operators with LinuxCNC's precedence, all
//!   left-associative: `**` above `* / MOD` above `+ -` above
//!   `EQ NE GT GE LT LE` above `AND OR XOR`. MOD's result has the sign of
//!   the divisor's magnitude (LinuxCNC adds |b| to a negative fmod).
//! - `-v`, `+v` before a non-number value.
//! - Functions with a bracketed argument, angles in degrees: ABS ACOS ASIN
//!   COS EXP FIX (floor) FUP (ceiling) ROUND (half away from zero) LN SIN
//!   SQRT TAN, `ATAN[y]/[x]` (atan2, degrees), `EXISTS[#<name>]`.
//!
//! A value that is NaN or infinite is an error, as in LinuxCNC.

use super::error::{expression, syntax, GcodeError};
use super::params::{ParamKey, Params, MAX_NUMBERED};

/// A position in a cleaned line, with the line number and the word being
/// read (for errors).
pub(crate) struct Cursor<'a> {
    /// The cleaned line.
    pub s: &'a [u8],
    /// Position in `s`.
    pub i: usize,
    /// Source line.
    pub line: usize,
    /// The word whose value is being read.
    pub word: String,
}

impl Cursor<'_> {
    pub(crate) fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    fn peek_at(&self, k: usize) -> Option<u8> {
        self.s.get(self.i + k).copied()
    }

    fn starts_with(&self, t: &str) -> bool {
        self.s[self.i..].starts_with(t.as_bytes())
    }

    pub(crate) fn syntax(&self, why: impl Into<String>) -> GcodeError {
        syntax(self.line, self.word.clone(), why)
    }

    fn expression(&self, why: impl Into<String>) -> GcodeError {
        expression(self.line, self.word.clone(), why)
    }

    fn expect(&mut self, c: u8) -> Result<(), GcodeError> {
        if self.peek() == Some(c) {
            self.i += 1;
            Ok(())
        } else {
            Err(self.syntax(format!("expected '{}' in the value", c as char)))
        }
    }
}

/// Binary operators, in LinuxCNC's precedence classes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl Op {
    fn precedence(self) -> u8 {
        match self {
            Op::Pow => 6,
            Op::Mul | Op::Div | Op::Mod => 5,
            Op::Add | Op::Sub => 4,
            Op::Eq | Op::Ne | Op::Gt | Op::Ge | Op::Lt | Op::Le => 3,
            Op::And | Op::Or | Op::Xor => 2,
        }
    }
}

/// Read one value at the cursor.
pub(crate) fn read_value(c: &mut Cursor, p: &Params) -> Result<f64, GcodeError> {
    let Some(ch) = c.peek() else {
        return Err(c.syntax("a value is missing"));
    };
    let next_is_number = c.peek_at(1).is_some_and(|d| d.is_ascii_digit() || d == b'.');
    let v = match ch {
        b'[' => read_expression(c, p)?,
        b'#' => {
            let key = read_param_key(c, p)?;
            p.get(&key)
                .ok_or_else(|| c.expression(format!("named parameter {key} is not defined")))?
        }
        b'+' if !next_is_number && c.peek_at(1).is_some() => {
            c.i += 1;
            read_value(c, p)?
        }
        b'-' if !next_is_number && c.peek_at(1).is_some() => {
            c.i += 1;
            -read_value(c, p)?
        }
        b'a'..=b'z' => read_function(c, p)?,
        _ => read_number(c)?,
    };
    if v.is_nan() {
        return Err(c.expression("the value is not a number"));
    }
    if v.is_infinite() {
        return Err(c.expression("the value is infinite"));
    }
    Ok(v)
}

/// A literal number: sign, digits, one point.
fn read_number(c: &mut Cursor) -> Result<f64, GcodeError> {
    let start = c.i;
    if matches!(c.peek(), Some(b'+' | b'-')) {
        c.i += 1;
    }
    while matches!(c.peek(), Some(b'0'..=b'9' | b'.')) {
        c.i += 1;
    }
    let text = std::str::from_utf8(&c.s[start..c.i]).unwrap_or("");
    let digits = text.trim_start_matches(['+', '-']);
    if digits.is_empty() || digits == "." {
        let at =
            c.s.get(start)
                .map_or("end of line".to_string(), |b| format!("'{}'", *b as char));
        return Err(c.syntax(format!("a number is missing (found {at})")));
    }
    text.parse::<f64>()
        .map_err(|_| c.syntax(format!("bad number format '{text}'")))
}

/// `#` then `<name>` or a value: the parameter referred to.
pub(crate) fn read_param_key(c: &mut Cursor, p: &Params) -> Result<ParamKey, GcodeError> {
    c.expect(b'#')?;
    if c.peek() == Some(b'<') {
        c.i += 1;
        let start = c.i;
        while c.peek().is_some_and(|b| b != b'>') {
            c.i += 1;
        }
        if c.peek() != Some(b'>') {
            return Err(c.syntax("named parameter without its closing '>'"));
        }
        let name = String::from_utf8_lossy(&c.s[start..c.i]).into_owned();
        c.i += 1;
        if name.is_empty() {
            return Err(c.syntax("empty parameter name"));
        }
        return Ok(ParamKey::Named(name));
    }
    let v = read_value(c, p)?;
    let n = v.round();
    if (v - n).abs() > 1e-4 {
        return Err(c.syntax(format!("parameter number {v} is not an integer")));
    }
    if n < 1.0 || n > f64::from(MAX_NUMBERED) {
        return Err(c.syntax(format!("parameter number {n} is out of range 1..{MAX_NUMBERED}")));
    }
    Ok(ParamKey::Numbered(n as u32))
}

/// The operator at the cursor (after a value), or `]`.
fn read_op(c: &mut Cursor) -> Result<Option<Op>, GcodeError> {
    const WORDS: [(&str, Op); 15] = [
        ("**", Op::Pow),
        ("*", Op::Mul),
        ("/", Op::Div),
        ("+", Op::Add),
        ("-", Op::Sub),
        ("mod", Op::Mod),
        ("eq", Op::Eq),
        ("ne", Op::Ne),
        ("gt", Op::Gt),
        ("ge", Op::Ge),
        ("lt", Op::Lt),
        ("le", Op::Le),
        ("and", Op::And),
        ("or", Op::Or),
        ("xor", Op::Xor),
    ];
    if c.peek() == Some(b']') {
        c.i += 1;
        return Ok(None);
    }
    for (t, op) in WORDS {
        if c.starts_with(t) {
            c.i += t.len();
            return Ok(Some(op));
        }
    }
    match c.peek() {
        None => Err(c.syntax("unclosed '[' in the expression")),
        Some(b) => Err(c.syntax(format!("unknown operator at '{}'", b as char))),
    }
}

fn apply(c: &Cursor, op: Op, a: f64, b: f64) -> Result<f64, GcodeError> {
    let truth = |x: bool| if x { 1.0 } else { 0.0 };
    Ok(match op {
        Op::Pow => {
            if a < 0.0 && b.fract() != 0.0 {
                return Err(c.expression(format!("{a} ** {b}: a negative number to a non-integer power")));
            }
            a.powf(b)
        }
        Op::Mul => a * b,
        Op::Div => {
            if b == 0.0 {
                return Err(c.expression("division by zero"));
            }
            a / b
        }
        Op::Mod => {
            if b == 0.0 {
                return Err(c.expression("MOD by zero"));
            }
            let r = a % b;
            if r >= 0.0 {
                r
            } else {
                r + b.abs()
            }
        }
        Op::Add => a + b,
        Op::Sub => a - b,
        Op::Eq => truth(a == b),
        Op::Ne => truth(a != b),
        Op::Gt => truth(a > b),
        Op::Ge => truth(a >= b),
        Op::Lt => truth(a < b),
        Op::Le => truth(a <= b),
        Op::And => truth(a != 0.0 && b != 0.0),
        Op::Or => truth(a != 0.0 || b != 0.0),
        Op::Xor => truth((a != 0.0) != (b != 0.0)),
    })
}

/// `[ value (op value)* ]`, evaluated by precedence, left to right within
/// a precedence class.
fn read_expression(c: &mut Cursor, p: &Params) -> Result<f64, GcodeError> {
    c.expect(b'[')?;
    let mut values = vec![read_value(c, p)?];
    let mut ops: Vec<Op> = Vec::new();
    loop {
        let next = read_op(c)?;
        // reduce while the stacked operator binds at least as tightly
        while let Some(&top) = ops.last() {
            if next.is_some_and(|n| n.precedence() > top.precedence()) {
                break;
            }
            ops.pop();
            let b = values.pop().unwrap_or(0.0);
            let a = values.pop().unwrap_or(0.0);
            values.push(apply(c, top, a, b)?);
        }
        match next {
            None => return Ok(values.pop().unwrap_or(0.0)),
            Some(op) => {
                ops.push(op);
                values.push(read_value(c, p)?);
            }
        }
    }
}

/// A function name then its bracketed argument.
fn read_function(c: &mut Cursor, p: &Params) -> Result<f64, GcodeError> {
    let start = c.i;
    while c.peek().is_some_and(|b| b.is_ascii_lowercase()) {
        c.i += 1;
    }
    let name = String::from_utf8_lossy(&c.s[start..c.i]).into_owned();
    if c.peek() != Some(b'[') {
        return Err(c.syntax(format!("'{name}' is not a value (a function needs '[')")));
    }
    let deg = std::f64::consts::PI / 180.0;
    if name == "exists" {
        c.expect(b'[')?;
        let key = read_param_key(c, p)?;
        c.expect(b']')?;
        return Ok(if p.exists(&key) { 1.0 } else { 0.0 });
    }
    if name == "atan" {
        let y = read_expression(c, p)?;
        c.expect(b'/')?;
        if c.peek() != Some(b'[') {
            return Err(c.syntax("ATAN needs its second argument in brackets: ATAN[y]/[x]"));
        }
        let x = read_expression(c, p)?;
        return Ok(y.atan2(x) / deg);
    }
    let x = read_expression(c, p)?;
    let domain = |ok: bool, what: &str| {
        if ok {
            Ok(())
        } else {
            Err(c.expression(format!("{}[{x}]: argument {what}", name.to_uppercase())))
        }
    };
    Ok(match name.as_str() {
        "abs" => x.abs(),
        "acos" => {
            domain((-1.0..=1.0).contains(&x), "outside -1..1")?;
            x.acos() / deg
        }
        "asin" => {
            domain((-1.0..=1.0).contains(&x), "outside -1..1")?;
            x.asin() / deg
        }
        "cos" => (x * deg).cos(),
        "sin" => (x * deg).sin(),
        "tan" => (x * deg).tan(),
        "exp" => x.exp(),
        "fix" => x.floor(),
        "fup" => x.ceil(),
        "round" => x.round(),
        "ln" => {
            domain(x > 0.0, "not positive")?;
            x.ln()
        }
        "sqrt" => {
            domain(x >= 0.0, "negative")?;
            x.sqrt()
        }
        _ => return Err(c.syntax(format!("unknown function '{}'", name.to_uppercase()))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(s: &str) -> Result<f64, GcodeError> {
        let mut p = Params::default();
        p.set(ParamKey::Numbered(1), 3.0);
        p.set(ParamKey::Named("r".into()), 2.0);
        let mut c = Cursor {
            s: s.as_bytes(),
            i: 0,
            line: 1,
            word: "X".into(),
        };
        let v = read_value(&mut c, &p)?;
        assert_eq!(c.i, s.len(), "all of {s} read");
        Ok(v)
    }

    #[test]
    fn precedence_and_left_association_follow_linuxcnc() {
        assert_eq!(eval("[1+2*3]").unwrap(), 7.0);
        assert_eq!(eval("[2**3**2]").unwrap(), 64.0);
        assert_eq!(eval("[10-4-3]").unwrap(), 3.0);
        assert_eq!(eval("[1+1eq2]").unwrap(), 1.0);
        assert_eq!(eval("[1lt2and3gt4]").unwrap(), 0.0);
        assert_eq!(eval("[1or0xor1]").unwrap(), 0.0);
        assert_eq!(eval("[-7mod3]").unwrap(), 2.0);
        assert_eq!(eval("[7mod3]").unwrap(), 1.0);
        assert_eq!(eval("-[1+2]").unwrap(), -3.0);
        assert_eq!(eval("-.5").unwrap(), -0.5);
        assert_eq!(eval("1.").unwrap(), 1.0);
    }

    #[test]
    fn functions_take_degrees() {
        assert!((eval("sin[30]").unwrap() - 0.5).abs() < 1e-15);
        assert!((eval("cos[60]").unwrap() - 0.5).abs() < 1e-15);
        assert!((eval("atan[1]/[1]").unwrap() - 45.0).abs() < 1e-12);
        assert!((eval("atan[1]/[-1]").unwrap() - 135.0).abs() < 1e-12);
        assert!((eval("acos[0]").unwrap() - 90.0).abs() < 1e-12);
        assert_eq!(eval("fix[-1.5]").unwrap(), -2.0);
        assert_eq!(eval("fup[1.2]").unwrap(), 2.0);
        assert_eq!(eval("round[2.5]").unwrap(), 3.0);
        assert_eq!(eval("round[-2.5]").unwrap(), -3.0);
        assert_eq!(eval("sqrt[16]").unwrap(), 4.0);
        assert!((eval("ln[exp[2]]").unwrap() - 2.0).abs() < 1e-12);
        assert_eq!(eval("abs[-2]").unwrap(), 2.0);
        assert_eq!(eval("exists[#<r>]").unwrap(), 1.0);
        assert_eq!(eval("exists[#<nope>]").unwrap(), 0.0);
    }

    #[test]
    fn parameters_are_read() {
        assert_eq!(eval("#1").unwrap(), 3.0);
        assert_eq!(eval("#2").unwrap(), 0.0);
        assert_eq!(eval("##1").unwrap(), 0.0);
        assert_eq!(eval("#<r>").unwrap(), 2.0);
        assert_eq!(eval("[#1*#<r>]").unwrap(), 6.0);
        assert!(matches!(eval("#<nope>"), Err(GcodeError::Expression { .. })));
    }

    #[test]
    fn bad_values_are_typed_errors() {
        assert!(matches!(eval("[1/0]"), Err(GcodeError::Expression { .. })));
        assert!(matches!(eval("sqrt[-1]"), Err(GcodeError::Expression { .. })));
        assert!(matches!(eval("asin[2]"), Err(GcodeError::Expression { .. })));
        assert!(matches!(eval("[1+2"), Err(GcodeError::Syntax { .. })));
        assert!(matches!(eval("foo[1]"), Err(GcodeError::Syntax { .. })));
        assert!(matches!(eval("."), Err(GcodeError::Syntax { .. })));
    }
}
