//! A command's message types: structs, their `Message` impls and the `Command` impl.

use std::fmt::Write as _;

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};
use yosemitech_rtu::Function;
use yosemitech_spec::{CommandSpec, EnumRepr, FieldKind};

use super::constants::f32_lit;
use super::fields::{
    FieldGen, decode_expr, encode_field, field_doc, field_gens, field_value, range_violation, whole_data_encoding,
};
use super::ident;
use crate::naming::Names;
use crate::text::{self, doc, hex, lit, one_line, opt_lit};

/// Whether a message type gets `validate()`: write requests. On a read, a
/// range is the measuring range the user manual states: a probe may report
/// values outside it, so replies are never refused for it (the reference
/// interpreter agrees).
fn has_validate(_gens: &[FieldGen<'_>], write_request: bool) -> bool {
    write_request
}

fn message_impl(
    ty: &Ident,
    gens: &[FieldGen<'_>],
    c: &CommandSpec,
    with_data: bool,
    write_request: bool,
) -> TokenStream {
    let validated = with_data && has_validate(gens, write_request);
    let infos = gens.iter().map(|g| {
        let name = lit(g.field.display_name());
        let unit = opt_lit(g.field.unit.as_deref());
        quote!(rtu::FieldInfo::new(#name, #unit))
    });
    let mut extras = TokenStream::new();
    for g in gens {
        let name = &g.name;
        if let Some(absent) = g.field.absent {
            let method = format_ident!("{}_present", g.field.display_name());
            let ty = &g.ty;
            let sentinel = match &g.field.kind {
                FieldKind::F32 { .. } => f32_lit(absent as f32),
                _ => {
                    let v = Literal::i64_unsuffixed(absent as i64);
                    quote!(#v)
                }
            };
            let d = doc(&format!(
                "`{}`, or `None` where the device reads {absent}: the manual's value for a sub-probe that is not fitted (a real reading of exactly {absent} looks the same).",
                g.field.display_name()
            ));
            extras.extend(quote! {
                #d
                pub fn #method(&self) -> Option<#ty> {
                    if self.#name == #sentinel { None } else { Some(self.#name) }
                }
            });
        }
        if let FieldKind::Flags { flags, repr } = &g.field.kind {
            let raw_ty = match repr {
                EnumRepr::U8 => quote!(u8),
                EnumRepr::U16(_) => quote!(u16),
            };
            let consts = flags.iter().map(|f| {
                let c = format_ident!(
                    "{}_{}",
                    yosemitech_spec::names::shouty(g.field.display_name()),
                    yosemitech_spec::names::shouty(&f.name)
                );
                let m = hex(u32::from(f.mask), if matches!(repr, EnumRepr::U8) { 2 } else { 4 });
                let d = doc(&format!(
                    "Bit of `{}`: {}",
                    g.field.display_name(),
                    f.doc.as_deref().map(one_line).unwrap_or_else(|| f.name.clone())
                ));
                quote!(#d pub const #c: #raw_ty = #m;)
            });
            let method = format_ident!("{}_names", g.field.display_name());
            let pairs = flags.iter().map(|f| {
                let n = lit(&f.name);
                let m = hex(u32::from(f.mask), if matches!(repr, EnumRepr::U8) { 2 } else { 4 });
                quote!((#m, #n))
            });
            let count = Literal::usize_unsuffixed(flags.len());
            let d = doc(&format!(
                "The names of the flags set in `{}`, in mask order; bits no flag names are not listed.",
                g.field.display_name()
            ));
            extras.extend(quote! {
                #(#consts)*
                #d
                pub fn #method(&self) -> impl Iterator<Item = &'static str> + '_ {
                    const KNOWN: [(#raw_ty, &str); #count] = [#(#pairs),*];
                    KNOWN.into_iter().filter(move |(mask, _)| self.#name & mask != 0).map(|(_, name)| name)
                }
            });
        }
    }
    let inherent = if extras.is_empty() {
        TokenStream::new()
    } else {
        quote! {
            impl #ty {
                #extras
            }
        }
    };
    let len = if with_data { 2 * usize::from(c.count) } else { 0 };
    if gens.is_empty() && len == 0 {
        return quote! {
            #inherent
            impl rtu::NoData for #ty {}
        };
    }
    let len_lit = Literal::usize_unsuffixed(len);
    let from = if gens.is_empty() {
        quote! {
            fn from_data(_data: &[u8; #len_lit]) -> Self {
                Self
            }
        }
    } else {
        let inits = gens.iter().map(|g| {
            let name = &g.name;
            let e = decode_expr(g, len);
            quote!(#name: #e)
        });
        quote! {
            fn from_data(data: &[u8; #len_lit]) -> Self {
                Self { #(#inits),* }
            }
        }
    };
    // Every byte: a field's byte, a reserved byte's fill, or 0 for gaps.
    let mut slots: Vec<TokenStream> = (0..len).map(|_| quote!(0x00)).collect();
    for f in &c.fields {
        if let FieldKind::Reserved { len: rl, fill } = f.kind {
            for slot in slots.iter_mut().skip(f.offset).take(rl) {
                *slot = hex(u32::from(fill), 2);
            }
        }
    }
    let mut binds = Vec::new();
    let whole = match gens {
        [g] if g.field.offset == 0 && g.field.size() == len => whole_data_encoding(g),
        _ => None,
    };
    for g in gens {
        let (bind, bytes) = encode_field(g);
        binds.push(bind);
        for (slot, b) in slots.iter_mut().skip(g.field.offset).zip(bytes) {
            *slot = b;
        }
    }
    let to_body = whole.unwrap_or_else(|| {
        quote! {
            #(#binds)*
            [#(#slots),*]
        }
    });
    let arms = gens.iter().enumerate().map(|(i, g)| {
        let i = Literal::usize_unsuffixed(i);
        let value = field_value(g);
        quote!(#i => Some(#value),)
    });
    let field = if gens.is_empty() {
        quote! {
            fn field(&self, _index: usize) -> Option<rtu::FieldValue<'_>> {
                None
            }
        }
    } else {
        quote! {
            fn field(&self, index: usize) -> Option<rtu::FieldValue<'_>> {
                match index {
                    #(#arms)*
                    _ => None,
                }
            }
        }
    };
    let mut validate = TokenStream::new();
    if validated {
        let mut violations: Vec<(TokenStream, &FieldGen<'_>)> =
            gens.iter().filter_map(|g| Some((range_violation(g)?, g))).collect();
        for g in gens.iter().filter(|g| matches!(g.field.kind, FieldKind::Bcd) && g.field.range.is_none()) {
            let name = &g.name;
            violations.push((quote!(self.#name.value().is_none()), g));
        }
        if !violations.is_empty() {
            // One `if .. else if ..` chain: the first field out of range is named.
            let mut chain = quote!({ Ok(()) });
            for (violated, g) in violations.iter().rev() {
                let spec_name = lit(g.field.display_name());
                chain = quote! {
                    if #violated {
                        Err(rtu::EncodeError::OutOfRange { field: #spec_name })
                    } else #chain
                };
            }
            validate = quote! {
                fn validate(&self) -> Result<(), rtu::EncodeError> {
                    #chain
                }
            };
        }
    }
    quote! {
        #inherent

        impl rtu::Message for #ty {
            type Data = [u8; #len_lit];
            const FIELDS: &'static [rtu::FieldInfo] = &[#(#infos),*];

            #from

            fn to_data(&self) -> [u8; #len_lit] {
                #to_body
            }

            #field
            #validate
        }
    }
}

/// Who builds a message type decides its shape. A reply is built by the
/// generated crate's decoder, so it is `#[non_exhaustive]`: a field a later
/// manual names is then no breaking change for code that reads the others
/// (outside that crate a reply is read, matched with `..`, or made by
/// `Message::from_data`).
/// A request is built by its user and stays exhaustive: a field a later
/// manual adds to a write is something the device now needs, which every
/// caller must supply.
#[derive(Clone, Copy)]
enum Builder {
    User,
    Decoder,
}

fn struct_def(ty: &Ident, gens: &[FieldGen<'_>], docs: TokenStream, builder: Builder) -> TokenStream {
    let non_exhaustive = match builder {
        Builder::Decoder => quote!(#[non_exhaustive]),
        Builder::User => TokenStream::new(),
    };
    if gens.is_empty() {
        return quote! {
            #docs
            #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
            #non_exhaustive
            pub struct #ty;
        };
    }
    let has_float = gens.iter().any(|g| matches!(g.field.kind, FieldKind::F32 { .. }));
    let derives = if has_float {
        quote!(#[derive(Debug, Clone, Copy, PartialEq)])
    } else {
        quote!(#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)])
    };
    let members = gens.iter().map(|g| {
        let d = field_doc(g);
        let name = &g.name;
        let ty = &g.ty;
        quote!(#d pub #name: #ty)
    });
    quote! {
        #docs
        #derives
        #non_exhaustive
        pub struct #ty {
            #(#members),*
        }
    }
}

pub(super) fn command_doc(c: &CommandSpec) -> String {
    let mut d = format!("{}.\n\n", one_line(&c.title).trim_end_matches('.'));
    d.push_str(text::clean(&c.doc).trim_end());
    d.push_str("\n\n");
    if let Some(source) = text::source(&c.source) {
        let _ = write!(d, "{source} ");
    }
    let registers = if c.count == 1 { "register" } else { "registers" };
    match c.function {
        Function::Read => {
            let _ = write!(d, "Reads (function 0x03) {} {registers} at 0x{:04X}.", c.count, c.address);
        }
        Function::Write => {
            let _ = write!(d, "Writes (function 0x10) {} {registers} at 0x{:04X}.", c.count, c.address);
        }
    }
    match (c.trigger, c.function) {
        (true, Function::Write) => d.push_str(" A trigger: the write carries no data (byte count 0)."),
        (true, Function::Read) => d.push_str(
            " A trigger: a read used as a command. Its reply carries no value and is accepted with byte count 0 and no data, byte count 0 followed by the registers, or the registers with their byte count.",
        ),
        _ => {}
    }
    if let Some(since) = &c.since {
        let _ = write!(d, " Added in software revision {}.", one_line(since));
    }
    if let Some(role) = c.role {
        let _ = write!(d, " Role: `{}`.", role.name());
    }
    if let Some(slave) = c.fixed_slave {
        let _ = write!(
            d,
            " Always sent to slave 0x{slave:02X}, and the reply comes from 0x{slave:02X}, whatever the probe's address."
        );
    }
    if !c.extra_byte_counts.is_empty() {
        let counts: Vec<String> = c.extra_byte_counts.iter().map(|b| format!("0x{b:02X}")).collect();
        let _ = write!(
            d,
            " The reply is framed by its length; besides 0x{:02X} its byte count may be {} (see the example's erratum).",
            2 * usize::from(c.count),
            counts.join(" or ")
        );
    }
    if let Some(from) = &c.shared_from {
        let _ = write!(d, " Shared by every Yosemitech probe (`{}`).", one_line(from));
    }
    d.push('\n');
    let names: Vec<&str> = c.fields.iter().filter_map(|f| f.name.as_deref()).collect();
    d.push_str(&text::examples(&c.examples, &names));
    let errata: Vec<String> = c
        .errata
        .iter()
        .map(|e| {
            let table = e.table_says();
            format!(
                "- **{}** ({}): the table gives {}. {}",
                one_line(&e.id),
                text::figure_ref(e.figure),
                table.join(", "),
                one_line(&e.note)
            )
        })
        .collect();
    if !errata.is_empty() {
        d.push_str("\n# Errata\n\n");
        for e in errata {
            d.push_str(&e);
            d.push('\n');
        }
    }
    d
}

fn layout_expr(c: &CommandSpec) -> TokenStream {
    let address = hex(u32::from(c.address), 4);
    let count = Literal::u16_unsuffixed(c.count);
    if c.fixed_slave.is_none() && c.extra_byte_counts.is_empty() && !c.trigger {
        return match c.function {
            Function::Read => quote!(rtu::Layout::read(#address, #count)),
            Function::Write => quote!(rtu::Layout::write(#address, #count)),
        };
    }
    let function = match c.function {
        Function::Read => quote!(rtu::Function::Read),
        Function::Write => quote!(rtu::Function::Write),
    };
    let fixed = match c.fixed_slave {
        Some(s) => {
            let s = hex(u32::from(s), 2);
            quote!(Some(#s))
        }
        None => quote!(None),
    };
    let extra = c.extra_byte_counts.iter().map(|b| hex(u32::from(*b), 2));
    let trigger = c.trigger;
    quote! {
        rtu::Layout {
            function: #function,
            address: #address,
            count: #count,
            fixed_slave: #fixed,
            extra_byte_counts: &[#(#extra),*],
            trigger: #trigger,
        }
    }
}

pub(super) fn command(names: &Names, ci: usize, c: &CommandSpec) -> TokenStream {
    let n = &names.commands[ci];
    let ty = ident(&n.ty);
    let gens = field_gens(names, ci, c);
    let name = lit(&c.name);
    let layout = layout_expr(c);
    let docs = doc(&command_doc(c));
    let mut out = TokenStream::new();
    let response = match c.function {
        Function::Read => {
            let resp = ident(&n.response);
            // A trigger read (a read used as a command) ignores its reply's data.
            let (resp_gens, resp_docs) = if c.trigger {
                (&[][..], doc(&format!("Reply to [`{}`]: an acknowledgement that carries no value.", n.ty)))
            } else {
                let first_sentence =
                    one_line(&c.doc).split(". ").next().unwrap_or_default().trim_end_matches('.').to_owned();
                (&gens[..], doc(&format!("Reply to [`{}`]. {first_sentence}.", n.ty)))
            };
            out.extend(struct_def(&ty, &[], docs, Builder::User));
            out.extend(message_impl(&ty, &[], c, false, false));
            out.extend(struct_def(&resp, resp_gens, resp_docs, Builder::Decoder));
            out.extend(message_impl(&resp, resp_gens, c, !c.trigger, false));
            quote!(#resp)
        }
        Function::Write => {
            out.extend(struct_def(&ty, &gens, docs, Builder::User));
            out.extend(message_impl(&ty, &gens, c, true, true));
            quote!(())
        }
    };
    out.extend(quote! {
        impl rtu::Command for #ty {
            type Response = #response;
            const NAME: &'static str = #name;
            const LAYOUT: rtu::Layout<'static> = #layout;
        }
    });
    out
}
