//! What can go wrong reading a spec file's YAML, as data: the kind and the
//! place. `messages` turns each kind into words for a spec author.

use std::fmt;

use serde::de;

use crate::diag::Pos;

/// A YAML or shape error and where it is (line 0 until it is placed).
#[derive(Debug)]
pub(super) struct Error {
    pub kind: Kind,
    /// Where: for an error inside a value used through an alias, where the
    /// alias is.
    pub at: Pos,
}

#[derive(Debug)]
pub(super) enum Kind {
    /// The parser's own message: the text is not YAML.
    Syntax {
        msg: String,
    },
    /// An alias (`*name`) with no anchor (`&name`) before it.
    UnknownAnchor,
    /// A second document (`---`) in the file.
    MultipleDocuments,
    /// A limit of [`super::limits`] passed.
    Limit {
        limit: Limit,
    },
    /// A key written twice in one mapping.
    DuplicateKey {
        key: String,
    },
    UnknownField {
        field: String,
        expected: &'static [&'static str],
    },
    UnknownVariant {
        variant: String,
        expected: &'static [&'static str],
    },
    MissingField {
        field: &'static str,
    },
    /// A scalar that does not read as the `ty` asked for (`u32`, `bool`, ...).
    InvalidScalar {
        ty: &'static str,
    },
    /// A scalar whose tag (`!!str`, `!!binary`) says it is not the `ty` asked for.
    WrongTag {
        tag: String,
        ty: &'static str,
    },
    InvalidType {
        unexpected: String,
        expected: String,
    },
    InvalidValue {
        unexpected: String,
        expected: String,
    },
    InvalidLength {
        len: usize,
        expected: String,
    },
    /// Nothing written where text is asked for.
    NullIntoString,
    /// A node of the wrong shape: `expected` says what was asked for.
    Unexpected {
        expected: &'static str,
    },
    /// `.inf` or `.nan` where a number of no asked-for type is read.
    NonFiniteFloat {
        value: String,
    },
    /// A message from a `Deserialize` impl (an untagged enum's "no variant matched").
    Message {
        msg: String,
    },
    /// An error inside a value used through an alias, and where the value
    /// is written: told at both places.
    Alias {
        error: Box<Error>,
        written: Pos,
    },
}

/// Which limit a hostile file passed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Limit {
    Nodes,
    Depth,
    Aliases,
    Anchors,
    AliasReplay,
}

const NOWHERE: Pos = Pos { line: 0, column: 0 };

impl Error {
    pub(super) fn new(kind: Kind, at: Pos) -> Self {
        Self { kind, at }
    }

    /// Where the error is, or `None` when it was made without a place.
    pub(super) fn at(&self) -> Option<Pos> {
        (self.at.line > 0).then_some(self.at)
    }

    /// The error at `place` if it has no place yet.
    pub(super) fn placed(mut self, place: Pos) -> Self {
        if self.at().is_none() {
            self.at = place;
        }
        self
    }

    /// The error itself, through any alias.
    pub(super) fn inner(&self) -> &Error {
        match &self.kind {
            Kind::Alias { error, .. } => error.inner(),
            _ => self,
        }
    }
}

impl From<Kind> for Error {
    /// An error made without a place (by serde or a visitor): the node
    /// being read places it.
    fn from(kind: Kind) -> Self {
        Self { kind, at: NOWHERE }
    }
}

impl fmt::Display for Error {
    /// A developer's one-line account; `messages` words it for spec authors.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.kind {
            Kind::Syntax { msg } | Kind::Message { msg } => f.write_str(msg),
            Kind::UnknownAnchor => f.write_str("unknown anchor"),
            Kind::MultipleDocuments => f.write_str("more than one document"),
            Kind::Limit { limit } => write!(f, "limit passed: {limit:?}"),
            Kind::DuplicateKey { key } => write!(f, "duplicate key `{key}`"),
            Kind::UnknownField { field, .. } => write!(f, "unknown field `{field}`"),
            Kind::UnknownVariant { variant, .. } => write!(f, "unknown variant `{variant}`"),
            Kind::MissingField { field } => write!(f, "missing field `{field}`"),
            Kind::InvalidScalar { ty } => write!(f, "invalid {ty}"),
            Kind::WrongTag { tag, ty } => write!(f, "tag {tag} where a {ty} is expected"),
            Kind::InvalidType { unexpected, expected } => write!(f, "invalid type: {unexpected}, expected {expected}"),
            Kind::InvalidValue { unexpected, expected } => {
                write!(f, "invalid value: {unexpected}, expected {expected}")
            }
            Kind::InvalidLength { len, expected } => write!(f, "invalid length {len}, expected {expected}"),
            Kind::NullIntoString => f.write_str("null where text is expected"),
            Kind::Unexpected { expected } => write!(f, "expected {expected}"),
            Kind::NonFiniteFloat { value } => write!(f, "non-finite number {value}"),
            Kind::Alias { error, written } => write!(
                f,
                "{error} (written at line {}, column {}; used at line {}, column {})",
                written.line, written.column, self.at.line, self.at.column
            ),
        }
    }
}

impl std::error::Error for Error {}

impl de::Error for Error {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Kind::Message { msg: msg.to_string() }.into()
    }
    fn invalid_type(unexpected: de::Unexpected<'_>, expected: &dyn de::Expected) -> Self {
        Kind::InvalidType { unexpected: unexpected.to_string(), expected: expected.to_string() }.into()
    }
    fn invalid_value(unexpected: de::Unexpected<'_>, expected: &dyn de::Expected) -> Self {
        Kind::InvalidValue { unexpected: unexpected.to_string(), expected: expected.to_string() }.into()
    }
    fn invalid_length(len: usize, expected: &dyn de::Expected) -> Self {
        Kind::InvalidLength { len, expected: expected.to_string() }.into()
    }
    fn unknown_variant(variant: &str, expected: &'static [&'static str]) -> Self {
        Kind::UnknownVariant { variant: variant.to_owned(), expected }.into()
    }
    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        Kind::UnknownField { field: field.to_owned(), expected }.into()
    }
    fn missing_field(field: &'static str) -> Self {
        Kind::MissingField { field }.into()
    }
}
