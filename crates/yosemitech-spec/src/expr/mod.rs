//! The expression language of derived quantities, and its units.
//!
//! An expression is numbers, names (the quantity's inputs and the sensor's
//! constants), `+ - * / ^`, unary minus, parentheses, `exp(x)`, `ln(x)`, the
//! comparisons `< <= > >= == !=` and `if(condition, then, else)`; nothing
//! else. [`parse`] turns the text into an [`Expr`], [`check`] resolves its
//! names and checks its units, and [`Expr::eval`] computes it in `f64`, as
//! the generated functions do.
//!
//! Units are products of symbols with integer powers (`mg/L`, `mS/cm`,
//! `mg/L per uS/cm`, `kPa`, `degC`, `%`); `1` or nothing is dimensionless.
//! Symbols are opaque: `mS` and `uS` are different units, as are `degC` and
//! `K`, and `%` is a unit of its own (not dimensionless). `+`, `-`, the
//! comparisons and the branches of `if` need equal units; `exp` and `ln`
//! take dimensionless arguments and give dimensionless values; `^` takes a
//! dimensionless exponent, which must be a whole number when the base has
//! a unit. A bare number takes whatever unit its place needs: beside a
//! quantity in `+`, `-` or a comparison it has that quantity's unit, and as
//! a factor it is a conversion factor (`conductivity * 1000` declared in
//! `uS/cm` reads as 1000 uS/mS), so a product with a bare number, like a
//! name whose unit is not declared, has no fixed unit and is checked only
//! where it meets a quantity whose unit is known.

mod check;
mod eval;
mod parse;
mod unit;

pub use self::check::{Binding, Dim, Name, check, names_used};
pub use self::parse::{MAX_DEPTH, parse};
pub use self::unit::Unit;

/// A byte range of the expression's text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Span {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
}

/// What is wrong with an expression, and where in its text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExprError {
    /// The offending token.
    pub span: Span,
    /// What is wrong.
    pub message: String,
    /// What would be valid.
    pub help: Option<String>,
    /// Another place the help refers to (the `(` a missing `)` would close).
    pub related: Option<Span>,
}

impl ExprError {
    fn new(span: Span, message: impl Into<String>, help: Option<String>) -> Self {
        Self { span, message: message.into(), help, related: None }
    }
}

/// An arithmetic operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// `+`.
    Add,
    /// `-`.
    Sub,
    /// `*`.
    Mul,
    /// `/`.
    Div,
    /// `^`.
    Pow,
}

/// A comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cmp {
    /// `<`.
    Lt,
    /// `<=`.
    Le,
    /// `>`.
    Gt,
    /// `>=`.
    Ge,
    /// `==`.
    Eq,
    /// `!=`.
    Ne,
}

impl Cmp {
    /// The operator as written.
    pub fn symbol(self) -> &'static str {
        match self {
            Cmp::Lt => "<",
            Cmp::Le => "<=",
            Cmp::Gt => ">",
            Cmp::Ge => ">=",
            Cmp::Eq => "==",
            Cmp::Ne => "!=",
        }
    }
}

/// A function of the language.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Func {
    /// `exp(x)`.
    Exp,
    /// `ln(x)`, the natural logarithm.
    Ln,
}

/// Names an expression cannot give an input or a constant: its functions.
pub const FUNCTION_NAMES: &[&str] = &["exp", "ln", "if"];

/// One node of an expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    /// A number as written.
    Num(f64),
    /// A name, before [`check`] resolves it.
    Name(String),
    /// Input `index` of the quantity (after [`check`]).
    Input(usize, String),
    /// A scalar constant of the sensor, by name, with its value as the generated constant holds it.
    Const(String, f64),
    /// `-x`.
    Neg(Box<Expr>),
    /// `a op b`.
    Bin(Op, Box<Expr>, Box<Expr>),
    /// `exp(x)`, `ln(x)`.
    Call(Func, Box<Expr>),
    /// `a < b` and the other comparisons: a condition, not a number.
    Cmp(Cmp, Box<Expr>, Box<Expr>),
    /// `if(condition, then, else)`.
    If(Box<Expr>, Box<Expr>, Box<Expr>),
}

/// An expression with the position of each node in the text.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    /// What it is.
    pub node: Node,
    /// The text it was parsed from (an operator's node: the operator).
    pub span: Span,
}

impl Expr {
    fn new(node: Node, span: Span) -> Self {
        Self { node, span }
    }

    /// The whole number this is written as (`2`, `-3`), within the
    /// powers [`Power::Whole`] computes by multiplication.
    pub fn whole_literal(&self) -> Option<i32> {
        match &self.node {
            Node::Num(v) if v.fract() == 0.0 && v.abs() <= 64.0 => Some(*v as i32),
            Node::Neg(x) => x.whole_literal().map(|n| -n),
            _ => None,
        }
    }
}

/// How `base ^ exponent` is computed, decided from how the formula writes
/// it: the generated function and the interpreter compute a power the same
/// way. A general power function is large in firmware (about 3 KB of
/// flash with its helpers) and the formulas of the manuals need none: they
/// square a value or raise a number to a computed power.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Power {
    /// A whole exponent written as such (`x^2`): repeated multiplication.
    Whole(i32),
    /// A positive number raised to a computed power (`10^y`): a product
    /// when `y` is whole, else `exp(ln_base * y)`, with the base's
    /// logarithm computed once, here.
    OfNumber {
        /// The base, as written.
        base: f64,
        /// Its natural logarithm.
        ln_base: f64,
    },
    /// Anything else: the general power function.
    General,
}

impl Power {
    /// How the formula's `base ^ exponent` is computed.
    pub fn of(base: &Expr, exponent: &Expr) -> Self {
        if let Some(n) = exponent.whole_literal() {
            return Self::Whole(n);
        }
        match base.node {
            Node::Num(b) if b > 0.0 && b.is_finite() => Self::OfNumber { base: b, ln_base: b.ln() },
            _ => Self::General,
        }
    }
}

/// What the tests of each part share: a formula parsed, checked against
/// a few names and computed.
#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn unit(s: &str) -> Unit {
        Unit::parse(s).unwrap()
    }

    pub(super) fn names() -> Vec<Name> {
        vec![
            Name { name: "c".into(), binding: Binding::Input(0), unit: Some(unit("mS/cm")) },
            Name { name: "t".into(), binding: Binding::Input(1), unit: Some(unit("degC")) },
            Name { name: "s".into(), binding: Binding::Input(2), unit: None },
            Name { name: "k".into(), binding: Binding::Const(0.5), unit: Some(unit("mg/L per mS/cm")) },
        ]
    }

    pub(super) fn run(src: &str, unit_decl: Option<&str>, inputs: &[f64]) -> Result<Option<f64>, ExprError> {
        let e = parse(src)?;
        let decl = unit_decl.map(unit);
        let (e, _) = check(&e, &names(), decl.as_ref())?;
        Ok(e.eval(inputs))
    }

    pub(super) fn err(src: &str, unit_decl: Option<&str>) -> ExprError {
        run(src, unit_decl, &[1.0, 2.0, 3.0]).unwrap_err()
    }
}
