//! A formula's text to its tree: a lexer and a recursive-descent parser
//! whose errors point at the offending token.

use super::{Cmp, Expr, ExprError, FUNCTION_NAMES, Func, Node, Op, Span};

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

/// Parses a formula. Names stay unresolved until [`check`](fn@super::check).
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

#[cfg(test)]
mod tests {
    use super::super::tests::err;
    use super::*;

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
}
