//! A value and where the spec file wrote it.
//!
//! A located value is asked for the way serde-saphyr's own `Spanned` asks:
//! a newtype named `__yaml_spanned`, answered with a map of the value and
//! its two places. The tree YAML is read from (`yaml::tree`, the
//! workspace's one reader) answers it; so does serde-saphyr, which this
//! crate's tests use as an oracle (the tools only write YAML with it).
//! Unlike serde-saphyr's `Spanned`, this one does not also accept a value
//! buffered by serde (`flatten`, `untagged`), which would compile `T`'s
//! deserializer once more for every primitive; the document types put no
//! located value there.

use std::fmt;
use std::marker::PhantomData;

use serde::Deserialize;
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, Visitor};

use crate::diag::Pos;

/// A value, where it is used (`referenced`: an alias's place) and where it
/// is written (`defined`); both [`Pos::default`] (line 0) for a value made
/// in code.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Spanned<T> {
    /// The value.
    pub value: T,
    /// Where the value is used: the alias, or the value itself.
    pub referenced: Pos,
    /// Where the value is written.
    pub defined: Pos,
}

impl<T> Spanned<T> {
    /// A value at the given places.
    #[must_use]
    pub const fn new(value: T, referenced: Pos, defined: Pos) -> Self {
        Self { value, referenced, defined }
    }

    /// A value made in code, written nowhere.
    #[must_use]
    pub const fn unplaced(value: T) -> Self {
        Self { value, referenced: Pos { line: 0, column: 0 }, defined: Pos { line: 0, column: 0 } }
    }
}

/// The newtype name by which a deserializer recognises a request for a
/// location (serde-saphyr's own `Spanned` uses it).
pub(crate) const SPANNED_REQUEST: &str = "__yaml_spanned";

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Spanned<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_newtype_struct(SPANNED_REQUEST, Request(PhantomData))
    }
}

/// Answered with a deserializer of the located value.
struct Request<T>(PhantomData<T>);

impl<'de, T: Deserialize<'de>> Visitor<'de> for Request<T> {
    type Value = Spanned<T>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a value read from YAML")
    }

    fn visit_newtype_struct<D: Deserializer<'de>>(self, deserializer: D) -> Result<Self::Value, D::Error> {
        deserializer.deserialize_struct("Spanned", &["value", "referenced", "defined"], Fields(PhantomData))
    }
}

/// The located value as serde-saphyr writes it: a map of a marker, `value`,
/// `referenced` and `defined` (each a map with `line` and `column`).
struct Fields<T>(PhantomData<T>);

impl<'de, T: Deserialize<'de>> Visitor<'de> for Fields<T> {
    type Value = Spanned<T>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a value read from YAML")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        let (mut value, mut referenced, mut defined) = (None, None, None);
        while let Some(key) = map.next_key::<Key>()? {
            match key {
                Key::Value => value = Some(map.next_value::<T>()?),
                Key::Referenced => referenced = Some(map.next_value::<Place>()?.0),
                Key::Defined => defined = Some(map.next_value::<Place>()?.0),
                Key::Line | Key::Column | Key::Span | Key::Other => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(Spanned {
            value: value.ok_or_else(|| de::Error::missing_field("value"))?,
            referenced: referenced.unwrap_or_default(),
            defined: defined.unwrap_or_default(),
        })
    }
}

/// A key of the located value's map, or of a place's; the marker and a
/// place's other keys (its span, its source) are `Other`.
enum Key {
    Value,
    Referenced,
    Defined,
    Line,
    Column,
    Span,
    Other,
}

impl<'de> Deserialize<'de> for Key {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct KeyVisitor;
        impl Visitor<'_> for KeyVisitor {
            type Value = Key;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a key of a located value")
            }
            fn visit_str<E: de::Error>(self, key: &str) -> Result<Key, E> {
                Ok(match key {
                    "value" => Key::Value,
                    "referenced" => Key::Referenced,
                    "defined" => Key::Defined,
                    "line" => Key::Line,
                    "column" => Key::Column,
                    "span" => Key::Span,
                    _ => Key::Other,
                })
            }
        }
        deserializer.deserialize_identifier(KeyVisitor)
    }
}

