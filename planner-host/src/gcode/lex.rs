//! Lines to blocks: comments, block delete, case and spaces, then the words
//! and parameter assignments of a block, with their values read.
//!
//! Written by hand rather than with the `gcode` crate: that crate keeps
//! word values as `f32` (about 7 significant digits, 6e-5 mm at 1 m) and
//! does not read parameters or bracketed expressions, while in RS274/NGC
//! every word's value may be `#<name>` or `[…]` — a pre-pass to substitute
//! them would itself have to lex the whole line. LinuxCNC's own reader
//! (`interp_read.cc`) is a small hand-written scanner too, and this one
//! follows it:
//!
//! - outside comments, case and spaces do not matter: `g1 x 1 . 5` is
//!   `G1 X1.5`;
//! - `( … )` is a comment (no nesting, closed on its line), `;` comments to
//!   the end of the line;
//! - `/` first on a line marks a block-delete line (skipped only when the
//!   block-delete switch is on; rs274's default is off);
//! - `%` alone on the first line opens the program and a later `%` line
//!   ends it;
//! - `N` may only come first;
//! - `#…=value` assigns a parameter; every value on a line is read with the
//!   parameters as they were before the line, and the assignments take
//!   effect after it (LinuxCNC's documented order).

use super::error::{not_text, syntax, unsupported, GcodeError};
use super::expr::{read_param_key, read_value, Cursor};
use super::params::{ParamKey, Params};

/// A source line with its comments removed, lower case, without spaces.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CleanLine {
    /// Source line (1-based).
    pub line: usize,
    /// The line starts with `/`.
    pub block_delete: bool,
    /// The line is a `%` line.
    pub percent: bool,
    /// The text to read.
    pub text: String,
    /// The comments' text, as written.
    pub comments: Vec<String>,
}

/// One word: a letter and its value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Word {
    /// Lower-case letter.
    pub letter: u8,
    /// The value.
    pub value: f64,
}

/// A read block: its words and parameter assignments.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Block {
    /// Source line.
    pub line: usize,
    /// The `N` word.
    pub n: Option<f64>,
    /// The words in order.
    pub words: Vec<Word>,
    /// Parameter assignments, applied after the block is read.
    pub assignments: Vec<(ParamKey, f64)>,
}

/// The program's text, or [`GcodeError::NotText`] at the first NUL byte or
/// invalid UTF-8 sequence.
pub fn text_of(bytes: &[u8]) -> Result<&str, GcodeError> {
    let line_at = |k: usize| bytes[..k].iter().filter(|&&b| b == b'\n').count() + 1;
    if let Some(k) = bytes.iter().position(|&b| b == 0) {
        return Err(not_text(line_at(k), "\\x00", "a NUL byte: the file is not text"));
    }
    std::str::from_utf8(bytes).map_err(|e| {
        let k = e.valid_up_to();
        let bad: String = bytes[k..]
            .iter()
            .take(e.error_len().unwrap_or(1).max(1))
            .map(|b| format!("\\x{b:02x}"))
            .collect();
        not_text(line_at(k), bad, "bytes that are not UTF-8: the file is not text")
    })
}

/// Remove comments, spaces and case from one source line.
pub(crate) fn clean(raw: &str, line: usize) -> Result<CleanLine, GcodeError> {
    let raw = raw.strip_suffix('\r').unwrap_or(raw);
    let mut text = String::with_capacity(raw.len());
    let mut comments = Vec::new();
    let mut chars = raw.chars();
    while let Some(ch) = chars.next() {
        match ch {
            '(' => {
                let mut body = String::new();
                loop {
                    match chars.next() {
                        Some(')') => break,
                        Some('(') => return Err(syntax(line, "(", "nested comment: '(' inside a comment")),
                        Some(c) => body.push(c),
                        None => return Err(syntax(line, "(", "comment not closed on its line")),
                    }
                }
                comments.push(body);
            }
            ';' => {
                comments.push(chars.by_ref().collect());
            }
            ' ' | '\t' => {}
            c if c.is_ascii() && !c.is_ascii_control() => text.push(c.to_ascii_lowercase()),
            c => {
                return Err(syntax(
                    line,
                    c.to_string(),
                    "a character that is not RS274/NGC (outside a comment)",
                ))
            }
        }
    }
    let block_delete = text.starts_with('/');
    if block_delete {
        text.remove(0);
    }
    let percent = text == "%";
    Ok(CleanLine {
        line,
        block_delete,
        percent,
        text,
        comments,
    })
}

