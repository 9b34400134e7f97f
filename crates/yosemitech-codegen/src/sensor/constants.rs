//! Literals, constants and enumerations.

use std::fmt::Write as _;

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};
use yosemitech_spec::{Constant, ConstantType, EnumRepr, Sensor};

use super::{ident, unsupported};
use crate::Error;
use crate::naming::EnumDef;
use crate::text::{self, doc, hex, lit, one_line};

pub(super) fn f32_lit(v: f32) -> TokenStream {
    if v.is_nan() {
        quote!(f32::NAN)
    } else if v == f32::INFINITY {
        quote!(f32::INFINITY)
    } else if v == f32::NEG_INFINITY {
        quote!(f32::NEG_INFINITY)
    } else {
        let l = Literal::f32_unsuffixed(v);
        quote!(#l)
    }
}

pub(super) fn f64_lit(v: f64) -> TokenStream {
    if v.is_nan() {
        quote!(f64::NAN)
    } else if v == f64::INFINITY {
        quote!(f64::INFINITY)
    } else if v == f64::NEG_INFINITY {
        quote!(f64::NEG_INFINITY)
    } else {
        let l = Literal::f64_unsuffixed(v);
        quote!(#l)
    }
}

fn int_lit(s: &Sensor, c: &Constant, v: f64, max: f64) -> Result<TokenStream, Error> {
    if v.fract() != 0.0 || v < 0.0 || v > max {
        return Err(unsupported(s, format!("constant `{}`: {v} does not fit its type", c.name)));
    }
    // Checked integral and in range above.
    let l = Literal::u64_unsuffixed(v as u64);
    Ok(quote!(#l))
}

pub(super) fn constant(s: &Sensor, c: &Constant, name: &str) -> Result<TokenStream, Error> {
    let name = ident(name);
    let (ty, values) = match c.ty {
        ConstantType::F32 => (quote!(f32), c.values.iter().map(|v| f32_lit(*v as f32)).collect::<Vec<_>>()),
        ConstantType::U8 => {
            (quote!(u8), c.values.iter().map(|v| int_lit(s, c, *v, 255.0)).collect::<Result<Vec<_>, _>>()?)
        }
        ConstantType::U16 => {
            (quote!(u16), c.values.iter().map(|v| int_lit(s, c, *v, 65535.0)).collect::<Result<Vec<_>, _>>()?)
        }
        ConstantType::U32 => (
            quote!(u32),
            c.values.iter().map(|v| int_lit(s, c, *v, f64::from(u32::MAX))).collect::<Result<Vec<_>, _>>()?,
        ),
    };
    let mut d = one_line(&c.doc);
    if let Some(unit) = &c.unit {
        let _ = write!(d, "\n\nUnit: {}.", one_line(unit));
    }
    if let Some(source) = c.source.as_ref().and_then(text::source) {
        let _ = write!(d, "\n\n{source}");
    }
    let d = doc(&d);
    if c.is_list {
        let n = Literal::usize_unsuffixed(values.len());
        Ok(quote! {
            #d
            pub const #name: [#ty; #n] = [#(#values),*];
        })
    } else {
        let v = values.first().cloned().unwrap_or_else(|| quote!(0));
        Ok(quote! {
            #d
            pub const #name: #ty = #v;
        })
    }
}

fn enum_raw_ty(repr: EnumRepr) -> TokenStream {
    match repr {
        EnumRepr::U8 => quote!(u8),
        EnumRepr::U16(_) => quote!(u16),
    }
}

pub(super) fn enum_type(s: &Sensor, e: &EnumDef) -> Result<TokenStream, Error> {
    let ty = ident(&e.ty);
    let raw_ty = enum_raw_ty(e.repr);
    let mut variants = Vec::new();
    let mut from_arms = Vec::new();
    let mut raw_arms = Vec::new();
    let mut name_arms = Vec::new();
    let mut known = Vec::new();
    for v in &e.variants {
        let vi = format_ident!("{}", heck::ToUpperCamelCase::to_upper_camel_case(v.name.as_str()));
        let raw = match e.repr {
            EnumRepr::U8 => match u8::try_from(v.value) {
                Ok(b) => hex(u32::from(b), 2),
                Err(_) => {
                    return Err(unsupported(s, format!("enum `{}`: code {} does not fit one byte", e.ty, v.value)));
                }
            },
            EnumRepr::U16(_) => hex(u32::from(v.value), 4),
        };
        let mut d = v.doc.as_deref().map(one_line).unwrap_or_default();
        if !d.is_empty() {
            d.push(' ');
        }
        let width = if matches!(e.repr, EnumRepr::U8) { 2 } else { 4 };
        let _ = write!(d, "Code 0x{:0width$X}.", v.value);
        let d = doc(&d);
        let name = lit(&v.name);
        variants.push(quote!(#d #vi,));
        from_arms.push(quote!(#raw => Self::#vi,));
        raw_arms.push(quote!(Self::#vi => #raw,));
        name_arms.push(quote!(Self::#vi => Some(#name),));
        known.push(quote!(Self::#vi));
    }
    let mut d = e.doc.as_deref().map(one_line).unwrap_or_default();
    let size = match e.repr {
        EnumRepr::U8 => "one byte".to_owned(),
        EnumRepr::U16(order) => format!("two bytes, {}", text::order2(order)),
    };
    let _ = write!(
        d,
        "\n\nA code of {size} on the wire, used by {}.",
        e.used_by.iter().map(|u| format!("`{u}`")).collect::<Vec<_>>().join(", ")
    );
    d.push_str(" Codes the spec does not name decode to [`Self::Unknown`]; `from_raw` never returns `Unknown` for a named code.");
    d.push_str(
        " Non-exhaustive: a later manual may name another code, so a `match` outside this crate needs a `_` arm.",
    );
    let d = doc(&d);
    Ok(quote! {
        #d
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[non_exhaustive]
        pub enum #ty {
            #(#variants)*
            /// A code the spec does not name, as received.
            Unknown(#raw_ty),
        }

        impl #ty {
            /// Every named code, in spec order.
            pub const KNOWN: &[Self] = &[#(#known),*];

            /// The variant for a wire code.
            pub const fn from_raw(raw: #raw_ty) -> Self {
                match raw {
                    #(#from_arms)*
                    other => Self::Unknown(other),
                }
            }

            /// The wire code.
            pub const fn raw(self) -> #raw_ty {
                match self {
                    #(#raw_arms)*
                    Self::Unknown(raw) => raw,
                }
            }

            /// The spec's snake_case name of the code, `None` for [`Self::Unknown`].
            pub const fn name(self) -> Option<&'static str> {
                match self {
                    #(#name_arms)*
                    Self::Unknown(_) => None,
                }
            }
        }

        impl ::core::fmt::Display for #ty {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                match self.name() {
                    Some(name) => write!(f, "{name} ({})", self.raw()),
                    None => write!(f, "unknown ({})", self.raw()),
                }
            }
        }
    })
}
