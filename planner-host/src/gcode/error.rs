//! Why a program is refused: one typed error per kind, each naming the
//! source line (1-based, as an editor counts, not the `N` word) and the word
//! that could not be read or would not be obeyed.
//!
//! Displayed as `LINE 12: word 'G41': cutter compensation is not supported`.

/// A G-code program that cannot be read, or asks for something this reader
/// does not do. Every kind carries the source line and the word.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GcodeError {
    /// The file is not text: a NUL byte or bytes that are not UTF-8.
    #[error("LINE {line}: word '{word}': {why}")]
    NotText {
        /// Source line.
        line: usize,
        /// The offending bytes, escaped.
        word: String,
        /// Why.
        why: String,
    },
    /// The text cannot be read as RS274/NGC: a bad number, an unclosed
    /// comment, an unknown letter, a word twice on a line, a word with no
    /// G-code that uses it.
    #[error("LINE {line}: word '{word}': {why}")]
    Syntax {
        /// Source line.
        line: usize,
        /// The word.
        word: String,
        /// Why.
        why: String,
    },
    /// A valid RS274/NGC word this reader refuses because it would move the
    /// machine or change the geometry in a way not modelled (cutter
    /// compensation, offsets, canned cycles, control flow, rotary axes…).
    #[error("LINE {line}: word '{word}': {why}")]
    Unsupported {
        /// Source line.
        line: usize,
        /// The word.
        word: String,
        /// Why.
        why: String,
    },
    /// An expression or parameter that has no value: division by zero, a
    /// function outside its domain, an undefined named parameter.
    #[error("LINE {line}: word '{word}': {why}")]
    Expression {
        /// Source line.
        line: usize,
        /// The word whose value was being read.
        word: String,
        /// Why.
        why: String,
    },
    /// An arc LinuxCNC refuses: start and end radii disagree beyond its
    /// tolerance, a zero radius, an R too small to reach the end point.
    #[error("LINE {line}: word '{word}': {why}")]
    Arc {
        /// Source line.
        line: usize,
        /// The word.
        word: String,
        /// Why.
        why: String,
    },
    /// A G5.2 or G6.2 NURBS that is not a curve: a wrong number of knots,
    /// a non-positive weight, fewer control points than the order.
    #[error("LINE {line}: word '{word}': {why}")]
    Nurbs {
        /// Source line.
        line: usize,
        /// The word.
        word: String,
        /// Why.
        why: String,
    },
    /// A feed move with no feed rate (F0, or no F yet).
    #[error("LINE {line}: word '{word}': {why}")]
    Feed {
        /// Source line.
        line: usize,
        /// The word.
        word: String,
        /// Why.
        why: String,
    },
}

impl GcodeError {
    /// The source line (1-based).
    pub fn line(&self) -> usize {
        match self {
            GcodeError::NotText { line, .. }
            | GcodeError::Syntax { line, .. }
            | GcodeError::Unsupported { line, .. }
            | GcodeError::Expression { line, .. }
            | GcodeError::Arc { line, .. }
            | GcodeError::Nurbs { line, .. }
            | GcodeError::Feed { line, .. } => *line,
        }
    }

    /// The word the error is about.
    pub fn word(&self) -> &str {
        match self {
            GcodeError::NotText { word, .. }
            | GcodeError::Syntax { word, .. }
            | GcodeError::Unsupported { word, .. }
            | GcodeError::Expression { word, .. }
            | GcodeError::Arc { word, .. }
            | GcodeError::Nurbs { word, .. }
            | GcodeError::Feed { word, .. } => word,
        }
    }
}

/// Shorthands for the interpreter and the readers: `syntax(line, word, why)`.
macro_rules! ctor {
    ($name:ident, $variant:ident) => {
        pub(crate) fn $name(line: usize, word: impl Into<String>, why: impl Into<String>) -> GcodeError {
            GcodeError::$variant {
                line,
                word: word.into(),
                why: why.into(),
            }
        }
    };
}
ctor!(syntax, Syntax);
ctor!(unsupported, Unsupported);
ctor!(expression, Expression);
ctor!(arc, Arc);
ctor!(nurbs, Nurbs);
ctor!(feed, Feed);
ctor!(not_text, NotText);
