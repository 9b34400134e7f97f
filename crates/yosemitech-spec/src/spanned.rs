//! A value and where the spec file wrote it: serde-saphyr's `Spanned`, read
//! the one way serde-saphyr hands it over.
//!
//! serde-saphyr's own `Spanned<T>` also accepts a value buffered by serde
//! (`flatten`, `untagged`), and so instantiates `T`'s deserializer once more
//! for every primitive and every map access that path could bring: about a
//! third of this crate's generated code, compiled in every build script that
//! generates from a spec. The document types use neither `flatten` nor
//! `untagged` around a located value, so this one asks for the location
//! and reads the value with serde-saphyr's deserializer alone.

use std::fmt;
use std::marker::PhantomData;

use serde::Deserialize;
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, Visitor};
use serde_saphyr::Location;

/// A value, where it is used (`referenced`: an alias's place) and where it
/// is written (`defined`); both [`Location::UNKNOWN`] for a value made in
/// code.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Spanned<T> {
    /// The value.
    pub value: T,
    /// Where the value is used: the alias, or the value itself.
    pub referenced: Location,
    /// Where the value is written.
    pub defined: Location,
}

impl<T> Spanned<T> {
    /// A value at the given places.
    #[must_use]
    pub const fn new(value: T, referenced: Location, defined: Location) -> Self {
        Self { value, referenced, defined }
    }
}

/// The newtype name by which serde-saphyr's deserializer recognises a
/// request for a location (its own `Spanned` uses it).
const SPANNED_REQUEST: &str = "__yaml_spanned";

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Spanned<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_newtype_struct(SPANNED_REQUEST, Request(PhantomData))
    }
}

/// Answered by serde-saphyr with a deserializer of the located value.
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
/// `referenced` and `defined`.
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
                Key::Referenced => referenced = Some(map.next_value::<Location>()?),
                Key::Defined => defined = Some(map.next_value::<Location>()?),
                Key::Other => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(Spanned {
            value: value.ok_or_else(|| de::Error::missing_field("value"))?,
            referenced: referenced.unwrap_or(Location::UNKNOWN),
            defined: defined.unwrap_or(Location::UNKNOWN),
        })
    }
}

/// A key of the located value's map; the marker is one of the others.
enum Key {
    Value,
    Referenced,
    Defined,
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
                    _ => Key::Other,
                })
            }
        }
        deserializer.deserialize_identifier(KeyVisitor)
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

    #[test]
    fn a_value_carries_where_it_is_written_and_where_it_is_used() {
        let yaml = "first: &n 7\nsecond: *n\nlist:\n  - a\n  - b\ntable: {x: 1.5}\n";
        let doc: Doc = serde_saphyr::from_str(yaml).unwrap();
        let at = |l: serde_saphyr::Location| (l.line(), l.column());
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

    #[test]
    fn a_wrong_type_is_an_error_at_the_value() {
        let Err(e) = serde_saphyr::from_str::<Doc>("first: seven\nsecond: 1\nlist: []\ntable: {}\n") else {
            panic!("`seven` read as a number")
        };
        assert_eq!(e.location().map(|l| (l.line(), l.column())), Some((1, 8)), "{e}");
    }
}
