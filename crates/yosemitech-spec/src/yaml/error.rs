//! What can go wrong reading a spec file's YAML, as data: the kind and the
//! place. `messages` turns each kind into words for a spec author.

use std::fmt;

use serde::de;

use crate::diag::Pos;

/// A YAML or shape error and where it is.
#[derive(Debug)]
pub(super) enum Error {
    /// The parser's own message: the text is not YAML.
    Syntax {
        msg: String,
        at: Pos,
    },
    /// An alias (`*name`) with no anchor (`&name`) before it.
    UnknownAnchor {
        at: Pos,
    },
    /// A second document (`---`) in the file.
    MultipleDocuments {
        at: Pos,
    },
    /// A limit of [`super::limits`] passed.
    Limit {
        limit: Limit,
        at: Pos,
    },
    /// A key written twice in one mapping.
    DuplicateKey {
        key: String,
        at: Pos,
    },
    UnknownField {
        field: String,
        expected: &'static [&'static str],
        at: Pos,
    },
    UnknownVariant {
        variant: String,
        expected: &'static [&'static str],
        at: Pos,
    },
    MissingField {
        field: &'static str,
        at: Pos,
    },
    /// A scalar that does not read as the `ty` asked for (`u32`, `bool`, ...).
    InvalidScalar {
        ty: &'static str,
        at: Pos,
    },
    /// A scalar whose tag (`!!str`, `!!binary`) says it is not the `ty` asked for.
    WrongTag {
        tag: String,
        ty: &'static str,
        at: Pos,
    },
    InvalidType {
        unexpected: String,
        expected: String,
        at: Pos,
    },
    InvalidValue {
        unexpected: String,
        expected: String,
        at: Pos,
    },
    InvalidLength {
        len: usize,
        expected: String,
        at: Pos,
    },
    /// Nothing written where text is asked for.
    NullIntoString {
        at: Pos,
    },
    /// A node of the wrong shape: `expected` says what was asked for.
    Unexpected {
        expected: &'static str,
        at: Pos,
    },
    /// `.inf` or `.nan` where a number of no asked-for type is read.
    NonFiniteFloat {
        value: String,
        at: Pos,
    },
    /// A message from a `Deserialize` impl (an untagged enum's "no variant matched").
    Message {
        msg: String,
        at: Pos,
    },
    /// An error inside a value used through an alias: told at both places.
    Alias {
        error: Box<Error>,
        used: Pos,
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

impl Error {
    /// Where the error is (for an alias, where the value is used), or
    /// `None` when it was made without a place.
    pub(super) fn at(&self) -> Option<Pos> {
        let at = match self {
            Error::Alias { used, .. } => *used,
            Error::Syntax { at, .. }
            | Error::UnknownAnchor { at }
            | Error::MultipleDocuments { at }
            | Error::Limit { at, .. }
            | Error::DuplicateKey { at, .. }
            | Error::UnknownField { at, .. }
            | Error::UnknownVariant { at, .. }
            | Error::MissingField { at, .. }
            | Error::InvalidScalar { at, .. }
            | Error::WrongTag { at, .. }
            | Error::InvalidType { at, .. }
            | Error::InvalidValue { at, .. }
            | Error::InvalidLength { at, .. }
            | Error::NullIntoString { at }
            | Error::Unexpected { at, .. }
            | Error::NonFiniteFloat { at, .. }
            | Error::Message { at, .. } => *at,
        };
        (at.line > 0).then_some(at)
    }

    /// The error at `at` if it has no place yet.
    pub(super) fn placed(mut self, place: Pos) -> Self {
        if self.at().is_some() {
            return self;
        }
        match &mut self {
            Error::Alias { .. } => {}
            Error::Syntax { at, .. }
            | Error::UnknownAnchor { at }
            | Error::MultipleDocuments { at }
            | Error::Limit { at, .. }
            | Error::DuplicateKey { at, .. }
            | Error::UnknownField { at, .. }
            | Error::UnknownVariant { at, .. }
            | Error::MissingField { at, .. }
            | Error::InvalidScalar { at, .. }
            | Error::WrongTag { at, .. }
            | Error::InvalidType { at, .. }
            | Error::InvalidValue { at, .. }
            | Error::InvalidLength { at, .. }
            | Error::NullIntoString { at }
            | Error::Unexpected { at, .. }
            | Error::NonFiniteFloat { at, .. }
            | Error::Message { at, .. } => *at = place,
        }
        self
    }

    /// The error itself, through any alias.
    pub(super) fn inner(&self) -> &Error {
        match self {
            Error::Alias { error, .. } => error.inner(),
            other => other,
        }
    }
}

impl fmt::Display for Error {
    /// A developer's one-line account; `messages` words it for spec authors.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Syntax { msg, .. } | Error::Message { msg, .. } => f.write_str(msg),
            Error::UnknownAnchor { .. } => f.write_str("unknown anchor"),
            Error::MultipleDocuments { .. } => f.write_str("more than one document"),
            Error::Limit { limit, .. } => write!(f, "limit passed: {limit:?}"),
            Error::DuplicateKey { key, .. } => write!(f, "duplicate key `{key}`"),
            Error::UnknownField { field, .. } => write!(f, "unknown field `{field}`"),
            Error::UnknownVariant { variant, .. } => write!(f, "unknown variant `{variant}`"),
            Error::MissingField { field, .. } => write!(f, "missing field `{field}`"),
            Error::InvalidScalar { ty, .. } => write!(f, "invalid {ty}"),
            Error::WrongTag { tag, ty, .. } => write!(f, "tag {tag} where a {ty} is expected"),
            Error::InvalidType { unexpected, expected, .. } => {
                write!(f, "invalid type: {unexpected}, expected {expected}")
            }
            Error::InvalidValue { unexpected, expected, .. } => {
                write!(f, "invalid value: {unexpected}, expected {expected}")
            }
            Error::InvalidLength { len, expected, .. } => write!(f, "invalid length {len}, expected {expected}"),
            Error::NullIntoString { .. } => f.write_str("null where text is expected"),
            Error::Unexpected { expected, .. } => write!(f, "expected {expected}"),
            Error::NonFiniteFloat { value, .. } => write!(f, "non-finite number {value}"),
            Error::Alias { error, used, written } => write!(
                f,
                "{error} (written at line {}, column {}; used at line {}, column {})",
                written.line, written.column, used.line, used.column
            ),
        }
    }
}

impl std::error::Error for Error {}

const NOWHERE: Pos = Pos { line: 0, column: 0 };

impl de::Error for Error {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Error::Message { msg: msg.to_string(), at: NOWHERE }
    }
    fn invalid_type(unexpected: de::Unexpected<'_>, expected: &dyn de::Expected) -> Self {
        Error::InvalidType { unexpected: unexpected.to_string(), expected: expected.to_string(), at: NOWHERE }
    }
    fn invalid_value(unexpected: de::Unexpected<'_>, expected: &dyn de::Expected) -> Self {
        Error::InvalidValue { unexpected: unexpected.to_string(), expected: expected.to_string(), at: NOWHERE }
    }
    fn invalid_length(len: usize, expected: &dyn de::Expected) -> Self {
        Error::InvalidLength { len, expected: expected.to_string(), at: NOWHERE }
    }
    fn unknown_variant(variant: &str, expected: &'static [&'static str]) -> Self {
        Error::UnknownVariant { variant: variant.to_owned(), expected, at: NOWHERE }
    }
    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        Error::UnknownField { field: field.to_owned(), expected, at: NOWHERE }
    }
    fn missing_field(field: &'static str) -> Self {
        Error::MissingField { field, at: NOWHERE }
    }
}
