//! The mechanics shared by the JSON files the steps hand each other (`calibration.json`,
//! `report.json`, `sim/truth.json`): read the version first, then the typed record, write by
//! atomic rename; every error names the file. Each format's owner module holds its serde type,
//! its file name and its version, and calls these; a reader never opens such a file as untyped
//! JSON.
//!
//! A file without `format_version` was written before versions were recorded: it is read as
//! version 1. A file of another version is refused with both versions named, before its fields
//! are looked at, so a reader never misreads a newer file.
//!
//! JSON has no NaN or infinity, and serde_json writes a non-finite number as `null` (an
//! undefined error, a setting without a cap); reading it back into a number would fail, so the
//! reader takes `null` where a number is expected as NaN ([`NullAsNan`]). An `Option` field
//! still reads `null` as `None`.

use serde::Serialize;
use serde::de::value::{MapAccessDeserializer, MapDeserializer, SeqDeserializer};
use serde::de::{DeserializeOwned, Deserializer, IntoDeserializer, Visitor};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Why a versioned file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a valid {what}: {message}")]
    Parse {
        path: PathBuf,
        what: &'static str,
        message: String,
    },
    #[error(
        "{path}: {what} format_version {found}, but this brdf-rig reads version {supported} \
         ({remedy})"
    )]
    Version {
        path: PathBuf,
        what: &'static str,
        found: u64,
        supported: u32,
        remedy: &'static str,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl FormatError {
    /// True when the file does not exist (a reader may treat that as "not made yet").
    pub fn is_not_found(&self) -> bool {
        matches!(self, FormatError::Read { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

/// What a versioned file is, for its reader: its name in messages, its version, and what to do
/// about a file of another version.
#[derive(Clone, Copy, Debug)]
pub struct Versioned {
    /// e.g. "calibration file (calibration.json)".
    pub what: &'static str,
    pub version: u32,
    /// e.g. "re-run `brdf-rig calibrate` on the session".
    pub remedy: &'static str,
}

/// The version a file without `format_version` has.
pub const fn version_1() -> u32 {
    1
}

impl Versioned {
    /// Reads `path` as this format: the version first, then the typed record.
    pub fn read<T: DeserializeOwned>(&self, path: &Path) -> Result<T, FormatError> {
        let bytes = std::fs::read(path).map_err(|source| FormatError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        self.parse(&bytes, path)
    }

    /// Parses bytes as this format; `path` names them in errors.
    pub fn parse<T: DeserializeOwned>(&self, bytes: &[u8], path: &Path) -> Result<T, FormatError> {
        let parse_err = |message: String| FormatError::Parse {
            path: path.to_path_buf(),
            what: self.what,
            message,
        };
        let value: serde_json::Value =
            serde_json::from_slice(bytes).map_err(|e| parse_err(e.to_string()))?;
        let found = match value.get("format_version") {
            None => u64::from(version_1()),
            Some(x) => x
                .as_u64()
                .ok_or_else(|| parse_err(format!("format_version {x} is not a version number")))?,
        };
        if found != u64::from(self.version) {
            return Err(FormatError::Version {
                path: path.to_path_buf(),
                what: self.what,
                found,
                supported: self.version,
                remedy: self.remedy,
            });
        }
        serde_path_to_error::deserialize(NullAsNan(&value)).map_err(|e| {
            let field = e.path().to_string();
            parse_err(if field == "." {
                e.inner().to_string()
            } else {
                format!("`{field}`: {}", e.inner())
            })
        })
    }

    /// Writes `value` to `path` as pretty JSON, atomically.
    pub fn write<T: Serialize>(&self, path: &Path, value: &T) -> Result<(), FormatError> {
        let write_err = |source: std::io::Error| FormatError::Write {
            path: path.to_path_buf(),
            source,
        };
        let json = serde_json::to_vec_pretty(value).map_err(|e| write_err(e.into()))?;
        crate::atomic::write_atomic(path, &json).map_err(write_err)
    }
}

/// A parsed JSON value read into a typed record as `serde_json` would, except that `null` where
/// a number is expected reads as NaN (see the module header).
struct NullAsNan<'a>(&'a Value);

impl<'de> IntoDeserializer<'de, serde_json::Error> for NullAsNan<'de> {
    type Deserializer = Self;
    fn into_deserializer(self) -> Self {
        self
    }
}

impl<'de> Deserializer<'de> for NullAsNan<'de> {
    type Error = serde_json::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_unit(),
            Value::Bool(b) => visitor.visit_bool(*b),
            Value::Number(n) => {
                if let Some(u) = n.as_u64() {
                    visitor.visit_u64(u)
                } else if let Some(i) = n.as_i64() {
                    visitor.visit_i64(i)
                } else {
                    visitor.visit_f64(n.as_f64().unwrap_or(f64::NAN))
                }
            }
            Value::String(s) => visitor.visit_borrowed_str(s),
            Value::Array(a) => {
                let mut seq = SeqDeserializer::new(a.iter().map(NullAsNan));
                let v = visitor.visit_seq(&mut seq)?;
                seq.end()?;
                Ok(v)
            }
            Value::Object(o) => {
                let mut map = MapDeserializer::new(o.iter().map(|(k, v)| (Key(k), NullAsNan(v))));
                let v = visitor.visit_map(&mut map)?;
                map.end()?;
                Ok(v)
            }
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_f64(f64::NAN),
            _ => self.deserialize_any(visitor),
        }
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        self.deserialize_f64(visitor)
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            _ => visitor.visit_some(self),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        match self.0 {
            // a unit variant
            Value::String(s) => visitor.visit_enum(s.as_str().into_deserializer()),
            // {"variant": content}
            Value::Object(o) => visitor.visit_enum(MapAccessDeserializer::new(
                MapDeserializer::new(o.iter().map(|(k, v)| (Key(k), NullAsNan(v)))),
            )),
            other => Err(serde::de::Error::invalid_type(
                serde::de::Unexpected::Other(match other {
                    Value::Null => "null",
                    Value::Bool(_) => "a boolean",
                    Value::Number(_) => "a number",
                    _ => "an array",
                }),
                &"an enum variant",
            )),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit
        unit_struct seq tuple tuple_struct map struct identifier ignored_any
    }
}

/// A JSON object's key: a string that a map with number (or boolean) keys reads as one, as
/// `serde_json` itself does.
struct Key<'a>(&'a str);

