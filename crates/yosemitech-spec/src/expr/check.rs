//! A formula's names resolved to inputs and constants, and its units
//! checked.

use std::fmt;

use super::{Expr, ExprError, Func, Node, Op, Span, Unit};

/// What a name of a formula stands for.
#[derive(Debug, Clone, PartialEq)]
pub enum Binding {
    /// Input `index` of the quantity.
    Input(usize),
    /// A scalar constant of the sensor with its value.
    Const(f64),
}

/// A name a formula may use, with its unit when declared.
#[derive(Debug, Clone, PartialEq)]
pub struct Name {
    /// The name.
    pub name: String,
    /// What it stands for.
    pub binding: Binding,
    /// Its unit; `None` when not declared (not checked).
    pub unit: Option<Unit>,
}

/// The unit of a number in a formula: known, or free (a bare number, or a
/// name whose unit is not declared), which takes the unit its place needs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Dim {
    /// A known unit.
    Known(Unit),
    /// Any unit.
    Free,
}

impl fmt::Display for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Dim::Known(u) => write!(f, "{u}"),
            Dim::Free => f.write_str("any unit"),
        }
    }
}

enum Ty {
    Num(Dim),
    Bool,
}

/// Resolves the names of `expr` against `names` and checks its units; the
/// result's unit must be `unit` when one is declared. Returns the resolved
/// expression (names replaced by inputs and constants) and its unit.
pub fn check(expr: &Expr, names: &[Name], unit: Option<&Unit>) -> Result<(Expr, Dim), ExprError> {
    let mut resolved = expr.clone();
    let ty = check_node(&mut resolved, names)?;
    let dim = match ty {
        Ty::Bool => {
            return Err(ExprError::new(
                expr.span,
                "the formula is a comparison, not a number",
                Some("use comparisons as the condition of `if(condition, then, else)`".into()),
            ));
        }
        Ty::Num(d) => d,
    };
    if let (Some(want), Dim::Known(got)) = (unit, &dim)
        && want != got
    {
        return Err(ExprError::new(
            Span { start: 0, end: 0 },
            format!("the formula gives {got}, but the quantity's `unit` is {want}"),
            Some("change the formula or the `unit`; units are checked symbol by symbol (mS and uS differ)".into()),
        ));
    }
    Ok((resolved, dim))
}

fn number(e: &mut Expr, names: &[Name], what: &str) -> Result<Dim, ExprError> {
    match check_node(e, names)? {
        Ty::Num(d) => Ok(d),
        Ty::Bool => Err(ExprError::new(
            e.span,
            format!("a comparison is not a number ({what})"),
            Some("use comparisons only as the condition of `if(condition, then, else)`".into()),
        )),
    }
}

fn same(a: Dim, b: Dim, span: Span, what: &str) -> Result<Dim, ExprError> {
    match (a, b) {
        (Dim::Free, d) | (d, Dim::Free) => Ok(d),
        (Dim::Known(a), Dim::Known(b)) if a == b => Ok(Dim::Known(a)),
        (Dim::Known(a), Dim::Known(b)) => Err(ExprError::new(
            span,
            format!("{what} needs equal units: {a} on the left, {b} on the right"),
            Some("convert one side first; units are checked symbol by symbol (degC and K differ)".into()),
        )),
    }
}

