//! What the two command-line tools (`feedplan` here, `feedsim` in
//! sim-harness) share, so that they speak alike: the exit codes and their
//! help text, the exit code of a planner error, the curve argument (a file
//! or a built-in name), G-code programs told from curves, the machine
//! options (`--machine`, `--limits`), and writing to a stdout that may close ([`outln!`](crate::outln)).

use std::path::Path;

use crate::geometry::builtin;
use crate::geometry::curve::Nurbs;
use crate::geometry::curve_error::CurveError;
use crate::limits::{self, LimitsError};
use crate::machine::{Machine, MachineError};
use crate::plan::error::PlanError;
use crate::program::plan::ProgramError;

/// Exit code: an I/O or internal error.
pub const EXIT_IO: u8 = 1;
/// Exit code: usage (clap's own, and an option value that does not fit).
pub const EXIT_USAGE: u8 = 2;
/// Exit code: bad input (an unreadable or invalid curve, table, limits file,
/// servo file, CSV or G-code program).
pub const EXIT_INPUT: u8 = 3;
/// Exit code: an infeasible plan (an LP or the plan has no solution).
pub const EXIT_INFEASIBLE: u8 = 4;
/// Exit code: a limit exceeded in a check.
pub const EXIT_LIMIT: u8 = 5;

/// The exit codes, shown after every `--help` of both tools.
pub const EXIT_CODES_HELP: &str = "\
Exit codes:
  0  success
  1  I/O or internal error (e.g. an output file cannot be written)
  2  usage: unknown option, bad option value, or an option that does not fit
  3  bad input: unreadable or invalid curve, table, program file, limits file, machine file,
     servo file, CSV or G-code program (a word it refuses: LINE N: word 'G41': ...; a move
     outside the machine's travel: LINE N: the move leaves the travel ...)
  4  infeasible plan: an LP or the plan has no solution (stall, no room for the end segments,
     the override window LP)
  5  a limit exceeded in a check (feedsim run --check, feedsim check)";

/// The exit code of a planner error: bad input 3, an option that does not
/// fit 2, I/O 1, no solution 4.
pub fn plan_exit_code(e: &PlanError) -> u8 {
    match e {
        PlanError::Curve(_) | PlanError::Limits(_) | PlanError::Corner { .. } | PlanError::FeedProfile(_) => {
            EXIT_INPUT
        }
        PlanError::TooFewPoints { .. } | PlanError::OverrideLevel { .. } | PlanError::Committing => {
            EXIT_USAGE
        }
        PlanError::Io { .. } | PlanError::Table(_) => EXIT_IO,
        PlanError::Level { source, .. } => plan_exit_code(source),
        _ => EXIT_INFEASIBLE,
    }
}

/// The exit code of a program planning error: the planner's for a path that
/// cannot be planned ([`plan_exit_code`]), bad input 3 for the rest.
pub fn program_exit_code(e: &ProgramError) -> u8 {
    match e {
        ProgramError::Plan { source, .. } => plan_exit_code(source),
        ProgramError::File(_) => EXIT_IO,
        _ => EXIT_INPUT,
    }
}

/// Extensions of G-code part programs.
pub const PROGRAM_EXTENSIONS: [&str; 3] = ["ngc", "nc", "tap"];

/// Is this argument a G-code program rather than a JSON curve? By its
/// extension (`.ngc`, `.nc`, `.tap`, any case), else by its content: an
/// existing file whose first non-blank byte is not `{`.
pub fn is_gcode_program(arg: &Path) -> bool {
    if let Some(ext) = arg.extension().and_then(|e| e.to_str()) {
        if PROGRAM_EXTENSIONS.iter().any(|x| x.eq_ignore_ascii_case(ext)) {
            return true;
        }
        if ext.eq_ignore_ascii_case("json") {
            return false;
        }
    }
    match std::fs::read(arg) {
        Ok(b) => b
            .iter()
            .find(|c| !c.is_ascii_whitespace())
            .is_some_and(|&c| c != b'{'),
        Err(_) => false,
    }
}

/// Why the machine options give no machine (exit 3; both options: 2).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MachineArgError {
    /// The machine file cannot be used.
    #[error(transparent)]
    Machine(#[from] MachineError),
    /// The limits file cannot be used.
    #[error(transparent)]
    Limits(#[from] LimitsError),
    /// `--machine` and `--limits` together.
    #[error("--machine and --limits do not go together: the machine file has the limits")]
    Both,
}

impl MachineArgError {
    /// The exit code: 2 for both options, 3 for a bad file.
    pub fn exit_code(&self) -> u8 {
        match self {
            MachineArgError::Both => EXIT_USAGE,
            _ => EXIT_INPUT,
        }
    }
}

/// The machine of `--machine FILE` or `--limits FILE` (the built-in machine
/// with those limits, rapids at their feed limit), else Table 1
/// ([`Machine::table1`]).
pub fn load_machine(machine: Option<&Path>, limits_file: Option<&Path>) -> Result<Machine, MachineArgError> {
    match (machine, limits_file) {
        (Some(_), Some(_)) => Err(MachineArgError::Both),
        (Some(m), None) => Ok(Machine::load(m)?),
        (None, Some(l)) => Ok(Machine::with_limits(limits::load(l)?)),
        (None, None) => Ok(Machine::table1()),
    }
}

/// Why a curve argument gives no curve (both exit 3).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CurveArgError {
    /// Neither a file nor the name of a built-in curve.
    #[error("{0}: no such file, and not a built-in curve ({names})", names = builtin::NAMES.join(", "))]
    Unknown(String),
    /// The file or the built-in curve is not a valid toolpath.
    #[error(transparent)]
    Curve(#[from] CurveError),
}

/// A curve argument: a file if one exists at that path, else the built-in
/// curve of that name (case-insensitive), else [`CurveArgError::Unknown`]
/// for a bare name, or the file's own read error for anything that looks
/// like a path.
pub fn load_curve(arg: &Path) -> Result<Nurbs, CurveArgError> {
    if !arg.exists() {
        if let Some(c) = arg.to_str().and_then(builtin::by_name) {
            return Ok(c?);
        }
        if arg.extension().is_none() && arg.components().count() == 1 {
            return Err(CurveArgError::Unknown(arg.display().to_string()));
        }
    }
    Ok(Nurbs::load(arg)?)
}

/// Where [`outln!`](crate::outln) goes when stdout refuses a write: a closed pipe
/// (`tool … | head`) ends the program quietly with status 0; any other
/// write error is reported and exits [`EXIT_IO`].
pub fn stdout_failed(tool: &str, e: std::io::Error) -> ! {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        std::process::exit(0);
    }
    eprintln!("{tool}: error: cannot write to stdout: {e}");
    std::process::exit(i32::from(EXIT_IO));
}

/// `println!` to stdout without the panic on a closed pipe: see
/// [`cli::stdout_failed`](crate::cli::stdout_failed). Use in a binary (the
/// error names `CARGO_BIN_NAME`).
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            $crate::cli::stdout_failed(env!("CARGO_BIN_NAME"), e)
        }
    }};
}