impl<'de> IntoDeserializer<'de, serde_json::Error> for Key<'de> {
    type Deserializer = Self;
    fn into_deserializer(self) -> Self {
        self
    }
}

/// `deserialize_$t` that parses the key as a `$t`.
macro_rules! parsed_key {
    ($($method:ident => $t:ty, $visit:ident;)*) => {$(
        fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
            match self.0.parse::<$t>() {
                Ok(x) => visitor.$visit(x),
                Err(_) => Err(serde::de::Error::invalid_value(
                    serde::de::Unexpected::Str(self.0),
                    &stringify!($t),
                )),
            }
        }
    )*};
}

impl<'de> Deserializer<'de> for Key<'de> {
    type Error = serde_json::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        visitor.visit_borrowed_str(self.0)
    }

    parsed_key! {
        deserialize_bool => bool, visit_bool;
        deserialize_i8 => i8, visit_i8;
        deserialize_i16 => i16, visit_i16;
        deserialize_i32 => i32, visit_i32;
        deserialize_i64 => i64, visit_i64;
        deserialize_i128 => i128, visit_i128;
        deserialize_u8 => u8, visit_u8;
        deserialize_u16 => u16, visit_u16;
        deserialize_u32 => u32, visit_u32;
        deserialize_u64 => u64, visit_u64;
        deserialize_u128 => u128, visit_u128;
        deserialize_f32 => f32, visit_f32;
        deserialize_f64 => f64, visit_f64;
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        visitor.visit_some(self)
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        visitor.visit_enum(self.0.into_deserializer())
    }

    serde::forward_to_deserialize_any! {
        char str string bytes byte_buf unit unit_struct seq tuple tuple_struct map struct
        identifier ignored_any
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Rec {
        #[serde(default = "version_1")]
        format_version: u32,
        items: Vec<f64>,
    }

    const FMT: Versioned = Versioned {
        what: "test file (t.json)",
        version: 1,
        remedy: "make it again",
    };

    #[test]
    fn versions_are_checked_before_fields_and_errors_name_file_and_field() {
        let p = Path::new("/x/t.json");
        let r: Rec = FMT.parse(br#"{"items": [1.0]}"#, p).unwrap();
        assert_eq!(r.format_version, 1, "a file without a version is version 1");
        let e = FMT
            .parse::<Rec>(br#"{"format_version": 2, "other": 1}"#, p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/x/t.json") && e.contains("format_version 2") && e.contains("version 1"),
            "{e}"
        );
        let e = FMT
            .parse::<Rec>(br#"{"items": [1.0, "a"]}"#, p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("/x/t.json") && e.contains("`items[1]`"), "{e}");
        let e = FMT.parse::<Rec>(b"{ not json", p).unwrap_err().to_string();
        assert!(e.contains("not a valid test file"), "{e}");
    }

    #[test]
    fn non_finite_numbers_read_back_as_nan_and_options_as_none() {
        #[derive(Debug, serde::Serialize, serde::Deserialize)]
        struct Nums {
            x: f64,
            xs: [f32; 2],
            maybe: Option<f64>,
            kind: Kind,
            by_view: std::collections::BTreeMap<u32, f64>,
        }
        #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(rename_all = "kebab-case")]
        enum Kind {
            Plain,
            Scaled(f64),
            Spread { by: f64 },
        }
        let p = Path::new("/x/n.json");
        for kind in [
            Kind::Plain,
            Kind::Scaled(f64::NAN),
            Kind::Spread { by: 2.0 },
        ] {
            let json = serde_json::to_vec(&Nums {
                x: f64::NAN,
                xs: [f32::INFINITY, 1.5],
                maybe: None,
                kind,
                by_view: [(3, 1.0), (12, f64::NAN)].into(),
            })
            .unwrap();
            // what serde_json makes of them: null
            assert!(String::from_utf8_lossy(&json).contains("\"x\":null"));
            let n: Nums = FMT.parse(&json, p).unwrap();
            assert!(n.x.is_nan() && n.xs[0].is_nan() && n.xs[1] == 1.5);
            assert_eq!(n.maybe, None);
            assert_eq!(n.by_view[&3], 1.0);
            assert!(n.by_view[&12].is_nan());
            match n.kind {
                Kind::Scaled(s) => assert!(s.is_nan()),
                k => assert!(matches!(k, Kind::Plain | Kind::Spread { by: 2.0 }), "{k:?}"),
            }
        }
        let e = FMT
            .parse::<Nums>(
                br#"{"x": 1, "xs": [1, 2], "maybe": 3, "kind": 7, "by_view": {}}"#,
                p,
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("`kind`"), "{e}");
        let e = FMT
            .parse::<Nums>(
                br#"{"x": 1, "xs": [1, 2], "maybe": 3, "kind": "plain", "by_view": {"a": 1}}"#,
                p,
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("by_view") && e.contains("\"a\""), "{e}");
    }

    #[test]
    fn write_then_read() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.json");
        let r = Rec {
            format_version: 1,
            items: vec![0.5, 2.0],
        };
        FMT.write(&p, &r).unwrap();
        assert_eq!(FMT.read::<Rec>(&p).unwrap(), r);
        assert!(
            FMT.read::<Rec>(&dir.path().join("no.json"))
                .unwrap_err()
                .is_not_found()
        );
    }
}
