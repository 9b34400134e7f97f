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

use std::collections::BTreeMap;
use std::fmt;

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

    fn holds(self, a: f64, b: f64) -> bool {
        match self {
            Cmp::Lt => a < b,
            Cmp::Le => a <= b,
            Cmp::Gt => a > b,
            Cmp::Ge => a >= b,
            Cmp::Eq => a == b,
            Cmp::Ne => a != b,
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

    /// The value for `inputs` (by index), in `f64`; `None` where a
    /// comparison meets a NaN. A non-finite number is returned as such.
    pub fn eval(&self, inputs: &[f64]) -> Option<f64> {
        Some(match &self.node {
            Node::Num(v) | Node::Const(_, v) => *v,
            Node::Input(i, _) => *inputs.get(*i)?,
            Node::Name(_) | Node::Cmp(..) => return None,
            Node::Neg(x) => -x.eval(inputs)?,
            Node::Bin(op, a, b) => {
                let (a, b) = (a.eval(inputs)?, b.eval(inputs)?);
                match op {
                    Op::Add => a + b,
                    Op::Sub => a - b,
                    Op::Mul => a * b,
                    Op::Div => a / b,
                    Op::Pow => a.powf(b),
                }
            }
            Node::Call(Func::Exp, x) => x.eval(inputs)?.exp(),
            Node::Call(Func::Ln, x) => x.eval(inputs)?.ln(),
            Node::If(c, a, b) => {
                if c.condition(inputs)? {
                    a.eval(inputs)?
                } else {
                    b.eval(inputs)?
                }
            }
        })
    }

    fn condition(&self, inputs: &[f64]) -> Option<bool> {
        let Node::Cmp(op, a, b) = &self.node else { return None };
        let (a, b) = (a.eval(inputs)?, b.eval(inputs)?);
        if a.is_nan() || b.is_nan() { None } else { Some(op.holds(a, b)) }
    }
}

// ----------------------------------------------------------------------------
// Units.

/// A unit: symbols with their (non-zero) integer powers; empty is dimensionless.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Unit(pub BTreeMap<String, i32>);

impl Unit {
    /// True for a unit without symbols.
    pub fn is_dimensionless(&self) -> bool {
        self.0.is_empty()
    }

    fn times(&self, other: &Unit, sign: i32) -> Unit {
        let mut out = self.0.clone();
        for (s, p) in &other.0 {
            let e = out.entry(s.clone()).or_insert(0);
            *e += sign * p;
            if *e == 0 {
                out.remove(s);
            }
        }
        Unit(out)
    }

    fn power(&self, n: i32) -> Unit {
        if n == 0 {
            return Unit::default();
        }
        Unit(self.0.iter().map(|(s, p)| (s.clone(), p * n)).collect())
    }

    /// Parses a unit as the spec writes it: symbols joined by `*`, `·` or
    /// spaces, `/` dividing by the symbol after it, ` per ` dividing by
    /// everything after it, `^n` (or `^-n`) powers; `1` or nothing for
    /// dimensionless.
    pub fn parse(text: &str) -> Result<Unit, String> {
        let text = text.trim();
        let (num, den) = match text.split_once(" per ") {
            Some((n, d)) => (n, Some(d)),
            None => (text, None),
        };
        let mut unit = parse_product(num)?;
        if let Some(d) = den {
            unit = unit.times(&parse_product(d)?, -1);
        }
        Ok(unit)
    }
}

fn parse_product(text: &str) -> Result<Unit, String> {
    let mut unit = Unit::default();
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    let mut sign = 1;
    let mut expect_factor = true;
    while i < chars.len() {
        let c = chars[i];
        if c == ' ' || c == '*' || c == '·' {
            i += 1;
            continue;
        }
        if c == '/' {
            if expect_factor && i > 0 {
                return Err(format!("`{text}`: `/` follows no symbol"));
            }
            sign = -1;
            expect_factor = true;
            i += 1;
            continue;
        }
        let start = i;
        while i < chars.len() && (chars[i].is_alphanumeric() || matches!(chars[i], '%' | '°' | 'µ' | '_')) {
            i += 1;
        }
        if i == start {
            return Err(format!("`{text}`: `{c}` is not part of a unit symbol"));
        }
        let symbol: String = chars[start..i].iter().collect();
        let mut power = 1i32;
        if chars.get(i) == Some(&'^') {
            i += 1;
            let from = i;
            if chars.get(i) == Some(&'-') {
                i += 1;
            }
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
            }
            let digits: String = chars[from..i].iter().collect();
            power = digits.parse().map_err(|_| format!("`{text}`: `^` takes a whole number"))?;
        }
        if symbol != "1" {
            if symbol.starts_with(|c: char| c.is_ascii_digit()) {
                return Err(format!("`{text}`: `{symbol}` is not a unit symbol"));
            }
            unit = unit.times(&Unit(BTreeMap::from([(symbol, power)])), sign);
        }
        sign = 1;
        expect_factor = false;
    }
    if expect_factor && !chars.is_empty() && text.trim_end().ends_with('/') {
        return Err(format!("`{text}`: `/` is followed by no symbol"));
    }
    Ok(unit)
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("1 (dimensionless)");
        }
        let mut first = true;
        for (s, p) in self.0.iter().filter(|(_, p)| **p > 0) {
            if !first {
                f.write_str("*")?;
            }
            first = false;
            if *p == 1 { write!(f, "{s}")? } else { write!(f, "{s}^{p}")? }
        }
        if first {
            f.write_str("1")?;
        }
        for (s, p) in self.0.iter().filter(|(_, p)| **p < 0) {
            if *p == -1 { write!(f, "/{s}")? } else { write!(f, "/{s}^{}", -p)? }
        }
        Ok(())
    }
}

