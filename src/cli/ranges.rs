//! Range-checked number parsers for clap: every numeric option is checked when the command line
//! is parsed, before anything runs, and the error says the allowed range
//! (`invalid value '1.5' for '--subset <SUBSET>': must be in (0, 1]`). NaN and infinities are
//! outside every range.
//!
//! Used as `#[arg(long, value_parser = ranges::real_in(Open(0.0), Closed(1.0)))]` or
//! `value_parser = ranges::int_in(1usize, 1000)`. The parsed type is the bound's type, so it must
//! be the field's type (clap checks that at run time; the tests parse every command's defaults).

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

/// A finite `f64` in the range from `lo` to `hi`.
pub fn real_in(lo: End, hi: End) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s: &str| {
        let range = describe(lo, hi);
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("not a number; must be in {range}"))?;
        if real_ok(v, lo, hi) {
            Ok(v)
        } else {
            Err(format!("must be a finite number in {range}"))
        }
    }
}

/// The same as [`real_in`] for an `f32` option.
pub fn real32_in(lo: End, hi: End) -> impl Fn(&str) -> Result<f32, String> + Clone + Send + Sync {
    let parse = real_in(lo, hi);
    move |s: &str| parse(s).map(|v| v as f32)
}

/// An integer in `[lo, hi]`.
pub fn int_in<T>(lo: T, hi: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync,
{
    move |s: &str| {
        let range = format!("[{lo}, {hi}]");
        let v: T = s
            .trim()
            .parse()
            .map_err(|_| format!("not a whole number; must be in {range}"))?;
        if v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(format!("must be in {range}"))
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
            let e = p(bad).unwrap_err();
            assert!(e.contains("(0, 1]"), "{bad}: {e}");
        }
        assert!(p("abc").unwrap_err().contains("not a number"));
        let q = real_in(Closed(0.0), Unbounded);
        assert_eq!(q("1e300"), Ok(1e300));
        assert!(q("inf").unwrap_err().contains("[0, inf)"));
        assert!(q("-0.1").is_err());
    }

    #[test]
    fn integers_outside_the_range_name_it() {
        let p = int_in(1usize, 1000);
        assert_eq!(p("1"), Ok(1));
        assert_eq!(p("1000"), Ok(1000));
        assert_eq!(p("0").unwrap_err(), "must be in [1, 1000]");
        assert!(p("1001").unwrap_err().contains("[1, 1000]"));
        assert!(p("-3").unwrap_err().contains("not a whole number"));
        assert!(p("2.5").unwrap_err().contains("[1, 1000]"));
    }
}