/// `print!` to stdout without the panic on a closed pipe, as [`outln!`](crate::outln).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = write!(std::io::stdout(), $($arg)*) {
            $crate::cli::stdout_failed(env!("CARGO_BIN_NAME"), e)
        }
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_curve_argument_is_a_file_or_a_built_in_name() {
        assert_eq!(
            load_curve(Path::new("Fan")).unwrap(),
            builtin::by_name("fan").unwrap().unwrap()
        );
        assert!(matches!(load_curve(Path::new("spiral")), Err(CurveArgError::Unknown(n)) if n == "spiral"));
        assert!(matches!(
            load_curve(Path::new("no/such/file.json")),
            Err(CurveArgError::Curve(_))
        ));
    }

    #[test]
    fn programs_are_told_from_curves_by_extension_or_content() {
        assert!(is_gcode_program(Path::new("part.NGC")));
        assert!(is_gcode_program(Path::new("part.tap")));
        assert!(!is_gcode_program(Path::new("curve.json")));
        assert!(!is_gcode_program(Path::new("fan")));
        let dir = std::env::temp_dir().join(format!("feedlp-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (g, j) = (dir.join("part"), dir.join("curve"));
        std::fs::write(&g, "G0 X1\n").unwrap();
        std::fs::write(&j, " {\"degree\": 2}").unwrap();
        assert!(is_gcode_program(&g));
        assert!(!is_gcode_program(&j));
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(matches!(
            load_machine(Some(Path::new("a.toml")), Some(Path::new("b.json"))),
            Err(MachineArgError::Both)
        ));
        assert_eq!(load_machine(None, None).unwrap(), Machine::table1());
    }

    #[test]
    fn planner_errors_map_to_the_documented_exit_codes() {
        let bad_input = PlanError::Curve(CurveError::Degree { degree: 9 });
        assert_eq!(plan_exit_code(&bad_input), EXIT_INPUT);
        let nested = PlanError::Level {
            percent: 50.0,
            source: Box::new(bad_input),
        };
        assert_eq!(plan_exit_code(&nested), EXIT_INPUT);
        assert!(EXIT_CODES_HELP.lines().count() >= 7);
    }
}
