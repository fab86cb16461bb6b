//! Range checks for numbers a user gives: every numeric command-line option is checked when the
//! command line is parsed, before anything runs, and the error says the allowed range
//! (`invalid value '1.5' for '--subset <SUBSET>': must be in (0, 1]`). NaN and infinities are
//! outside every range. The lab page's requests (`serve`) are checked with the same ranges
//! ([`check_real`], [`check_int`]), so a browser cannot ask for what the command line refuses.
//!
//! Used as `#[arg(long, value_parser = ranges::real_in(Open(0.0), Closed(1.0)))]` or
//! `value_parser = ranges::int_in(1usize, 1000)`. The parsed type is the bound's type, so it must
//! be the field's type (clap checks that at run time; the tests parse every command's defaults).
//! Pure: no I/O.

use std::fmt::Display;
use std::str::FromStr;

/// One end of a range of real numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum End {
    /// The bound itself is allowed.
    Closed(f64),
    /// The bound itself is not allowed.
    Open(f64),
    /// No bound (the number must still be finite).
    Unbounded,
}

pub use End::{Closed, Open, Unbounded};

/// A number outside its range, or not a number. `range` is written as [`describe`] writes it;
/// `what` names the field or option, `value` is the number as given.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RangeError {
    #[error("{what} = {value}: must be a finite number in {range}")]
    Real {
        what: String,
        value: String,
        range: String,
    },
    #[error("{what} = {value}: must be in {range}")]
    Int {
        what: String,
        value: String,
        range: String,
    },
    /// A command-line value that does not parse as a number (clap names the option).
    #[error("not a number; must be in {range}")]
    NotANumber { range: String },
    #[error("not a whole number; must be in {range}")]
    NotAWholeNumber { range: String },
    /// A command-line real outside its range (clap names the option and the value).
    #[error("must be a finite number in {range}")]
    RealOutside { range: String },
    /// A command-line integer outside its range.
    #[error("must be in {range}")]
    IntOutside { range: String },
}

/// `[a, b]`, `(a, b]`, `[a, inf)`, ... as a reader of a math text expects.
fn describe(lo: End, hi: End) -> String {
    let left = match lo {
        Closed(v) => format!("[{v}"),
        Open(v) => format!("({v}"),
        Unbounded => "(-inf".to_string(),
    };
    let right = match hi {
        Closed(v) => format!("{v}]"),
        Open(v) => format!("{v})"),
        Unbounded => "inf)".to_string(),
    };
    format!("{left}, {right}")
}

fn real_ok(v: f64, lo: End, hi: End) -> bool {
    let above = match lo {
        Closed(b) => v >= b,
        Open(b) => v > b,
        Unbounded => true,
    };
    let below = match hi {
        Closed(b) => v <= b,
        Open(b) => v < b,
        Unbounded => true,
    };
    v.is_finite() && above && below
}

/// `value` itself when it is finite and in the range from `lo` to `hi`; otherwise an error that
/// names `what` and the range.
pub fn check_real(what: &str, value: f64, lo: End, hi: End) -> Result<f64, RangeError> {
    if real_ok(value, lo, hi) {
        Ok(value)
    } else {
        Err(RangeError::Real {
            what: what.to_string(),
            value: value.to_string(),
            range: describe(lo, hi),
        })
    }
}

/// `value` itself when it is in `[lo, hi]`; otherwise an error that names `what` and the range.
pub fn check_int<T>(what: &str, value: T, lo: T, hi: T) -> Result<T, RangeError>
where
    T: PartialOrd + Display + Copy,
{
    if value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(RangeError::Int {
            what: what.to_string(),
            value: value.to_string(),
            range: format!("[{lo}, {hi}]"),
        })
    }
}

/// A finite `f64` in the range from `lo` to `hi`.
pub fn real_in(lo: End, hi: End) -> impl Fn(&str) -> Result<f64, RangeError> + Clone + Send + Sync {
    move |s: &str| {
        let range = describe(lo, hi);
        let Ok(v) = s.trim().parse::<f64>() else {
            return Err(RangeError::NotANumber { range });
        };
        if real_ok(v, lo, hi) {
            Ok(v)
        } else {
            Err(RangeError::RealOutside { range })
        }
    }
}

/// The same as [`real_in`] for an `f32` option.
pub fn real32_in(
    lo: End,
    hi: End,
) -> impl Fn(&str) -> Result<f32, RangeError> + Clone + Send + Sync {
    let parse = real_in(lo, hi);
    move |s: &str| parse(s).map(|v| v as f32)
}

/// An integer in `[lo, hi]`.
pub fn int_in<T>(lo: T, hi: T) -> impl Fn(&str) -> Result<T, RangeError> + Clone + Send + Sync
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync,
{
    move |s: &str| {
        let range = format!("[{lo}, {hi}]");
        let Ok(v) = s.trim().parse::<T>() else {
            return Err(RangeError::NotAWholeNumber { range });
        };
        if v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(RangeError::IntOutside { range })
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn reals_outside_the_range_name_it() {
        let p = real_in(Open(0.0), Closed(1.0));
        assert_eq!(p("0.5"), Ok(0.5));
        assert_eq!(p("1"), Ok(1.0));
        for bad in ["0", "1.5", "-1", "nan", "NaN", "inf", "-inf"] {
            let e = p(bad).unwrap_err().to_string();
            assert!(e.contains("(0, 1]"), "{bad}: {e}");
        }
        assert!(p("abc").unwrap_err().to_string().contains("not a number"));
        let q = real_in(Closed(0.0), Unbounded);
        assert_eq!(q("1e300"), Ok(1e300));
        assert!(q("inf").unwrap_err().to_string().contains("[0, inf)"));
        assert!(q("-0.1").is_err());
    }

    #[test]
    fn integers_outside_the_range_name_it() {
        let p = int_in(1usize, 1000);
        assert_eq!(p("1"), Ok(1));
        assert_eq!(p("1000"), Ok(1000));
        assert_eq!(p("0").unwrap_err().to_string(), "must be in [1, 1000]");
        assert!(p("1001").unwrap_err().to_string().contains("[1, 1000]"));
        assert!(
            p("-3")
                .unwrap_err()
                .to_string()
                .contains("not a whole number")
        );
        assert!(p("2.5").unwrap_err().to_string().contains("[1, 1000]"));
    }

    #[test]
    fn values_are_checked_against_the_same_ranges() {
        assert_eq!(check_real("level", 0.5, Open(0.0), Closed(1.0)), Ok(0.5));
        for bad in [0.0, 1.5, f64::NAN, f64::INFINITY] {
            let e = check_real("level", bad, Open(0.0), Closed(1.0))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("level = ") && e.contains("(0, 1]"), "{e}");
        }
        assert_eq!(check_int("channel", 2usize, 0, 2), Ok(2));
        assert_eq!(
            check_int("channel", 3usize, 0, 2).unwrap_err().to_string(),
            "channel = 3: must be in [0, 2]"
        );
    }
}