/// A place: the line and column of a serde-saphyr `Location`, or the
/// tree's (`yaml::tree`) line and column in one number, line first.
struct Place(Pos);

impl<'de> Deserialize<'de> for Place {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_struct("Location", &["line", "column"], PlaceVisitor)
    }
}

struct PlaceVisitor;

impl<'de> Visitor<'de> for PlaceVisitor {
    type Value = Place;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a line and a column")
    }

    fn visit_u64<E: de::Error>(self, packed: u64) -> Result<Place, E> {
        let half = |n: u64| u32::try_from(n & u64::from(u32::MAX)).unwrap_or(0);
        Ok(Place(Pos { line: half(packed >> 32), column: half(packed) }))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Place, A::Error> {
        let mut pos = Pos::default();
        while let Some(key) = map.next_key::<Key>()? {
            // Past u32, a place is no place (a spec file is far smaller).
            let number = |n: u64| u32::try_from(n).unwrap_or(0);
            match key {
                Key::Line => pos.line = number(map.next_value::<u64>()?),
                Key::Column => pos.column = number(map.next_value::<u64>()?),
                // serde-saphyr's span reads only as its own type (it
                // refuses `IgnoredAny`), and serde-saphyr answers a located
                // value only in the tests; the tree writes no span.
                #[cfg(test)]
                Key::Span => {
                    map.next_value::<serde_saphyr::Span>()?;
                }
                #[cfg(not(test))]
                Key::Span => {
                    map.next_value::<IgnoredAny>()?;
                }
                Key::Value | Key::Referenced | Key::Defined | Key::Other => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(Place(pos))
    }
}

/// The value alone, as serde-saphyr's `Spanned` writes it.
#[cfg(feature = "serialize")]
impl<T: serde::Serialize> serde::Serialize for Spanned<T> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.value.serialize(serializer)
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::Spanned;

    #[derive(serde::Deserialize)]
    struct Doc {
        first: Spanned<u32>,
        second: Spanned<u32>,
        list: Spanned<Vec<Spanned<String>>>,
        table: BTreeMap<String, Spanned<f64>>,
    }

    /// Read by the tree (the workspace's reader) and by serde-saphyr (the
    /// oracle), which answer the request alike.
    fn both(yaml: &str) -> [Doc; 2] {
        [crate::from_yaml_str(yaml).unwrap(), serde_saphyr::from_str(yaml).unwrap()]
    }

    #[test]
    fn a_value_carries_where_it_is_written_and_where_it_is_used() {
        let yaml = "first: &n 7\nsecond: *n\nlist:\n  - a\n  - b\ntable: {x: 1.5}\n";
        for doc in both(yaml) {
            let at = |p: crate::Pos| (p.line, p.column);
            assert_eq!((doc.first.value, doc.second.value), (7, 7));
            assert_eq!(at(doc.first.defined), (1, 11));
            // The alias uses the anchored value: defined there, referenced here.
            assert_eq!(at(doc.second.defined), (1, 11));
            assert_eq!(at(doc.second.referenced), (2, 9));
            let items: Vec<_> = doc.list.value.iter().map(|s| (s.value.as_str(), at(s.defined))).collect();
            assert_eq!(items, [("a", (4, 5)), ("b", (5, 5))]);
            assert_eq!(doc.table["x"].value, 1.5);
            assert_eq!(at(doc.table["x"].defined), (6, 12));
        }
    }

    #[test]
    fn a_wrong_type_is_an_error_at_the_value() {
        let yaml = "first: seven\nsecond: 1\nlist: []\ntable: {}\n";
        let Err(e) = serde_saphyr::from_str::<Doc>(yaml) else { panic!("`seven` read as a number") };
        assert_eq!(e.location().map(|l| (l.line(), l.column())), Some((1, 8)), "{e}");
        let Err(e) = crate::from_yaml_str::<Doc>(yaml) else { panic!("`seven` read as a number") };
        assert_eq!((e.pos.line, e.pos.column), (1, 8), "{e}");
    }
}
