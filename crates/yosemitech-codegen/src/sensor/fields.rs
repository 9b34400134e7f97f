//! Per-field facts and the tokens that decode, encode, check and document a field.

use std::fmt::Write as _;

use heck::ToUpperCamelCase;
use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};
use yosemitech_rtu::{ByteOrder2, ByteOrder4};
use yosemitech_spec::{CommandSpec, EnumRepr, Field, FieldKind};

use super::constants::{f32_lit, f64_lit};
use super::ident;
use crate::naming::Names;
use crate::text::{self, doc, hex, one_line};

/// Per-field facts for code generation.
pub(super) struct FieldGen<'a> {
    pub(super) field: &'a Field,
    pub(super) name: Ident,
    pub(super) ty: TokenStream,
}

pub(super) fn field_gens<'a>(names: &Names, ci: usize, c: &'a CommandSpec) -> Vec<FieldGen<'a>> {
    c.fields
        .iter()
        .enumerate()
        .filter_map(|(fi, f)| {
            let name = ident(f.name.as_deref()?);
            let ty = match &f.kind {
                FieldKind::F32 { .. } => quote!(f32),
                FieldKind::U8 => quote!(u8),
                FieldKind::I8 => quote!(i8),
                FieldKind::U16 { .. } => quote!(u16),
                FieldKind::I16 { .. } => quote!(i16),
                FieldKind::U32 { .. } => quote!(u32),
                FieldKind::I32 { .. } => quote!(i32),
                FieldKind::Ascii { len, .. } => {
                    let n = Literal::usize_unsuffixed(*len);
                    quote!(rtu::Ascii<#n>)
                }
                FieldKind::Version => quote!(rtu::Version),
                FieldKind::Bcd => quote!(rtu::Bcd),
                FieldKind::Flags { repr: EnumRepr::U8, .. } => quote!(u8),
                FieldKind::Flags { repr: EnumRepr::U16(_), .. } => quote!(u16),
                FieldKind::Enum { .. } => {
                    let e = names.enum_of.get(&(ci, fi)).and_then(|k| names.enums.get(*k))?;
                    let e = ident(&e.ty);
                    quote!(#e)
                }
                FieldKind::Reserved { .. } => return None,
            };
            Some(FieldGen { field: f, name, ty })
        })
        .collect()
}

/// `rtu::ByteOrder4::Dcba`: the variant is the order's name in CamelCase.
fn order4(o: ByteOrder4) -> TokenStream {
    let variant = format_ident!("{}", o.name().to_upper_camel_case());
    quote!(rtu::ByteOrder4::#variant)
}

/// `rtu::ByteOrder2::Ba`: the variant is the order's name in CamelCase.
pub(super) fn order2(o: ByteOrder2) -> TokenStream {
    let variant = format_ident!("{}", o.name().to_upper_camel_case());
    quote!(rtu::ByteOrder2::#variant)
}

/// The encoding of a field that fills the message's data alone, when its
/// encoder already returns the whole array.
pub(super) fn whole_data_encoding(g: &FieldGen<'_>) -> Option<TokenStream> {
    let name = &g.name;
    match &g.field.kind {
        FieldKind::F32 { order } => {
            let o = order4(*order);
            Some(quote!(rtu::codec::f32_to_wire(#o, self.#name)))
        }
        FieldKind::U16 { order } | FieldKind::Flags { repr: EnumRepr::U16(order), .. } => {
            let o = order2(*order);
            Some(quote!(rtu::codec::u16_to_wire(#o, self.#name)))
        }
        FieldKind::U32 { order } => {
            let o = order4(*order);
            Some(quote!(rtu::codec::u32_to_wire(#o, self.#name)))
        }
        FieldKind::Ascii { .. } | FieldKind::Version => Some(quote!(self.#name.to_wire())),
        _ => None,
    }
}

/// `[data[3], data[4], data[5], data[6]]`, or `*data` for all of it.
fn data_bytes(offset: usize, len: usize, data_len: usize) -> TokenStream {
    if offset == 0 && len == data_len {
        return quote!(*data);
    }
    let idx = (offset..offset + len).map(Literal::usize_unsuffixed);
    quote!([#(data[#idx]),*])
}

pub(super) fn decode_expr(g: &FieldGen<'_>, data_len: usize) -> TokenStream {
    let f = g.field;
    let b = data_bytes(f.offset, f.size(), data_len);
    let at = Literal::usize_unsuffixed(f.offset);
    let ty = &g.ty;
    match &f.kind {
        FieldKind::F32 { order } => {
            let o = order4(*order);
            quote!(rtu::codec::f32_from_wire(#o, #b))
        }
        FieldKind::U8 => quote!(data[#at]),
        FieldKind::I8 => quote!(i8::from_ne_bytes([data[#at]])),
        FieldKind::U16 { order } => {
            let o = order2(*order);
            quote!(rtu::codec::u16_from_wire(#o, #b))
        }
        FieldKind::I16 { order } => {
            let o = order2(*order);
            quote!(rtu::codec::u16_from_wire(#o, #b) as i16)
        }
        FieldKind::U32 { order } => {
            let o = order4(*order);
            quote!(rtu::codec::u32_from_wire(#o, #b))
        }
        FieldKind::I32 { order } => {
            let o = order4(*order);
            quote!(rtu::codec::u32_from_wire(#o, #b) as i32)
        }
        FieldKind::Ascii { padding, .. } => {
            let p = hex(u32::from(*padding), 2);
            quote!(rtu::Ascii::read(data, #at, #p))
        }
        FieldKind::Version => quote!(rtu::Version::from_wire(#b)),
        FieldKind::Bcd => quote!(rtu::Bcd(data[#at])),
        FieldKind::Flags { repr: EnumRepr::U8, .. } => quote!(data[#at]),
        FieldKind::Flags { repr: EnumRepr::U16(order), .. } => {
            let o = order2(*order);
            quote!(rtu::codec::u16_from_wire(#o, #b))
        }
        FieldKind::Enum { repr: EnumRepr::U8, .. } => quote!(#ty::from_raw(data[#at])),
        FieldKind::Enum { repr: EnumRepr::U16(order), .. } => {
            let o = order2(*order);
            quote!(#ty::from_raw(rtu::codec::u16_from_wire(#o, #b)))
        }
        FieldKind::Reserved { .. } => quote!(()),
    }
}

/// The wire bytes of a field: a statement binding `b<offset>..` (or nothing)
/// and one expression per byte.
pub(super) fn encode_field(g: &FieldGen<'_>) -> (TokenStream, Vec<TokenStream>) {
    let f = g.field;
    let name = &g.name;
    let bytes: Vec<Ident> = (f.offset..f.offset + f.size()).map(|i| format_ident!("b{}", i)).collect();
    let bind = |expr: TokenStream| -> (TokenStream, Vec<TokenStream>) {
        (quote!(let [#(#bytes),*] = #expr;), bytes.iter().map(|b| quote!(#b)).collect())
    };
    match &f.kind {
        FieldKind::F32 { order } => {
            let o = order4(*order);
            bind(quote!(rtu::codec::f32_to_wire(#o, self.#name)))
        }
        FieldKind::U8 => (TokenStream::new(), vec![quote!(self.#name)]),
        FieldKind::I8 => bind(quote!(self.#name.to_ne_bytes())),
        FieldKind::U16 { order } => {
            let o = order2(*order);
            bind(quote!(rtu::codec::u16_to_wire(#o, self.#name)))
        }
        FieldKind::I16 { order } => {
            let o = order2(*order);
            bind(quote!(rtu::codec::u16_to_wire(#o, self.#name as u16)))
        }
        FieldKind::U32 { order } => {
            let o = order4(*order);
            bind(quote!(rtu::codec::u32_to_wire(#o, self.#name)))
        }
        FieldKind::I32 { order } => {
            let o = order4(*order);
            bind(quote!(rtu::codec::u32_to_wire(#o, self.#name as u32)))
        }
        FieldKind::Ascii { .. } | FieldKind::Version => bind(quote!(self.#name.to_wire())),
        FieldKind::Bcd => (TokenStream::new(), vec![quote!(self.#name.0)]),
        FieldKind::Flags { repr: EnumRepr::U8, .. } => (TokenStream::new(), vec![quote!(self.#name)]),
        FieldKind::Flags { repr: EnumRepr::U16(order), .. } => {
            let o = order2(*order);
            bind(quote!(rtu::codec::u16_to_wire(#o, self.#name)))
        }
        FieldKind::Enum { repr: EnumRepr::U8, .. } => (TokenStream::new(), vec![quote!(self.#name.raw())]),
        FieldKind::Enum { repr: EnumRepr::U16(order), .. } => {
            let o = order2(*order);
            bind(quote!(rtu::codec::u16_to_wire(#o, self.#name.raw())))
        }
        FieldKind::Reserved { .. } => (TokenStream::new(), Vec::new()),
    }
}

pub(super) fn field_value(g: &FieldGen<'_>) -> TokenStream {
    let name = &g.name;
    match &g.field.kind {
        FieldKind::F32 { .. } => quote!(rtu::FieldValue::F32(self.#name)),
        FieldKind::U8
        | FieldKind::I8
        | FieldKind::U16 { .. }
        | FieldKind::I16 { .. }
        | FieldKind::U32 { .. }
        | FieldKind::I32 { .. } => quote!(rtu::FieldValue::Int(i64::from(self.#name))),
        FieldKind::Ascii { .. } => quote!(rtu::FieldValue::Text(self.#name.trimmed())),
        FieldKind::Version => quote!(rtu::FieldValue::Version(self.#name)),
        FieldKind::Bcd => quote!(rtu::FieldValue::Bcd(self.#name)),
        FieldKind::Flags { .. } => quote!(rtu::FieldValue::Int(i64::from(self.#name))),
        FieldKind::Enum { repr: EnumRepr::U8, .. } => {
            quote!(rtu::FieldValue::Enum { raw: u16::from(self.#name.raw()), name: self.#name.name() })
        }
        FieldKind::Enum { repr: EnumRepr::U16(_), .. } => {
            quote!(rtu::FieldValue::Enum { raw: self.#name.raw(), name: self.#name.name() })
        }
        FieldKind::Reserved { .. } => quote!(rtu::FieldValue::Int(0)),
    }
}

/// The condition under which a write's field is out of its spec range
/// (`None`: every value of the type is in range).
pub(super) fn range_violation(g: &FieldGen<'_>) -> Option<TokenStream> {
    let (min, max) = g.field.range?;
    let name = &g.name;
    // An integer is at least `min` when it is at least `min` rounded up (at
    // most `max` rounded down): the check needs no float, whatever the bounds.
    let int_bounds = |lo: f64, hi: f64| -> Option<(i64, i64)> {
        let (a, b) = (min.ceil().max(lo), max.floor().min(hi));
        (!min.is_nan() && !max.is_nan() && a <= b).then_some((a as i64, b as i64))
    };
    let int_check = |lo: i64, hi: i64, type_lo: i64, type_hi: i64| -> Option<TokenStream> {
        if lo <= type_lo && hi >= type_hi {
            return None;
        }
        let (lo, hi) = (Literal::i64_unsuffixed(lo), Literal::i64_unsuffixed(hi));
        Some(quote!(!(#lo..=#hi).contains(&self.#name)))
    };
    let float_check = || {
        let (lo, hi) = (f64_lit(min), f64_lit(max));
        quote!(!(#lo..=#hi).contains(&f64::from(self.#name)))
    };
    let (type_lo, type_hi): (i64, i64) = match &g.field.kind {
        FieldKind::Bcd => {
            // An invalid digit is never sent; in range means the digits' value.
            let (lo, hi) = (
                Literal::u8_unsuffixed(min.ceil().clamp(0.0, 99.0) as u8),
                Literal::u8_unsuffixed(max.floor().clamp(0.0, 99.0) as u8),
            );
            return Some(quote!(self.#name.value().is_none_or(|v| !(#lo..=#hi).contains(&v))));
        }
        FieldKind::F32 { .. } => {
            // Compared as f32, exactly (an f32 MCU has no f64 unit): a value is
            // at least `min` when it is at least the least f32 not below it,
            // at most `max` when at most the greatest f32 not above it.
            let (lo, hi) = (f32_lit(f32_at_or_above(min)), f32_lit(f32_at_or_below(max)));
            // NaN is not range-checked (the reference interpreter agrees): it is how
            // a logger writes "no value".
            return Some(quote!(!self.#name.is_nan() && !(#lo..=#hi).contains(&self.#name)));
        }
        FieldKind::U8 => (0, 255),
        FieldKind::I8 => (-128, 127),
        FieldKind::U16 { .. } => (0, 65535),
        FieldKind::I16 { .. } => (-32768, 32767),
        FieldKind::U32 { .. } => (0, i64::from(u32::MAX)),
        FieldKind::I32 { .. } => (i64::from(i32::MIN), i64::from(i32::MAX)),
        _ => return None,
    };
    match int_bounds(type_lo as f64, type_hi as f64) {
        Some((lo, hi)) => int_check(lo, hi, type_lo, type_hi),
        // No value of the type is in range.
        None => Some(float_check()),
    }
}

/// The least f32 at or above `bound` (infinity above the f32 range).
fn f32_at_or_above(bound: f64) -> f32 {
    // Rounding is the point: the nearest f32, then a step when it fell below.
    #[allow(clippy::cast_possible_truncation)]
    let near = bound as f32;
    if f64::from(near) < bound { near.next_up() } else { near }
}

/// The greatest f32 at or below `bound` (minus infinity below the f32 range).
fn f32_at_or_below(bound: f64) -> f32 {
    #[allow(clippy::cast_possible_truncation)]
    let near = bound as f32;
    if f64::from(near) > bound { near.next_down() } else { near }
}

pub(super) fn field_doc(g: &FieldGen<'_>) -> TokenStream {
    let f = g.field;
    let mut d = f.doc.as_deref().map(one_line).unwrap_or_default();
    if let Some(unit) = &f.unit {
        if !d.is_empty() {
            d.push(' ');
        }
        let _ = write!(d, "Unit: {}.", one_line(unit));
    }
    let _ = write!(d, "\n\nWire: {}.", text::encoding(f));
    if let Some((min, max)) = f.range {
        let _ = write!(d, " Valid range {min}..={max}; encoding refuses other values.");
    }
    doc(&d)
}

#[cfg(test)]
mod tests {
    use super::{f32_at_or_above, f32_at_or_below};

    #[test]
    fn f32_bounds_are_the_nearest_on_their_side() {
        let bounds = [0.0, 14.0, 0.1, -0.1, 1.0 / 3.0, 1e-50, -1e-50, 1e39, -1e39, f64::from(f32::MAX), 16_777_217.0];
        for bound in bounds {
            let (lo, hi) = (f32_at_or_above(bound), f32_at_or_below(bound));
            assert!(f64::from(lo) >= bound && f64::from(lo.next_down()) < bound, "{bound}: {lo}");
            assert!(f64::from(hi) <= bound && f64::from(hi.next_up()) > bound, "{bound}: {hi}");
        }
    }
}
