//! The document types read from the tree of located nodes (`load`).
//!
//! Reading from a tree instead of from the parser compiles serde's
//! deserializer machinery once, for this small deserializer, instead of
//! once per access type of a streaming one. A scalar is read as the type
//! asked for (`scalar`), and an error is placed at the node it concerns.

use serde::de::value::StrDeserializer;
use serde::de::{
    self, DeserializeOwned, DeserializeSeed, Deserializer, IntoDeserializer, MapAccess, SeqAccess, Visitor,
};
use serde::forward_to_deserialize_any;

use super::error::{Error, Kind};
use super::load::{Duplicates, Node, Scalar, Value, parse};
use super::scalar::Resolved;
use crate::diag::Pos;
use crate::spanned::SPANNED_REQUEST;

/// Reads `T` from `text`: the tree first, then `T` from it.
pub(super) fn from_str<T: DeserializeOwned>(text: &str) -> Result<T, Error> {
    let mut root = parse(text, Duplicates::Refuse)?;
    // An empty document reads as an empty mapping.
    if root.is_null() {
        root.value = Value::Map(Vec::new());
    }
    T::deserialize(NodeDeserializer { node: &root })
}

/// Reads the document types from one node of the tree.
#[derive(Clone, Copy)]
struct NodeDeserializer<'a> {
    node: &'a Node,
}

impl<'a> NodeDeserializer<'a> {
    fn of(self, node: &'a Node) -> Self {
        Self { node }
    }

    /// Places an error the node's reading made without a place: by serde,
    /// by a visitor, or by a `Deserialize` impl after it read the node
    /// (an untagged enum's "no variant matched").
    ///
    /// An error inside a value used through an alias (`*name`) is told at
    /// both places: where the value is written and where it is used.
    fn place<R>(self, result: Result<R, Error>) -> Result<R, Error> {
        result.map_err(|e| {
            let (used, written) = (self.node.referenced, self.node.defined);
            let e = e.placed(written);
            if matches!(e.kind, Kind::Alias { .. }) || used == written || used.line == 0 {
                return e;
            }
            Error::new(Kind::Alias { error: Box::new(e), written }, used)
        })
    }

    /// The node's scalar, or the error of asking a collection for one.
    fn scalar(self) -> Result<&'a Scalar, Error> {
        self.node.scalar().ok_or_else(|| self.wrong_shape("string scalar"))
    }

    /// The scalar read as `ty` by `read`, or the error at the scalar:
    /// `WrongTag` when the text would read but its tag says otherwise
    /// (`!!str 5` for a number), `InvalidScalar` when the text does not.
    fn read<T>(self, ty: &'static str, read: impl Fn(&Scalar) -> Option<T>) -> Result<T, Error> {
        let scalar = self.scalar()?;
        read(scalar).ok_or_else(|| {
            let kind = match &scalar.tag {
                Some(tag) if read(&Scalar { tag: None, ..scalar.clone() }).is_some() => {
                    Kind::WrongTag { tag: tag.clone(), ty }
                }
                _ => Kind::InvalidScalar { ty },
            };
            Error::new(kind, self.node.defined)
        })
    }

    fn wrong_shape(self, expected: &'static str) -> Error {
        Error::new(Kind::Unexpected { expected }, self.node.defined)
    }

    fn message(self, msg: &str) -> Error {
        Error::new(Kind::Message { msg: msg.into() }, self.node.defined)
    }

    fn entries(self) -> Option<Entries<'a>> {
        match &self.node.value {
            Value::Map(entries) => Some(Entries { of: self, entries: entries.iter(), value: None }),
            _ => None,
        }
    }
}

macro_rules! integers {
    ($($method:ident => $visit:ident: $ty:ident,)*) => {
        $(
            fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
                let value = self.read(stringify!($ty), |s| s.whole().and_then(|n| $ty::try_from(n).ok()))?;
                self.place(visitor.$visit(value))
            }
        )*
    };
}