// ----------------------------------------------------------------------------
// Parsing.

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(char),
    Cmp(Cmp),
    LParen,
    RParen,
    Comma,
    End,
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Num(v) => format!("the number `{v}`"),
        Tok::Name(n) => format!("the name `{n}`"),
        Tok::Op(c) => format!("`{c}`"),
        Tok::Cmp(c) => format!("`{}`", c.symbol()),
        Tok::LParen => "`(`".into(),
        Tok::RParen => "`)`".into(),
        Tok::Comma => "`,`".into(),
        Tok::End => "the end of the formula".into(),
    }
}

fn lex(src: &str) -> Result<Vec<(Tok, Span)>, ExprError> {
    let bytes = src.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        let start = i;
        match c {
            b' ' | b'\t' | b'\n' | b'\r' => {
                i += 1;
                continue;
            }
            b'0'..=b'9' | b'.' => {
                while i < bytes.len() && (bytes[i].is_ascii_digit() || bytes[i] == b'.') {
                    i += 1;
                }
                if i < bytes.len() && (bytes[i] == b'e' || bytes[i] == b'E') {
                    let mut j = i + 1;
                    if j < bytes.len() && (bytes[j] == b'+' || bytes[j] == b'-') {
                        j += 1;
                    }
                    if j < bytes.len() && bytes[j].is_ascii_digit() {
                        i = j;
                        while i < bytes.len() && bytes[i].is_ascii_digit() {
                            i += 1;
                        }
                    }
                }
                let text = &src[start..i];
                let span = Span { start, end: i };
                let value: f64 = text.parse().map_err(|_| {
                    ExprError::new(
                        span,
                        format!("`{text}` is not a number"),
                        Some("write numbers as `12`, `0.64` or `1.5e-3`".into()),
                    )
                })?;
                out.push((Tok::Num(value), span));
                continue;
            }
            b'a'..=b'z' | b'A'..=b'Z' | b'_' => {
                while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
                    i += 1;
                }
                out.push((Tok::Name(src[start..i].to_string()), Span { start, end: i }));
                continue;
            }
            _ => {}
        }
        let two = src.get(i..i + 2).unwrap_or("");
        let (tok, len) = match (c, two) {
            (_, "<=") => (Tok::Cmp(Cmp::Le), 2),
            (_, ">=") => (Tok::Cmp(Cmp::Ge), 2),
            (_, "==") => (Tok::Cmp(Cmp::Eq), 2),
            (_, "!=") => (Tok::Cmp(Cmp::Ne), 2),
            (b'<', _) => (Tok::Cmp(Cmp::Lt), 1),
            (b'>', _) => (Tok::Cmp(Cmp::Gt), 1),
            (b'+' | b'-' | b'*' | b'/' | b'^', _) => (Tok::Op(char::from(c)), 1),
            (b'(', _) => (Tok::LParen, 1),
            (b')', _) => (Tok::RParen, 1),
            (b',', _) => (Tok::Comma, 1),
            _ => {
                let ch = src[i..].chars().next().unwrap_or('?');
                let span = Span { start: i, end: i + ch.len_utf8() };
                let help = match ch {
                    '=' => "compare with `==`; the language has no assignment".to_string(),
                    '&' | '|' | '!' => "the language has no logical operators; nest `if(...)` instead".to_string(),
                    _ => {
                        "formulas hold numbers, names, + - * / ^, parentheses, exp(), ln(), comparisons and if(c, a, b)"
                            .to_string()
                    }
                };
                return Err(ExprError::new(
                    span,
                    format!("`{}` is not part of the formula language", ch.escape_default()),
                    Some(help),
                ));
            }
        };
        out.push((tok, Span { start: i, end: i + len }));
        i += len;
    }
    out.push((Tok::End, Span { start: src.len(), end: src.len() }));
    Ok(out)
}