fn check_node(e: &mut Expr, names: &[Name]) -> Result<Ty, ExprError> {
    let span = e.span;
    let ty = match &mut e.node {
        Node::Num(_) => Ty::Num(Dim::Free),
        Node::Input(..) | Node::Const(..) => Ty::Num(Dim::Free),
        Node::Name(name) => {
            let Some(found) = names.iter().find(|n| n.name == *name) else {
                let all: Vec<&str> = names.iter().map(|n| n.name.as_str()).collect();
                let list = if all.is_empty() { "none".to_string() } else { all.join(", ") };
                let help = match crate::suggest::closest(name, &all) {
                    Some(best) => format!("did you mean `{best}`? names: {list}"),
                    None => format!("a formula names the quantity's inputs and the sensor's constants: {list}"),
                };
                return Err(ExprError::new(span, format!("unknown name `{name}`"), Some(help)));
            };
            let dim = found.unit.clone().map_or(Dim::Free, Dim::Known);
            e.node = match found.binding {
                Binding::Input(i) => Node::Input(i, found.name.clone()),
                Binding::Const(v) => Node::Const(found.name.clone(), v),
            };
            Ty::Num(dim)
        }
        Node::Neg(x) => Ty::Num(number(x, names, "`-`")?),
        Node::Bin(op, a, b) => {
            let op = *op;
            let whole = b.whole_literal();
            let da = number(a, names, "an operand")?;
            let db = number(b, names, "an operand")?;
            Ty::Num(match op {
                Op::Add => same(da, db, span, "`+`")?,
                Op::Sub => same(da, db, span, "`-`")?,
                Op::Mul | Op::Div => match (da, db) {
                    (Dim::Known(x), Dim::Known(y)) => Dim::Known(x.times(&y, if op == Op::Mul { 1 } else { -1 })),
                    _ => Dim::Free,
                },
                Op::Pow => {
                    if let Dim::Known(u) = &db
                        && !u.is_dimensionless()
                    {
                        return Err(ExprError::new(
                            span,
                            format!("the exponent of `^` must be dimensionless, not {u}"),
                            None,
                        ));
                    }
                    match da {
                        Dim::Known(u) if !u.is_dimensionless() => match whole {
                            Some(n) => Dim::Known(u.power(n)),
                            None => {
                                return Err(ExprError::new(
                                    span,
                                    format!("a quantity in {u} can only be raised to a whole number written as such"),
                                    Some("write `x^2`, or divide `x` by its unit's scale first".into()),
                                ));
                            }
                        },
                        other => other,
                    }
                }
            })
        }
        Node::Call(f, x) => {
            let name = if *f == Func::Exp { "exp" } else { "ln" };
            let d = number(x, names, name)?;
            if let Dim::Known(u) = &d
                && !u.is_dimensionless()
            {
                return Err(ExprError::new(
                    span,
                    format!("`{name}` takes a dimensionless argument, not {u}"),
                    Some("divide the argument by a reference value in the same unit".into()),
                ));
            }
            Ty::Num(Dim::Known(Unit::default()))
        }
        Node::Cmp(op, a, b) => {
            let what = format!("`{}`", op.symbol());
            let da = number(a, names, "a comparison's operand")?;
            let db = number(b, names, "a comparison's operand")?;
            same(da, db, span, &what)?;
            Ty::Bool
        }
        Node::If(c, a, b) => {
            if !matches!(check_node(c, names)?, Ty::Bool) {
                return Err(ExprError::new(
                    c.span,
                    "the condition of `if` must be a comparison",
                    Some("write `if(x < 0, a, b)`".into()),
                ));
            }
            let da = number(a, names, "a branch of `if`")?;
            let db = number(b, names, "a branch of `if`")?;
            Ty::Num(same(da, db, span, "`if`")?)
        }
    };
    Ok(ty)
}

/// Every name `expr` uses, once each, in order of first use.
pub fn names_used(expr: &Expr) -> Vec<String> {
    fn walk(e: &Expr, out: &mut Vec<String>) {
        match &e.node {
            Node::Name(n) | Node::Input(_, n) | Node::Const(n, _) => {
                if !out.contains(n) {
                    out.push(n.clone());
                }
            }
            Node::Num(_) => {}
            Node::Neg(x) | Node::Call(_, x) => walk(x, out),
            Node::Bin(_, a, b) | Node::Cmp(_, a, b) => {
                walk(a, out);
                walk(b, out);
            }
            Node::If(c, a, b) => {
                walk(c, out);
                walk(a, out);
                walk(b, out);
            }
        }
    }
    let mut out = Vec::new();
    walk(expr, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::super::parse;
    use super::super::tests::{err, run};
    use super::*;

    #[test]
    fn units_check() {
        assert!(run("c * 1000", Some("uS/cm"), &[1.0]).is_ok(), "a bare factor converts");
        assert!(run("t + 273.15", Some("degC"), &[1.0, 1.0]).is_ok(), "a bare term takes the unit");
        assert!(run("c * c", Some("mS^2/cm^2"), &[1.0]).is_ok());
        assert!(run("c^2", Some("mS^2/cm^2"), &[1.0]).is_ok());
        assert!(run("c / c", Some("1"), &[1.0]).is_ok());
        assert!(run("exp(t / 100)", Some("1"), &[1.0, 1.0]).is_ok());
        assert!(run("s + c", Some("mS/cm"), &[1.0, 1.0, 1.0]).is_ok(), "an undeclared unit is free");
        assert!(err("c + t", None).message.contains("`+` needs equal units: mS/cm on the left, degC on the right"));
        assert!(err("c - t", None).message.contains("`-` needs equal units"));
        assert!(err("if(c < t, 1, 2)", None).message.contains("`<` needs equal units"));
        assert!(err("if(c < 1, c, t)", None).message.contains("`if` needs equal units"));
        assert!(err("exp(t)", None).message.contains("`exp` takes a dimensionless argument, not degC"));
        assert!(err("ln(c)", None).message.contains("`ln` takes a dimensionless argument"));
        assert!(err("c^1.5", None).message.contains("whole number"));
        assert!(err("2^t", None).message.contains("exponent"));
        assert!(run("c * 2", None, &[1.0]).is_ok());
        let e = err("c * c", Some("mS/cm"));
        assert!(e.message.contains("the formula gives mS^2/cm^2, but the quantity's `unit` is mS/cm"), "{e:?}");
        assert!(err("t < 1", None).message.contains("comparison, not a number"));
        assert!(err("(t < 1) + 1", None).message.contains("a comparison is not a number"));
        assert!(err("if(t, 1, 2)", None).message.contains("condition of `if` must be a comparison"));
    }

    #[test]
    fn names_in_order() {
        let e = parse("t * c + exp(t) - k").unwrap();
        assert_eq!(names_used(&e), ["t", "c", "k"]);
    }
}