impl<'de> Deserializer<'de> for NodeDeserializer<'_> {
    type Error = Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = match &self.node.value {
            Value::Scalar(scalar) => match scalar.resolve() {
                Ok(Resolved::Null) => visitor.visit_unit(),
                Ok(Resolved::Bool(b)) => visitor.visit_bool(b),
                Ok(Resolved::Unsigned(n)) => visitor.visit_u64(n),
                Ok(Resolved::Signed(n)) => visitor.visit_i64(n),
                Ok(Resolved::Float(x)) if x.is_finite() => visitor.visit_f64(x),
                // Allowed only where a number is asked for.
                Ok(Resolved::Float(_)) => {
                    return Err(Error::new(Kind::NonFiniteFloat { value: scalar.text.clone() }, self.node.defined));
                }
                Ok(Resolved::Text(s)) => visitor.visit_str(s),
                Err(ty) => Err(Error::new(Kind::InvalidScalar { ty }, self.node.defined)),
            },
            Value::List(items) => visitor.visit_seq(Items { of: self, items: items.iter() }),
            Value::Map(entries) => visitor.visit_map(Entries { of: self, entries: entries.iter(), value: None }),
        };
        self.place(result)
    }

    integers! {
        deserialize_i8 => visit_i8: i8,
        deserialize_i16 => visit_i16: i16,
        deserialize_i32 => visit_i32: i32,
        deserialize_i64 => visit_i64: i64,
        deserialize_u8 => visit_u8: u8,
        deserialize_u16 => visit_u16: u16,
        deserialize_u32 => visit_u32: u32,
        deserialize_u64 => visit_u64: u64,
    }

    fn deserialize_bool<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let value = self.read("bool", Scalar::boolean)?;
        self.place(visitor.visit_bool(value))
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let value = self.read("f64", Scalar::float)?;
        self.place(visitor.visit_f64(value))
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        // A finite number too large for an f32 is refused, not made infinite.
        #[allow(clippy::cast_possible_truncation)]
        let single = |s: &Scalar| {
            s.float().map(|x| x as f32).filter(|y| y.is_finite() || s.float().is_some_and(|x| !x.is_finite()))
        };
        let value = self.read("f32", single)?;
        self.place(visitor.visit_f32(value))
    }

    fn deserialize_char<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let mut chars = self.scalar()?.text.chars();
        let value = match (chars.next(), chars.next()) {
            (Some(c), None) => c,
            _ => return Err(self.message("expected a single character")),
        };
        self.place(visitor.visit_char(value))
    }

    fn deserialize_unit<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        if !self.node.is_null() {
            return Err(self.message("expected nothing (null)"));
        }
        self.place(visitor.visit_unit())
    }

    fn deserialize_str<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_string(visitor)
    }

    fn deserialize_string<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let scalar = self.scalar()?;
        if scalar.is_null() {
            return Err(Error::new(Kind::NullIntoString, self.node.defined));
        }
        self.place(visitor.visit_str(&scalar.text))
    }

    fn deserialize_bytes<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_any(visitor)
    }

    fn deserialize_byte_buf<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_any(visitor)
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = if self.node.is_null() { visitor.visit_none() } else { visitor.visit_some(self) };
        self.place(result)
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(self, _name: &'static str, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_unit(visitor)
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(self, name: &'static str, visitor: V) -> Result<V::Value, Error> {
        if name == SPANNED_REQUEST {
            return visitor.visit_newtype_struct(Located(self));
        }
        self.place(visitor.visit_newtype_struct(self))
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = match &self.node.value {
            Value::List(items) => visitor.visit_seq(Items { of: self, items: items.iter() }),
            _ => Err(self.wrong_shape("sequence start")),
        };
        self.place(result)
    }

    fn deserialize_tuple<V: Visitor<'de>>(self, _len: usize, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_seq(visitor)
    }

    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _len: usize,
        visitor: V,
    ) -> Result<V::Value, Error> {
        self.deserialize_seq(visitor)
    }

    fn deserialize_map<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let entries = self.entries().ok_or_else(|| self.wrong_shape("mapping start"))?;
        self.place(visitor.visit_map(entries))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        self.deserialize_map(visitor)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        let result = match &self.node.value {
            Value::Map(entries) => match entries.as_slice() {
                [(variant, value)] => {
                    visitor.visit_enum(Variant { name: self.of(variant), value: VariantValue(Some(self.of(value))) })
                }
                _ => Err(self.wrong_shape("a single-key mapping")),
            },
            Value::List(_) => Err(self.message("externally tagged enum expected scalar or mapping")),
            Value::Scalar(_) => visitor.visit_enum(Variant { name: self, value: VariantValue(None) }),
        };
        self.place(result)
    }

    fn deserialize_identifier<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let result = match self.node.name() {
            _ if self.node.is_null() => Err(Error::new(Kind::NullIntoString, self.node.defined)),
            Some(name) => visitor.visit_str(name),
            None => Err(self.wrong_shape("string scalar")),
        };
        self.place(result)
    }

    fn deserialize_ignored_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_unit()
    }
}