/// Read the words and assignments of a cleaned line.
pub(crate) fn read_block(cl: &CleanLine, params: &Params) -> Result<Block, GcodeError> {
    let mut c = Cursor {
        s: cl.text.as_bytes(),
        i: 0,
        line: cl.line,
        word: String::new(),
    };
    let mut block = Block {
        line: cl.line,
        n: None,
        words: Vec::new(),
        assignments: Vec::new(),
    };
    while let Some(ch) = c.peek() {
        match ch {
            b'#' => {
                c.word = "#".into();
                let key = read_param_key(&mut c, params)?;
                c.word = key.to_string();
                if c.peek() != Some(b'=') {
                    return Err(c.syntax("a parameter outside a value must be assigned: '#…=value'"));
                }
                c.i += 1;
                let v = read_value(&mut c, params)?;
                block.assignments.push((key, v));
            }
            b'o' => {
                return Err(unsupported(
                    cl.line,
                    "O",
                    "O-word control flow (subroutines, loops, conditions) is not supported",
                ))
            }
            b'a'..=b'z' | b'@' | b'^' => {
                c.i += 1;
                c.word = (ch as char).to_ascii_uppercase().to_string();
                let v = read_value(&mut c, params)?;
                if ch == b'n' {
                    if !block.words.is_empty() || block.n.is_some() || !block.assignments.is_empty() {
                        return Err(c.syntax("the N word must come first on its line"));
                    }
                    block.n = Some(v);
                } else {
                    block.words.push(Word { letter: ch, value: v });
                }
            }
            _ => {
                let shown = String::from_utf8_lossy(&cl.text.as_bytes()[c.i..]).into_owned();
                return Err(syntax(
                    cl.line,
                    (ch as char).to_string(),
                    format!("expected a word (a letter and a value), found '{shown}'"),
                ));
            }
        }
    }
    Ok(block)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comments_case_and_spaces_are_removed() {
        let l = clean("N10 g1 X 1 . 5 (move (x)\r", 3);
        assert!(l.is_err(), "nested comment");
        let l = clean("N10 g1 X 1 . 5 (Move) y2 ; rest", 3).unwrap();
        assert_eq!(l.text, "n10g1x1.5y2");
        assert_eq!(l.comments, vec!["Move".to_string(), " rest".to_string()]);
        let l = clean("/G0 X1", 1).unwrap();
        assert!(l.block_delete);
        assert_eq!(l.text, "g0x1");
        assert!(clean(" % ", 1).unwrap().percent);
        assert!(matches!(
            clean("G1 (open", 7),
            Err(GcodeError::Syntax { line: 7, .. })
        ));
    }

    #[test]
    fn words_and_assignments_are_read_with_the_old_values() {
        let mut p = Params::default();
        p.set(ParamKey::Numbered(1), 2.0);
        let b = read_block(&clean("N5 #1=5 #2=#1 G1 X[#1*2] Y-3", 1).unwrap(), &p).unwrap();
        assert_eq!(b.n, Some(5.0));
        assert_eq!(
            b.assignments,
            vec![(ParamKey::Numbered(1), 5.0), (ParamKey::Numbered(2), 2.0)]
        );
        let w: Vec<(u8, f64)> = b.words.iter().map(|w| (w.letter, w.value)).collect();
        assert_eq!(w, vec![(b'g', 1.0), (b'x', 4.0), (b'y', -3.0)]);
        assert!(read_block(&clean("G1 N5", 1).unwrap(), &p).is_err());
        assert!(read_block(&clean("G1 X", 1).unwrap(), &p).is_err());
        assert!(read_block(&clean("#1", 1).unwrap(), &p).is_err());
    }

    #[test]
    fn not_text_is_refused_with_its_line() {
        assert!(matches!(
            text_of(b"G0 X1\nG1\0"),
            Err(GcodeError::NotText { line: 2, .. })
        ));
        assert!(matches!(
            text_of(b"G0\n\nG1 X\xff"),
            Err(GcodeError::NotText { line: 3, ref word, .. }) if word == "\\xff"
        ));
        assert_eq!(text_of(b"G0 X1").unwrap(), "G0 X1");
    }
}