/// Deepest nesting a formula may have.
pub const MAX_DEPTH: usize = 64;

struct Parser {
    toks: Vec<(Tok, Span)>,
    at: usize,
    depth: usize,
}

impl Parser {
    fn peek(&self) -> &(Tok, Span) {
        self.toks.get(self.at).or(self.toks.last()).unwrap_or(&END)
    }

    fn bump(&mut self) -> (Tok, Span) {
        let t = self.peek().clone();
        if self.at < self.toks.len() {
            self.at += 1;
        }
        t
    }

    fn unexpected(&self, wanted: &str) -> ExprError {
        let (tok, span) = self.peek();
        ExprError::new(*span, format!("expected {wanted}, found {}", describe(tok)), None)
    }

    fn deeper(&mut self, span: Span) -> Result<(), ExprError> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(ExprError::new(span, format!("the formula nests deeper than {MAX_DEPTH} levels"), None));
        }
        Ok(())
    }

    fn expr(&mut self) -> Result<Expr, ExprError> {
        let left = self.sum()?;
        if let (Tok::Cmp(op), span) = self.peek().clone() {
            self.bump();
            let right = self.sum()?;
            if let (Tok::Cmp(_), again) = self.peek() {
                return Err(ExprError::new(
                    *again,
                    "comparisons do not chain",
                    Some("compare two numbers, and nest `if(...)` for more".into()),
                ));
            }
            return Ok(Expr::new(Node::Cmp(op, Box::new(left), Box::new(right)), span));
        }
        Ok(left)
    }

    fn sum(&mut self) -> Result<Expr, ExprError> {
        let mut left = self.term()?;
        while let (Tok::Op(c @ ('+' | '-')), span) = self.peek().clone() {
            self.bump();
            let right = self.term()?;
            let op = if c == '+' { Op::Add } else { Op::Sub };
            left = Expr::new(Node::Bin(op, Box::new(left), Box::new(right)), span);
        }
        Ok(left)
    }

    fn term(&mut self) -> Result<Expr, ExprError> {
        let mut left = self.unary()?;
        while let (Tok::Op(c @ ('*' | '/')), span) = self.peek().clone() {
            self.bump();
            let right = self.unary()?;
            let op = if c == '*' { Op::Mul } else { Op::Div };
            left = Expr::new(Node::Bin(op, Box::new(left), Box::new(right)), span);
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<Expr, ExprError> {
        if let (Tok::Op('-'), span) = self.peek().clone() {
            self.bump();
            self.deeper(span)?;
            let x = self.unary()?;
            self.depth -= 1;
            return Ok(Expr::new(Node::Neg(Box::new(x)), span));
        }
        self.power()
    }

    fn power(&mut self) -> Result<Expr, ExprError> {
        let base = self.atom()?;
        if let (Tok::Op('^'), span) = self.peek().clone() {
            self.bump();
            self.deeper(span)?;
            let exponent = self.unary()?;
            self.depth -= 1;
            return Ok(Expr::new(Node::Bin(Op::Pow, Box::new(base), Box::new(exponent)), span));
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Expr, ExprError> {
        let (tok, span) = self.peek().clone();
        match tok {
            Tok::Num(v) => {
                self.bump();
                Ok(Expr::new(Node::Num(v), span))
            }
            Tok::LParen => {
                self.bump();
                self.deeper(span)?;
                let inner = self.expr()?;
                self.depth -= 1;
                match self.bump() {
                    (Tok::RParen, _) => Ok(inner),
                    (tok, at) => Err(ExprError {
                        related: Some(span),
                        ..ExprError::new(
                            at,
                            format!("expected `)`, found {}", describe(&tok)),
                            Some("add the `)` that closes the `(`".into()),
                        )
                    }),
                }
            }
            Tok::Name(name) => {
                self.bump();
                if !matches!(self.peek().0, Tok::LParen) {
                    return Ok(Expr::new(Node::Name(name), span));
                }
                self.bump();
                self.deeper(span)?;
                let mut args = vec![self.expr()?];
                while matches!(self.peek().0, Tok::Comma) {
                    self.bump();
                    args.push(self.expr()?);
                }
                self.depth -= 1;
                match self.bump() {
                    (Tok::RParen, _) => {}
                    (tok, at) => {
                        return Err(ExprError::new(
                            at,
                            format!("expected `,` or `)`, found {}", describe(&tok)),
                            Some(format!("close the call of `{name}`")),
                        ));
                    }
                }
                let want = match name.as_str() {
                    "exp" | "ln" => 1,
                    "if" => 3,
                    other => {
                        let known = match other {
                            "log" | "log10" | "log2" => {
                                Some("did you mean `ln`? (the natural logarithm; log10(x) is `ln(x) / ln(10)`)")
                            }
                            "pow" => Some("write `a ^ b` for a power"),
                            "sqrt" => Some("write `x ^ 0.5` for a square root"),
                            _ => None,
                        };
                        let help = match known.map(str::to_string).or_else(|| {
                            crate::suggest::closest(other, FUNCTION_NAMES).map(|b| format!("did you mean `{b}`?"))
                        }) {
                            Some(best) => format!("{best} the functions are exp(x), ln(x) and if(c, a, b)"),
                            None => "the functions are exp(x), ln(x) and if(c, a, b)".to_string(),
                        };
                        return Err(ExprError::new(span, format!("unknown function `{other}`"), Some(help)));
                    }
                };
                if args.len() != want {
                    return Err(ExprError::new(
                        span,
                        format!(
                            "`{name}` takes {want} argument{}, not {}",
                            if want == 1 { "" } else { "s" },
                            args.len()
                        ),
                        Some(if want == 3 {
                            "write `if(condition, then, else)`".into()
                        } else {
                            format!("write `{name}(x)`")
                        }),
                    ));
                }
                let mut args = args.into_iter();
                let mut next = || Box::new(args.next().unwrap_or_else(|| Expr::new(Node::Num(0.0), span)));
                Ok(match name.as_str() {
                    "exp" => Expr::new(Node::Call(Func::Exp, next()), span),
                    "ln" => Expr::new(Node::Call(Func::Ln, next()), span),
                    _ => {
                        let (c, a, b) = (next(), next(), next());
                        Expr::new(Node::If(c, a, b), span)
                    }
                })
            }
            _ => Err(self.unexpected("a number, a name or `(`")),
        }
    }
}

const END: (Tok, Span) = (Tok::End, Span { start: 0, end: 0 });

/// Parses a formula. Names stay unresolved until [`check`].
pub fn parse(src: &str) -> Result<Expr, ExprError> {
    let toks = lex(src)?;
    if toks.len() == 1 {
        return Err(ExprError::new(Span::default(), "the formula is empty", Some("write `expr: \"a * b\"`".into())));
    }
    let mut p = Parser { toks, at: 0, depth: 0 };
    let e = p.expr()?;
    match p.peek() {
        (Tok::End, _) => Ok(e),
        (Tok::RParen, span) => Err(ExprError::new(*span, "this `)` closes nothing", None)),
        _ => Err(p.unexpected("an operator or the end of the formula")),
    }
}

// ----------------------------------------------------------------------------
// Names and units.

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

/// The whole number `e` is, when it is one written as such (`2`, `-1`).
fn whole_literal(e: &Expr) -> Option<i32> {
    match &e.node {
        Node::Num(v) if v.fract() == 0.0 && v.abs() <= 64.0 => Some(*v as i32),
        Node::Neg(x) => whole_literal(x).map(|n| -n),
        _ => None,
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
            let whole = whole_literal(b);
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
    use super::*;

    fn unit(s: &str) -> Unit {
        Unit::parse(s).unwrap()
    }

    fn names() -> Vec<Name> {
        vec![
            Name { name: "c".into(), binding: Binding::Input(0), unit: Some(unit("mS/cm")) },
            Name { name: "t".into(), binding: Binding::Input(1), unit: Some(unit("degC")) },
            Name { name: "s".into(), binding: Binding::Input(2), unit: None },
            Name { name: "k".into(), binding: Binding::Const(0.5), unit: Some(unit("mg/L per mS/cm")) },
        ]
    }

    fn run(src: &str, unit_decl: Option<&str>, inputs: &[f64]) -> Result<Option<f64>, ExprError> {
        let e = parse(src)?;
        let decl = unit_decl.map(unit);
        let (e, _) = check(&e, &names(), decl.as_ref())?;
        Ok(e.eval(inputs))
    }

    fn err(src: &str, unit_decl: Option<&str>) -> ExprError {
        run(src, unit_decl, &[1.0, 2.0, 3.0]).unwrap_err()
    }

    #[test]
    fn units_parse() {
        assert_eq!(unit("mg/L"), Unit(BTreeMap::from([("mg".into(), 1), ("L".into(), -1)])));
        assert_eq!(unit("mg/L per uS/cm"), unit("mg*cm/L/uS"));
        assert_eq!(unit("m^2/s"), unit("m m / s"));
        assert!(unit("1").is_dimensionless());
        assert!(unit("").is_dimensionless());
        assert_eq!(unit("%").to_string(), "%");
        assert_eq!(unit("kPa^-1").to_string(), "1/kPa");
        assert!(Unit::parse("mg/").is_err());
        assert!(Unit::parse("m^x").is_err());
        assert!(Unit::parse("a+b").is_err());
    }

    #[test]
    fn precedence_and_values() {
        assert_eq!(run("1 + 2 * 3", None, &[]), Ok(Some(7.0)));
        assert_eq!(run("(1 + 2) * 3", None, &[]), Ok(Some(9.0)));
        assert_eq!(run("-2^2", None, &[]), Ok(Some(-4.0)));
        assert_eq!(run("2^3^2", None, &[]), Ok(Some(512.0)));
        assert_eq!(run("2^-1", None, &[]), Ok(Some(0.5)));
        assert_eq!(run("8 / 4 / 2", None, &[]), Ok(Some(1.0)));
        assert_eq!(run("10 - 4 - 3", None, &[]), Ok(Some(3.0)));
        assert_eq!(run("1.5e3 + .5", None, &[]), Ok(Some(1500.5)));
        assert_eq!(run("ln(exp(2))", None, &[]), Ok(Some(2.0)));
        assert_eq!(run("if(t < 0, 0, t)", Some("degC"), &[0.0, -5.0]), Ok(Some(0.0)));
        assert_eq!(run("if(t >= 0, t, 0)", Some("degC"), &[0.0, 5.0]), Ok(Some(5.0)));
        assert_eq!(run("if(t == 2, 1, 0) + if(t != 2, 10, 20)", None, &[0.0, 2.0]), Ok(Some(21.0)));
        assert_eq!(run("c * k", Some("mg/L"), &[2.0]), Ok(Some(1.0)));
        // A NaN in a comparison has no value.
        assert_eq!(run("if(t > 1, 1, 2)", None, &[0.0, f64::NAN]), Ok(None));
    }

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
    fn errors_point_at_the_token() {
        let e = err("c * tt", None);
        assert_eq!((e.span.start, e.span.end), (4, 6));
        assert_eq!(e.message, "unknown name `tt`");
        assert!(e.help.unwrap().contains("did you mean `t`?"));
        let e = err("c + t", None);
        assert_eq!(e.span.start, 2, "at the operator");
        let e = parse("log(c)").unwrap_err();
        assert_eq!(e.message, "unknown function `log`");
        assert!(e.help.unwrap().contains("did you mean `ln`?"));
        let e = parse("exp(1, 2)").unwrap_err();
        assert!(e.message.contains("takes 1 argument, not 2"));
        let e = parse("if(1 < 2, 3)").unwrap_err();
        assert!(e.message.contains("takes 3 arguments, not 2"));
        let e = parse("(c + 1").unwrap_err();
        assert_eq!(e.span.start, 6);
        assert!(e.message.contains("expected `)`"));
        let e = parse("c + ").unwrap_err();
        assert!(e.message.contains("found the end of the formula"));
        let e = parse("c = 1").unwrap_err();
        assert_eq!(e.span.start, 2);
        assert!(e.help.unwrap().contains("=="));
        let e = parse("c && t").unwrap_err();
        assert!(e.help.unwrap().contains("logical"));
        let e = parse("1 < 2 < 3").unwrap_err();
        assert!(e.message.contains("chain"));
        let e = parse("1..2").unwrap_err();
        assert!(e.message.contains("not a number"));
        assert!(parse("").unwrap_err().message.contains("empty"));
        assert!(parse("c)").unwrap_err().message.contains("closes nothing"));
        assert!(parse("c t").unwrap_err().message.contains("expected an operator"));
        let deep = format!("{}1{}", "(".repeat(100), ")".repeat(100));
        assert!(parse(&deep).unwrap_err().message.contains("nests deeper"));
        let minus = format!("{}1", "-".repeat(100));
        assert!(parse(&minus).is_err());
    }

    #[test]
    fn names_in_order() {
        let e = parse("t * c + exp(t) - k").unwrap();
        assert_eq!(names_used(&e), ["t", "c", "k"]);
    }
}