/// The items of a list.
struct Items<'a> {
    of: NodeDeserializer<'a>,
    items: std::slice::Iter<'a, Node>,
}

impl<'de> SeqAccess<'de> for Items<'_> {
    type Error = Error;

    fn next_element_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<Option<S::Value>, Error> {
        self.items
            .next()
            .map(|item| {
                let item = self.of.of(item);
                item.place(seed.deserialize(item))
            })
            .transpose()
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.items.len())
    }
}

/// The entries of a mapping.
struct Entries<'a> {
    of: NodeDeserializer<'a>,
    entries: std::slice::Iter<'a, (Node, Node)>,
    value: Option<&'a Node>,
}

impl<'de> MapAccess<'de> for Entries<'_> {
    type Error = Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> Result<Option<K::Value>, Error> {
        let Some((key, value)) = self.entries.next() else { return Ok(None) };
        self.value = Some(value);
        let key = self.of.of(key);
        key.place(seed.deserialize(key)).map(Some)
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, Error> {
        match self.value.take() {
            Some(value) => {
                let value = self.of.of(value);
                value.place(seed.deserialize(value))
            }
            None => Err(de::Error::custom("a value asked for before its key")),
        }
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.entries.len())
    }
}

/// An enum's variant: a name alone (`read`), or a single-key mapping.
struct Variant<'a> {
    name: NodeDeserializer<'a>,
    value: VariantValue<'a>,
}

/// The value of a variant written as a single-key mapping.
struct VariantValue<'a>(Option<NodeDeserializer<'a>>);

impl<'a> VariantValue<'a> {
    /// The value a variant with data needs: a variant written by its name
    /// alone has none.
    fn data(self, expected: &'static str) -> Result<NodeDeserializer<'a>, Error> {
        self.0.ok_or_else(|| de::Error::invalid_type(de::Unexpected::UnitVariant, &expected))
    }
}

impl<'de, 'a> de::EnumAccess<'de> for Variant<'a> {
    type Error = Error;
    type Variant = VariantValue<'a>;

    fn variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<(S::Value, Self::Variant), Error> {
        let name = self.name;
        let variant = match name.node.name() {
            Some(text) => seed.deserialize(IntoDeserializer::<Error>::into_deserializer(text)),
            None => Err(name.wrong_shape("string scalar")),
        };
        Ok((name.place(variant)?, self.value))
    }
}

impl<'de> de::VariantAccess<'de> for VariantValue<'_> {
    type Error = Error;

    fn unit_variant(self) -> Result<(), Error> {
        match self.0 {
            Some(value) if !value.node.is_null() => Err(value.message("unexpected value for unit enum variant")),
            _ => Ok(()),
        }
    }

