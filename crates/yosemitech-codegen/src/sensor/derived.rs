//! Derived quantities: formulas as Rust expressions and the `DERIVED` table.

use std::fmt::Write as _;

use proc_macro2::{Ident, Literal, TokenStream};
use quote::quote;
use yosemitech_spec::expr::{Cmp, Func, Node, Op, Power};
use yosemitech_spec::{Derived, InputSource, Sensor};

use super::constants::f64_lit;
use super::ident;
use crate::text::{self, doc, lit, one_line, opt_lit};

/// The tokens of a formula, parenthesized only where Rust's precedence
/// would read it otherwise (the parse tree is kept exactly, so the
/// arithmetic is done in the same order as the interpreter's).
fn formula(e: &yosemitech_spec::expr::Expr) -> (TokenStream, u8) {
    // 3: an operand (a number, a name, a call), 2: a product, 1: a sum, 0: a condition.
    let wrap = |(t, p): (TokenStream, u8), min: u8| if p >= min { t } else { quote!((#t)) };
    match &e.node {
        Node::Num(v) => (f64_lit(*v), 3),
        Node::Input(_, name) => {
            let n = ident(name);
            (quote!(#n), 3)
        }
        Node::Const(name, _) => {
            let c = ident(&yosemitech_spec::names::shouty(name));
            (quote!(f64::from(#c)), 3)
        }
        Node::Name(name) => {
            let n = ident(name);
            (quote!(#n), 3)
        }
        Node::Neg(x) => {
            let x = wrap(formula(x), 3);
            (quote!(-#x), 3)
        }
        Node::Bin(Op::Pow, base, exponent) => match Power::of(base, exponent) {
            Power::Whole(n) => {
                let (a, n) = (formula(base).0, Literal::i32_unsuffixed(n));
                (quote!(rtu::derived::powi(#a, #n)), 3)
            }
            Power::OfNumber { base, ln_base } => {
                // The logarithms `core` names, by name; another base's as a number.
                let ln = match base {
                    10.0 => quote!(core::f64::consts::LN_10),
                    2.0 => quote!(core::f64::consts::LN_2),
                    _ => f64_lit(ln_base),
                };
                let (base, b) = (f64_lit(base), formula(exponent).0);
                (quote!(rtu::derived::pow_positive(#base, #ln, #b)), 3)
            }
            Power::General => {
                let (a, b) = (formula(base).0, formula(exponent).0);
                (quote!(rtu::derived::pow(#a, #b)), 3)
            }
        },
        Node::Bin(op, a, b) => {
            let prec = if matches!(op, Op::Add | Op::Sub) { 1 } else { 2 };
            let a = wrap(formula(a), prec);
            let b = wrap(formula(b), prec + 1);
            let t = match op {
                Op::Add => quote!(#a + #b),
                Op::Sub => quote!(#a - #b),
                Op::Mul => quote!(#a * #b),
                _ => quote!(#a / #b),
            };
            (t, prec)
        }
        Node::Call(f, x) => {
            let x = formula(x).0;
            let t = match f {
                Func::Exp => quote!(rtu::derived::exp(#x)),
                Func::Ln => quote!(rtu::derived::ln(#x)),
            };
            (t, 3)
        }
        Node::Cmp(op, a, b) => {
            let (a, b) = (formula(a).0, formula(b).0);
            let f = ident(match op {
                Cmp::Lt => "lt",
                Cmp::Le => "le",
                Cmp::Gt => "gt",
                Cmp::Ge => "ge",
                Cmp::Eq => "eq",
                Cmp::Ne => "ne",
            });
            (quote!(rtu::derived::#f(#a, #b)?), 0)
        }
        Node::If(c, a, b) => {
            let (c, a, b) = (formula(c).0, formula(a).0, formula(b).0);
            (quote!(if #c { #a } else { #b }), 0)
        }
    }
}

fn input_source(i: &yosemitech_spec::DerivedInput) -> String {
    match &i.source {
        InputSource::Field { command, field } => format!("the field `{field}` of `{command}`"),
        InputSource::Station(name) => format!("the station's `{name}`"),
    }
}

fn opt_range(range: Option<(f64, f64)>) -> TokenStream {
    match range {
        Some((min, max)) => {
            let (min, max) = (f64_lit(min), f64_lit(max));
            quote!(Some((#min, #max)))
        }
        None => quote!(None),
    }
}

/// `pub fn <quantity>(inputs: f32...) -> Result<f32, NotComputable>`.
pub(super) fn derived_fn(d: &Derived) -> TokenStream {
    let name = ident(&d.name);
    let mut text = format!("{}.\n\n{}", one_line(&d.title).trim_end_matches('.'), text::clean(&d.doc).trim_end());
    let _ = write!(text, "\n\nFormula (from the spec): `{}`", one_line(&d.expr).replace('`', "'"));
    match &d.unit {
        Some(unit) => {
            let _ = write!(text, ", in {}.", one_line(unit));
        }
        None => text.push('.'),
    }
    if let Some(source) = d.source.as_ref().and_then(text::source) {
        let _ = write!(text, "\n\n{source}");
    }
    text.push_str("\n\n# Inputs\n");
    for i in &d.inputs {
        let _ = write!(text, "\n- `{}`: {}", i.name, input_source(i));
        if let Some(unit) = &i.unit {
            let _ = write!(text, ", in {}", one_line(unit));
        }
        if let Some((min, max)) = i.range {
            let _ = write!(text, ", taken in {min}..={max}");
        }
        if let Some(default) = i.default {
            let _ = write!(text, " (default {default})");
        }
        text.push('.');
    }
    if !d.examples.is_empty() {
        text.push_str("\n\n# Examples\n");
        for e in &d.examples {
            let args: Vec<String> = d
                .inputs
                .iter()
                .map(|i| e.inputs.get(&i.name).or(i.default.as_ref()).map_or_else(String::new, |v| format!("{v:?}")))
                .collect();
            let _ = write!(text, "\n- `{}({})` is {}", d.name, args.join(", "), e.value);
            if let Some(unit) = &d.unit {
                let _ = write!(text, " {}", one_line(unit));
            }
            if e.tolerance > 0.0 {
                let _ = write!(text, " within {}", e.tolerance);
            }
            let _ = write!(text, ": {}", one_line(&e.doc));
        }
    }
    text.push_str(
        "\n\n# Errors\n\n`NotComputable` when an input is NaN, infinite or outside its range, or when \
         the formula has no finite value for the inputs.",
    );
    let docs = doc(&text);
    let params: Vec<TokenStream> = d
        .inputs
        .iter()
        .map(|i| {
            let n = ident(&i.name);
            quote!(#n: f32)
        })
        .collect();
    let checks: Vec<TokenStream> = d
        .inputs
        .iter()
        .map(|i| {
            let n = ident(&i.name);
            let l = lit(&i.name);
            let range = opt_range(i.range);
            quote!(let #n = rtu::derived::input(#l, #n, #range)?;)
        })
        .collect();
    let body = formula(&d.formula).0;
    quote! {
        #docs
        pub fn #name(#(#params),*) -> Result<f32, rtu::NotComputable> {
            #(#checks)*
            rtu::derived::output(#body)
        }
    }
}

/// `DERIVED`: every derived quantity as data, each computed through its function.
pub(super) fn derived_table(s: &Sensor) -> TokenStream {
    let entries: Vec<TokenStream> = s
        .derived
        .iter()
        .map(|d| {
            let name = lit(&d.name);
            let f = ident(&d.name);
            let title = lit(&one_line(&d.title));
            let unit = opt_lit(d.unit.as_deref().map(one_line).as_deref());
            let expr = lit(&one_line(&d.expr));
            let n = Literal::usize_unsuffixed(d.inputs.len());
            let inputs: Vec<TokenStream> = d
                .inputs
                .iter()
                .map(|i| {
                    let name = lit(&i.name);
                    let source = match &i.source {
                        InputSource::Field { command, field } => {
                            let (c, f) = (lit(command), lit(field));
                            quote!(rtu::InputSource::Field { command: #c, field: #f })
                        }
                        InputSource::Station(station) => {
                            let st = lit(station);
                            quote!(rtu::InputSource::Station { name: #st })
                        }
                    };
                    let unit = opt_lit(i.unit.as_deref().map(one_line).as_deref());
                    let default = match i.default {
                        Some(v) => {
                            let v = f64_lit(v);
                            quote!(Some(#v))
                        }
                        None => quote!(None),
                    };
                    let range = opt_range(i.range);
                    quote!(rtu::DerivedInput { name: #name, source: #source, unit: #unit, default: #default, range: #range })
                })
                .collect();
            let args: Vec<Ident> = d.inputs.iter().map(|i| ident(&i.name)).collect();
            quote! {
                rtu::DerivedInfo {
                    name: #name,
                    title: #title,
                    unit: #unit,
                    expr: #expr,
                    inputs: &[#(#inputs),*],
                    compute: |inputs| match *inputs {
                        [#(#args),*] => #f(#(#args),*),
                        _ => Err(rtu::NotComputable::Inputs { expected: #n, given: inputs.len() }),
                    },
                }
            }
        })
        .collect();
    quote! {
        /// Every derived quantity of the sensor as data, in spec order: its
        /// inputs, and its function (`compute` takes the inputs in parameter order).
        pub const DERIVED: &[rtu::DerivedInfo] = &[#(#entries),*];
    }
}