    fn newtype_variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<S::Value, Error> {
        seed.deserialize(self.data("a variant with a value")?)
    }

    fn tuple_variant<V: Visitor<'de>>(self, _len: usize, visitor: V) -> Result<V::Value, Error> {
        self.data("a tuple variant")?.deserialize_seq(visitor)
    }

    fn struct_variant<V: Visitor<'de>>(self, _fields: &'static [&'static str], visitor: V) -> Result<V::Value, Error> {
        self.data("a struct variant")?.deserialize_map(visitor)
    }
}

/// A located value asked for (`Spanned`): the value and its two places.
struct Located<'a>(NodeDeserializer<'a>);

impl<'de> Deserializer<'de> for Located<'_> {
    type Error = Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_map(LocatedFields { of: self.0, next: 0 })
    }

    forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map struct enum identifier ignored_any
    }
}

/// The fields of a located value, in order.
struct LocatedFields<'a> {
    of: NodeDeserializer<'a>,
    next: usize,
}

const LOCATED_FIELDS: [&str; 3] = ["value", "referenced", "defined"];

impl<'de> MapAccess<'de> for LocatedFields<'_> {
    type Error = Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> Result<Option<K::Value>, Error> {
        let Some(key) = LOCATED_FIELDS.get(self.next) else { return Ok(None) };
        self.next += 1;
        seed.deserialize(StrDeserializer::<Error>::new(key)).map(Some)
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, Error> {
        // A place as one number: a deserializer of its own type here would
        // compile every located type's reading once more.
        let place = |Pos { line, column }: Pos| {
            IntoDeserializer::<Error>::into_deserializer(u64::from(line) << 32 | u64::from(column))
        };
        match self.next {
            1 => self.of.place(seed.deserialize(self.of)),
            2 => seed.deserialize(place(self.of.node.referenced)),
            _ => seed.deserialize(place(self.of.node.defined)),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use serde::Deserialize;

    use super::from_str;
    use crate::Spanned;

    #[derive(Debug, Deserialize, PartialEq)]
    #[serde(rename_all = "snake_case")]
    enum Function {
        Read,
        Write,
    }

    #[derive(Debug, Deserialize, PartialEq)]
    #[serde(untagged)]
    enum Stated {
        Number(f64),
        Text(String),
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        count: Spanned<u32>,
        title: String,
        function: Function,
        scale: Option<f64>,
        note: Option<String>,
        list: Vec<Spanned<String>>,
        table: BTreeMap<String, Spanned<f64>>,
        #[serde(default)]
        stated: Vec<Stated>,
    }

    const DOC: &str =
        "count: &n 0x10\ntitle: 1.10\nfunction: read\nscale: ~\nnote: \"\"\nlist: [a, 'b', *n]\ntable: {x: 1.5}\n";

    #[test]
    fn values_read_as_the_core_schema_reads_them() {
        let doc: Doc = from_str(DOC).unwrap();
        assert_eq!(doc.count.value, 16);
        assert_eq!(doc.title, "1.10", "a plain scalar asked for as text is its text");
        assert_eq!(doc.function, Function::Read);
        assert_eq!((doc.scale, doc.note.as_deref()), (None, Some("")));
        let items: Vec<_> =
            doc.list.iter().map(|s| (s.value.as_str(), s.referenced.column, s.defined.column)).collect();
        assert_eq!(items, [("a", 8, 8), ("b", 11, 11), ("0x10", 16, 11)]);
        assert_eq!((doc.table["x"].value, doc.table["x"].defined.line), (1.5, 7));
        let stated = from_str::<Doc>(&format!("{DOC}stated: [7, \"7\", x]\n")).unwrap().stated;
        assert_eq!(stated, [Stated::Number(7.0), Stated::Text("7".into()), Stated::Text("x".into())]);
        // A float asked for as a float may be infinite; one of no asked-for type may not.
        let infinite = from_str::<Doc>(&DOC.replace("scale: ~", "scale: .inf")).unwrap();
        assert_eq!(infinite.scale, Some(f64::INFINITY));
    }

    #[test]
    fn errors_are_at_the_offending_place() {
        let at = |text: &str| {
            let Err(e) = from_str::<Doc>(text) else { panic!("read without an error:\n{text}") };
            let place = e.at().map(|at| (at.line, at.column));
            (place, e.to_string())
        };
        for (broken, line, column) in [
            (DOC.replace("0x10", "ten"), 1, 11),
            (DOC.replace("0x10", "--- 5"), 1, 11),
            (DOC.replace("0x10", "... 5"), 1, 11),
            (DOC.replace("function: read", "function: raed"), 3, 11),
            (DOC.replace("scale: ~", "scale: [1]"), 4, 8),
            (DOC.replace("note: \"\"", "nota: x"), 5, 1),
            (DOC.replace("count: &n 0x10", "count: &n 99999999999"), 1, 11),
            (format!("{DOC}stated: [1, .inf]\n"), 8, 13),
        ] {
            let (place, message) = at(&broken);
            assert_eq!(place, Some((line, column)), "{message}\n{broken}");
        }
        // Of the kind the messages know.
        let Err(e) = from_str::<Doc>(&DOC.replace("0x10", "ten")) else { panic!("`ten` read as a number") };
        assert!(matches!(e.kind, super::Kind::InvalidScalar { ty: "u32" }), "{e:?}");
        // A tag that says the value is something else is named as the cause.
        let Err(e) = from_str::<Doc>(&DOC.replace("0x10", "!!str 16")) else { panic!("`!!str 16` read as a number") };
        assert!(matches!(&e.kind, super::Kind::WrongTag { tag, ty: "u32" } if tag == "str"), "{e:?}");
        // A tag that fits, on a text that does not, is the text's error.
        let Err(e) = from_str::<Doc>(&DOC.replace("0x10", "!!int ten")) else { panic!("`!!int ten` read") };
        assert!(matches!(e.kind, super::Kind::InvalidScalar { ty: "u32" }), "{e:?}");
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        x: u32,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Outer {
        inner: Inner,
    }

    /// Every shape the document types use, each optional.
    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Shapes {
        #[serde(default)]
        inner: Option<Inner>,
        #[serde(default)]
        outer: Option<Outer>,
        #[serde(default)]
        function: Option<Function>,
        #[serde(default)]
        text: Option<String>,
        #[serde(default)]
        flag: Option<bool>,
        #[serde(default)]
        number: Option<u32>,
        #[serde(default)]
        small: Option<u8>,
        #[serde(default)]
        signed: Option<i32>,
        #[serde(default)]
        real: Option<f64>,
        #[serde(default)]
        single: Option<f32>,
        #[serde(default)]
        list: Vec<u32>,
        #[serde(default)]
        located: Vec<Spanned<String>>,
        #[serde(default)]
        table: Option<BTreeMap<String, u32>>,
        #[serde(default)]
        stated: Option<Stated>,
        #[serde(default)]
        required: Vec<Inner>,
    }

    /// What serde-saphyr (the reader the spec files were first read with,
    /// kept as an oracle) and the tree give: equal values, or errors at
    /// equal places.
    #[test]
    fn the_tree_reads_what_serde_saphyr_reads() {
        let texts = [
            "inner: {x: 1}\n",
            "inner: {x: }\n",
            "inner: {x: ~}\n",
            "inner: {}\n",
            "inner: 5\n",
            "inner: [1]\n",
            "inner: {x: 1, y: 2}\n",
            "outer: {inner: }\n",
            "outer: {inner: ~}\n",
            "outer: {inner: {x: [1]}}\n",
            "function: read\n",
            "function: [read]\n",
            "function: {read: 1}\n",
            "function: {raed: ~}\n",
            "function: 3\n",
            "function: ~\n",
            "function: raed\n",
            "text: [a]\n",
            "text: {a: 1}\n",
            "text: 12\n",
            "text: 1.10\n",
            "text: true\n",
            "text: ~\n",
            "text: \"\"\n",
            "text: .inf\n",
            "text: |\n  two\n  lines\n",
            "flag: yes\n",
            "flag: true\n",
            "flag: [true]\n",
            "flag: \"true\"\n",
            "number: {a: 1}\n",
            "number: \"12\"\n",
            "number: 1_000\n",
            "number: +12\n",
            "number: 012\n",
            "number: 0o17\n",
            "number: 0x1C00\n",
            "number: -1\n",
            "number: 4294967296\n",
            "number: 1.5\n",
            "number: twelve\n",
            "number: ''\n",
            "small: 256\n",
            "small: 255\n",
            "signed: -5\n",
            "signed: 0x7FFFFFFF\n",
            "real: .inf\n",
            "real: -.inf\n",
            "real: .nan\n",
            "real: 1e3\n",
            "real: 5\n",
            "real: \"1.5\"\n",
            "single: 1e40\n",
            "single: 0.1\n",
            "list: ~\n",
            "list:\n",
            "list: 5\n",
            "list: [1, x]\n",
            "list: {a: 1}\n",
            "list: [1, [2]]\n",
            "located: [a, 'b', 3]\n",
            "located: [[a]]\n",
            "table: [1]\n",
            "table: 5\n",
            "table: ~\n",
            "table: {a: 1, b: x}\n",
            "table: {1: 2}\n",
            "stated: 7\n",
            "stated: \"7\"\n",
            "stated: [7]\n",
            "stated: .inf\n",
            "stated: true\n",
            "stated: ~\n",
            "required: [{x: 1}, {}]\n",
            "required: [{x: 1}, 5]\n",
            "unknown: 1\n",
            "~: 1\n",
            "1: 2\n",
            "",
            "# nothing\n",
            "text:\n",
            "flag:\n",
            "real:\n",
            "function:\n",
            "inner:\n",
            "required: [~]\n",
            "number: |\n  5\n",
            "number: !!str 5\n",
            "\"number\": 5\n",
            "{number: 5, flag: true}\n",
            "number: 5\nnumber: 6\n",
            "text: plain\n  continued\n",
            "number: 1\n  2\n",
            "list: &l [1, x]\n",
            "table: &t {a: 1}\nnumber: *t\n",
            "inner: &i {x: a}\nouter: {inner: *i}\n",
            "required: &r [{x: 1}]\nlist: *r\n",
            "text: &s a\nfunction: *s\n",
            "&k flag: true\n",
            "{&k 1: 2}\n",
            "number: &n !!int 5\n",
            "number: !!int &n 5\n",
            "number: --- 5\n",
            "number: ... 5\n",
            "number: &a 5\nsmall: *a\n",
            "list: &l [1]\nlocated: *l\n",
        ];
        let direct = |text: &str| {
            let options = serde_saphyr::options! {
                duplicate_keys: serde_saphyr::DuplicateKeyPolicy::Error,
                strict_booleans: true,
            };
            match serde_saphyr::from_str_with_options::<Shapes>(text, options) {
                Ok(v) => format!("{v:?}"),
                Err(e) => format!("error at {:?}", e.location().map(|l| (l.line(), l.column()))),
            }
        };
        let tree = |text: &str| match from_str::<Shapes>(text) {
            Ok(v) => format!("{v:?}"),
            Err(e) => format!("error at {:?}", e.at().map(|at| (u64::from(at.line), u64::from(at.column)))),
        };
        let differ: Vec<String> = texts
            .iter()
            .filter(|t| direct(t) != tree(t))
            .map(|t| format!("{t:?}\n  serde-saphyr: {}\n  tree:         {}", direct(t), tree(t)))
            .collect();
        assert!(differ.is_empty(), "{}", differ.join("\n"));
    }
}
