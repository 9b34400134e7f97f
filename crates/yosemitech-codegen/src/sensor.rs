//! One sensor's module: tokens for every generated item.

use std::fmt::Write as _;

use heck::ToUpperCamelCase;
use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};
use yosemitech_rtu::{ByteOrder2, ByteOrder4, DataBits, Function, LineSettings, Parity, StopBits};
use yosemitech_spec::expr::{Cmp, Func, Node, Op};
use yosemitech_spec::{
    CommandSpec, Constant, ConstantType, Derived, EnumRepr, Field, FieldKind, InputSource, Role, Sensor,
};

use crate::Error;
use crate::naming::{EnumDef, Names};
use crate::text::{self, doc, hex, lit, one_line, opt_lit};

/// What [`crate::Config`] decides.
pub struct Options {
    /// The runtime crate's path.
    pub runtime: TokenStream,
    /// Whether to emit `Device`.
    pub device_handles: bool,
    /// The feature gating std-only items.
    pub std_feature: Option<String>,
    /// The feature gating `AsyncDevice`; `None`: no async handles.
    pub async_feature: Option<String>,
}

fn ident(name: &str) -> Ident {
    Ident::new(name, Span::call_site())
}

fn unsupported(sensor: &Sensor, detail: String) -> Error {
    Error::Unsupported { sensor: sensor.name.clone(), detail }
}

/// `pub mod <sensor> { include!("<file>"); }` with the sensor's
/// documentation; with `device`, its command table names each command's
/// `Device` method.
pub fn module_declaration(s: &Sensor, device: Option<&Names>, file: &str) -> TokenStream {
    let name = ident(&s.name);
    let file = lit(file);
    let mut d = format!("{}\n\n{}\n\n", one_line(&s.title), text::clean(&s.doc).trim_end());
    if let (Some(model), Some(code)) = (&s.model, &s.model_code) {
        let _ = writeln!(
            d,
            "Model {}, model code {} (serial numbers `YL{}...`).\n",
            one_line(model),
            one_line(code),
            one_line(code)
        );
    }
    for alias in &s.aliases {
        let code = alias.model_code.as_deref().map(|c| format!(", model code {}", one_line(c))).unwrap_or_default();
        let _ = writeln!(
            d,
            "Model {} answers with the same commands{code} ({}).\n",
            one_line(&alias.model),
            one_line(&alias.provenance.summary())
        );
    }
    let from = match (&s.manual, &s.provenance) {
        (Some(m), _) => format!("the spec of the manual \"{}\" ({})", one_line(&m.title), one_line(&m.revision)),
        (None, Some(p)) => format!("a spec of facts without a Modbus manual ({})", one_line(&p.summary())),
        (None, None) => "its spec".to_owned(),
    };
    let _ = writeln!(
        d,
        "Generated from {from}. Serial: {}; slave addresses {}..={}, factory address {}.",
        s.serial, s.min_address, s.max_address, s.default_address
    );
    if !s.revisions.is_empty() {
        d.push_str("\nManual revisions (commands a later firmware added say since when):\n\n");
        for line in text::manuals(s) {
            let _ = writeln!(d, "- {line}");
        }
    }
    let method_column = if device.is_some() { " `Device` method |" } else { "" };
    let _ = write!(
        d,
        "\n| Command | Function | Address | Registers | Request | Reply |{method_column}\n|---|---|---|---|---|---|{}\n",
        if device.is_some() { "---|" } else { "" }
    );
    for (ci, c) in s.commands.iter().enumerate() {
        let ty = heck::ToUpperCamelCase::to_upper_camel_case(c.name.as_str());
        let (function, reply) = match c.function {
            Function::Read => ("read (0x03)", format!("[`{ty}Response`]({}::{ty}Response)", s.name)),
            Function::Write => ("write (0x10)", "`()`".to_owned()),
        };
        let method =
            device.and_then(|names| names.commands.get(ci)).map(|n| format!(" `{}()` |", n.method)).unwrap_or_default();
        let _ = writeln!(
            d,
            "| {} | {function} | 0x{:04X} | {} | [`{ty}`]({}::{ty}) | {reply} |{method}",
            one_line(&c.title).replace('|', "\\|"),
            c.address,
            c.count,
            s.name
        );
    }
    if !s.errata.is_empty() {
        d.push_str("\n# Manual errata\n\n");
        for e in &s.errata {
            let _ = writeln!(d, "- **{}**: {}", one_line(&e.id), one_line(&e.note));
        }
    }
    let docs = doc(&d);
    quote! {
        #docs
        pub mod #name {
            include!(#file);
        }
    }
}

/// A fragment's shared commands, generated once.
pub struct SharedModule {
    /// The fragment's (module's) name.
    pub fragment: String,
    /// The commands generated in it.
    pub commands: Vec<CommandSpec>,
    /// Their items.
    pub tokens: TokenStream,
}

/// What makes a command the same everywhere it is used: wire layout and
/// fields (names, types, offsets, units, ranges). Titles, docs and examples
/// may differ by manual; units and enums may not, since they are part of the
/// generated type.
fn same_type(a: &CommandSpec, b: &CommandSpec) -> bool {
    let field =
        |f: &yosemitech_spec::Field| (f.name.clone(), f.kind.clone(), f.offset, f.unit.clone(), f.range, f.absent);
    a.name == b.name
        && a.layout() == b.layout()
        && a.fields.len() == b.fields.len()
        && a.fields.iter().zip(&b.fields).all(|(x, y)| field(x) == field(y))
}

/// A command can be shared when its type needs nothing module-level: no
/// enum types (whose names a sensor module plans for itself).
fn shareable(c: &CommandSpec) -> bool {
    !c.fields.iter().any(|f| matches!(f.kind, FieldKind::Enum { .. }))
}

/// The module of a fragment's shareable commands; `None` when it has none.
pub fn fragment_module(fragment: &yosemitech_spec::Fragment, o: &Options) -> Result<Option<SharedModule>, Error> {
    let commands: Vec<CommandSpec> = fragment.commands.iter().filter(|c| shareable(c)).cloned().collect();
    if commands.is_empty() {
        return Ok(None);
    }
    let pseudo = Sensor {
        name: fragment.name.clone(),
        title: fragment.name.clone(),
        doc: fragment.doc.clone(),
        model: None,
        model_code: None,
        also_model_codes: Vec::new(),
        aliases: Vec::new(),
        manual: None,
        provenance: None,
        revisions: Vec::new(),
        serial: LineSettings::default(),
        min_address: 1,
        max_address: 247,
        default_address: 1,
        commands: commands.clone(),
        procedure: None,
        constants: Vec::new(),
        errata: Vec::new(),
        derived: Vec::new(),
        file: fragment.file.clone(),
        files: vec![fragment.file.clone()],
    };
    let names = Names::plan(&pseudo)?;
    let rt = &o.runtime;
    let mut tokens = quote! {
        use #rt as rtu;
    };
    for (ci, c) in commands.iter().enumerate() {
        tokens.extend(command(&names, ci, c));
    }
    Ok(Some(SharedModule { fragment: fragment.name.clone(), commands, tokens }))
}

/// `pub mod <fragment> { include!("<file>"); }` with the fragment's documentation.
pub fn fragment_declaration(fragment: &yosemitech_spec::Fragment, commands: &[CommandSpec], file: &str) -> TokenStream {
    let name = ident(&fragment.name);
    let file = lit(file);
    let list: Vec<String> = commands.iter().map(|c| format!("`{}`", c.name)).collect();
    let d = format!(
        "{}

Commands of the shared fragment `{}`, generated once: every sensor module that uses them re-exports these types ({}), so one type serves every probe.",
        text::clean(&fragment.doc).trim_end(),
        fragment.name,
        list.join(", ")
    );
    let docs = doc(&d);
    quote! {
        #docs
        pub mod #name {
            include!(#file);
        }
    }
}

/// The shared module and type that stand for a sensor's command, if any.
fn shared_for<'m>(
    c: &CommandSpec,
    names: &crate::naming::CommandNames,
    shared: &'m [SharedModule],
) -> Option<&'m SharedModule> {
    let from = c.shared_from.as_deref()?;
    let module = shared.iter().find(|m| m.fragment == from)?;
    let def = module.commands.iter().find(|d| d.name == c.name)?;
    let ty = heck::ToUpperCamelCase::to_upper_camel_case(c.name.as_str());
    (same_type(def, c) && names.ty == ty && names.response == format!("{ty}Response")).then_some(module)
}

/// Every item of one sensor's module.
pub fn module(s: &Sensor, names: &Names, o: &Options, shared: &[SharedModule]) -> Result<TokenStream, Error> {
    let rt = &o.runtime;
    let mut out = quote! {
        use #rt as rtu;
    };
    out.extend(sensor_info(s)?);
    for (c, name) in s.constants.iter().zip(&names.constants) {
        out.extend(constant(s, c, name)?);
    }
    for d in &s.derived {
        out.extend(derived_fn(d));
    }
    for e in &names.enums {
        out.extend(enum_type(s, e)?);
    }
    for (ci, c) in s.commands.iter().enumerate() {
        match shared_for(c, &names.commands[ci], shared) {
            Some(module) => {
                let m = ident(&module.fragment);
                let ty = ident(&names.commands[ci].ty);
                let docs = doc(&command_doc(c));
                if c.is_read() {
                    let resp = ident(&names.commands[ci].response);
                    out.extend(quote! {
                        #docs
                        pub use super::#m::{#ty, #resp};
                    });
                } else {
                    out.extend(quote! {
                        #docs
                        pub use super::#m::#ty;
                    });
                }
            }
            None => out.extend(command(names, ci, c)),
        }
    }
    out.extend(dispatch(s, names));
    if o.device_handles {
        out.extend(device(s, names, o));
    }
    Ok(out)
}

fn sensor_info(s: &Sensor) -> Result<TokenStream, Error> {
    let name = lit(&s.name);
    let title = lit(&one_line(&s.title));
    let optional = |text: Option<String>| match text {
        Some(t) => {
            let t = lit(&one_line(&t));
            quote!(Some(#t))
        }
        None => quote!(None),
    };
    let manual = optional(s.manual.as_ref().map(|m| m.title.clone()));
    let revision = optional(s.manual.as_ref().map(|m| m.revision.clone()));
    let provenance = optional(s.provenance.as_ref().map(|p| p.summary()));
    let baud = Literal::u32_unsuffixed(s.serial.baud);
    let data_bits = match s.serial.format.data_bits {
        DataBits::Seven => quote!(Seven),
        DataBits::Eight => quote!(Eight),
    };
    let parity = match s.serial.format.parity {
        Parity::None => quote!(None),
        Parity::Even => quote!(Even),
        Parity::Odd => quote!(Odd),
    };
    let stop_bits = match s.serial.format.stop_bits {
        StopBits::One => quote!(One),
        StopBits::Two => quote!(Two),
    };
    let (min, max, default) = (
        Literal::u8_unsuffixed(s.min_address),
        Literal::u8_unsuffixed(s.max_address),
        Literal::u8_unsuffixed(s.default_address),
    );
    let d = doc(&format!("The {}: serial settings and slave addresses.", one_line(&s.title)));
    Ok(quote! {
        #d
        pub const SENSOR: rtu::SensorInfo = rtu::SensorInfo {
            name: #name,
            title: #title,
            manual: #manual,
            revision: #revision,
            provenance: #provenance,
            baud: #baud,
            format: rtu::CharFormat {
                data_bits: rtu::DataBits::#data_bits,
                parity: rtu::Parity::#parity,
                stop_bits: rtu::StopBits::#stop_bits,
            },
            min_address: #min,
            max_address: #max,
            default_address: #default,
        };
    })
}

fn f32_lit(v: f32) -> TokenStream {
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

fn f64_lit(v: f64) -> TokenStream {
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

fn constant(s: &Sensor, c: &Constant, name: &str) -> Result<TokenStream, Error> {
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

fn enum_type(s: &Sensor, e: &EnumDef) -> Result<TokenStream, Error> {
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
    let n = Literal::usize_unsuffixed(known.len());
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
    let d = doc(&d);
    Ok(quote! {
        #d
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum #ty {
            #(#variants)*
            /// A code the spec does not name, as received.
            Unknown(#raw_ty),
        }

        impl #ty {
            /// Every named code, in spec order.
            pub const KNOWN: [Self; #n] = [#(#known),*];

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

/// Per-field facts for code generation.
struct FieldGen<'a> {
    field: &'a Field,
    name: Ident,
    ty: TokenStream,
}

fn field_gens<'a>(names: &Names, ci: usize, c: &'a CommandSpec) -> Vec<FieldGen<'a>> {
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
fn order2(o: ByteOrder2) -> TokenStream {
    let variant = format_ident!("{}", o.name().to_upper_camel_case());
    quote!(rtu::ByteOrder2::#variant)
}

/// The encoding of a field that fills the message's data alone, when its
/// encoder already returns the whole array.
fn whole_data_encoding(g: &FieldGen<'_>) -> Option<TokenStream> {
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

fn decode_expr(g: &FieldGen<'_>, data_len: usize) -> TokenStream {
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
            quote!(rtu::Ascii::from_wire(#b, #p))
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
fn encode_field(g: &FieldGen<'_>) -> (TokenStream, Vec<TokenStream>) {
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

fn field_value(g: &FieldGen<'_>) -> TokenStream {
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

/// The range check of a write field, if it has a range.
fn range_check(g: &FieldGen<'_>) -> Option<TokenStream> {
    let (min, max) = g.field.range?;
    let name = &g.name;
    let spec_name = lit(g.field.display_name());
    let err = quote!(return Err(rtu::EncodeError::OutOfRange { field: #spec_name }););
    let int_bounds = |lo: f64, hi: f64| -> Option<(i64, i64)> {
        let (a, b) = (min.ceil().max(lo), max.floor().min(hi));
        (min.is_finite() && max.is_finite() && a <= b).then_some((a as i64, b as i64))
    };
    let int_check = |lo: i64, hi: i64, type_lo: i64, type_hi: i64| -> Option<TokenStream> {
        if lo <= type_lo && hi >= type_hi {
            return None;
        }
        let (lo, hi) = (Literal::i64_unsuffixed(lo), Literal::i64_unsuffixed(hi));
        Some(quote! {
            if !(#lo..=#hi).contains(&self.#name) {
                #err
            }
        })
    };
    let float_check = || {
        let (lo, hi) = (f64_lit(min), f64_lit(max));
        quote! {
            if !(#lo..=#hi).contains(&f64::from(self.#name)) {
                #err
            }
        }
    };
    let (type_lo, type_hi): (i64, i64) = match &g.field.kind {
        FieldKind::Bcd => {
            // An invalid digit is never sent; in range means the digits' value.
            let (lo, hi) = (
                Literal::u8_unsuffixed(min.ceil().clamp(0.0, 99.0) as u8),
                Literal::u8_unsuffixed(max.floor().clamp(0.0, 99.0) as u8),
            );
            return Some(quote! {
                match self.#name.value() {
                    Some(v) if (#lo..=#hi).contains(&v) => {}
                    _ => { #err }
                }
            });
        }
        FieldKind::F32 { .. } => {
            let (lo, hi) = (f64_lit(min), f64_lit(max));
            // NaN is not range-checked (the reference interpreter agrees): it is how
            // a logger writes "no value".
            return Some(quote! {
                if !self.#name.is_nan() && !(#lo..=#hi).contains(&f64::from(self.#name)) {
                    #err
                }
            });
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
        Some((lo, hi)) if min.fract() == 0.0 && max.fract() == 0.0 => int_check(lo, hi, type_lo, type_hi),
        _ => Some(float_check()),
    }
}

fn field_doc(g: &FieldGen<'_>) -> TokenStream {
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
        let mut checks: Vec<TokenStream> = gens.iter().filter_map(range_check).collect();
        for g in gens.iter().filter(|g| matches!(g.field.kind, FieldKind::Bcd) && g.field.range.is_none()) {
            let name = &g.name;
            let spec_name = lit(g.field.display_name());
            checks.push(quote! {
                if self.#name.value().is_none() {
                    return Err(rtu::EncodeError::OutOfRange { field: #spec_name });
                }
            });
        }
        if !checks.is_empty() {
            validate = quote! {
                fn validate(&self) -> Result<(), rtu::EncodeError> {
                    #(#checks)*
                    Ok(())
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

fn struct_def(ty: &Ident, gens: &[FieldGen<'_>], docs: TokenStream) -> TokenStream {
    if gens.is_empty() {
        return quote! {
            #docs
            #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
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
        pub struct #ty {
            #(#members),*
        }
    }
}

fn command_doc(c: &CommandSpec) -> String {
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
    for ex in &c.examples {
        d.push('\n');
        d.push_str(&text::example(ex, &names));
    }
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

fn command(names: &Names, ci: usize, c: &CommandSpec) -> TokenStream {
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
            out.extend(struct_def(&ty, &[], docs));
            out.extend(message_impl(&ty, &[], c, false, false));
            out.extend(struct_def(&resp, resp_gens, resp_docs));
            out.extend(message_impl(&resp, resp_gens, c, !c.trigger, false));
            quote!(#resp)
        }
        Function::Write => {
            out.extend(struct_def(&ty, &gens, docs));
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

fn dispatch(s: &Sensor, names: &Names) -> TokenStream {
    let derived_table = derived_table(s);
    let n = Literal::usize_unsuffixed(s.commands.len());
    let variants: Vec<Ident> = names.commands.iter().map(|c| ident(&c.ty)).collect();
    let titles: Vec<Literal> = s.commands.iter().map(|c| lit(&one_line(&c.title))).collect();
    let id_docs: Vec<TokenStream> =
        s.commands.iter().zip(&variants).map(|(c, v)| doc(&format!("`{}`: [`{v}`].", c.name))).collect();

    let mut response_variants = Vec::new();
    let mut decode_response_arms = Vec::new();
    let mut response_command_arms = Vec::new();
    let mut response_encode_arms = Vec::new();
    let mut response_field_arms = Vec::new();
    let mut froms = Vec::new();
    for (c, v) in s.commands.iter().zip(&variants) {
        let d = doc(&format!("The reply to [`{v}`]."));
        if c.is_read() {
            let resp = format_ident!("{}Response", v);
            response_variants.push(quote!(#d #v(#resp)));
            decode_response_arms
                .push(quote!(Self::#v => <#v as rtu::Command>::decode_response(slave, frame).map(Response::#v)));
            response_command_arms.push(quote!(Self::#v(_) => CommandId::#v));
            response_encode_arms.push(quote!(Self::#v(r) => <#v as rtu::Command>::encode_response(r, slave, out)));
            response_field_arms.push(quote!(Self::#v(r) => r.field(index)));
            froms.push(quote! {
                impl From<#resp> for Response {
                    fn from(response: #resp) -> Self {
                        Self::#v(response)
                    }
                }
            });
        } else {
            response_variants.push(quote!(#d #v));
            decode_response_arms
                .push(quote!(Self::#v => <#v as rtu::Command>::decode_response(slave, frame).map(|()| Response::#v)));
            response_command_arms.push(quote!(Self::#v => CommandId::#v));
            response_encode_arms.push(quote!(Self::#v => <#v as rtu::Command>::encode_response(&(), slave, out)));
            response_field_arms.push(quote!(Self::#v => None));
        }
        froms.push(quote! {
            impl From<#v> for Request {
                fn from(request: #v) -> Self {
                    Self::#v(request)
                }
            }
        });
    }
    let request_variants = variants.iter().map(|v| {
        let d = doc(&format!("A [`{v}`] request."));
        quote!(#d #v(#v))
    });

    quote! {
        /// Every command of this sensor as data, in spec order: name, title,
        /// layout, fields and codecs ([`CommandId`] indexes it).
        pub const COMMANDS: [rtu::CommandEntry; #n] = [
            #(rtu::CommandEntry::of::<#variants>(#titles),)*
        ];

        /// Every command of this sensor, for code that picks commands at run
        /// time (CLIs, simulators, tests).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum CommandId {
            #(#id_docs #variants,)*
        }

        impl CommandId {
            /// Every command, in spec order.
            pub const ALL: [Self; #n] = [#(Self::#variants),*];

            /// The command's row of [`COMMANDS`].
            // Variants are declared in table order, so every discriminant is an index.
            #[allow(clippy::indexing_slicing)]
            pub const fn entry(self) -> &'static rtu::CommandEntry {
                &COMMANDS[self as usize]
            }

            /// The command's snake_case name in the spec.
            pub const fn name(self) -> &'static str {
                self.entry().name
            }

            /// The command called `name` in the spec.
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL.into_iter().find(|id| id.name() == name)
            }

            /// The command's title in the manual.
            pub const fn title(self) -> &'static str {
                self.entry().title
            }

            /// Function, start address, register count and addressing quirks.
            pub const fn layout(self) -> rtu::Layout<'static> {
                self.entry().layout
            }

            /// Name and unit of each field of the request (empty for reads).
            pub const fn request_fields(self) -> &'static [rtu::FieldInfo] {
                self.entry().request_fields
            }

            /// Name and unit of each field of the reply (empty for writes).
            pub const fn response_fields(self) -> &'static [rtu::FieldInfo] {
                self.entry().response_fields
            }

            /// Checks a request frame for this command and decodes it.
            pub fn decode_request(self, frame: &[u8]) -> Result<(u8, Request), rtu::FrameError> {
                match self {
                    #(Self::#variants => {
                        <#variants as rtu::Command>::decode_request(frame).map(|(slave, r)| (slave, Request::#variants(r)))
                    })*
                }
            }

            /// Checks a reply to this command, sent to `slave`, and decodes it.
            pub fn decode_response(self, slave: u8, frame: &[u8]) -> Result<Response, rtu::FrameError> {
                match self {
                    #(#decode_response_arms,)*
                }
            }
        }

        impl ::core::fmt::Display for CommandId {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                f.write_str(self.name())
            }
        }

        /// A request of any command of this sensor.
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub enum Request {
            #(#request_variants,)*
        }

        impl Request {
            /// Which command this is.
            pub const fn command(&self) -> CommandId {
                match self {
                    #(Self::#variants(_) => CommandId::#variants,)*
                }
            }

            /// Writes the request frame for `slave` into `out` and returns its length.
            pub fn encode(&self, slave: u8, out: &mut [u8]) -> Result<usize, rtu::EncodeError> {
                match self {
                    #(Self::#variants(r) => rtu::Command::encode_request(r, slave, out),)*
                }
            }

            /// The value of field `index` of [`CommandId::request_fields`].
            pub fn field(&self, index: usize) -> Option<rtu::FieldValue<'_>> {
                match self {
                    #(Self::#variants(r) => rtu::Message::field(r, index),)*
                }
            }

            /// Every field with its name and unit, in wire order.
            pub fn fields(&self) -> impl Iterator<Item = (rtu::FieldInfo, rtu::FieldValue<'_>)> + '_ {
                self.command().request_fields().iter().enumerate().filter_map(|(i, info)| Some((*info, self.field(i)?)))
            }
        }

        /// A reply to any command of this sensor (writes reply with no data).
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub enum Response {
            #(#response_variants,)*
        }

        impl Response {
            /// Which command this answers.
            pub const fn command(&self) -> CommandId {
                match self {
                    #(#response_command_arms,)*
                }
            }

            /// Writes this reply from `slave` into `out` and returns its length.
            pub fn encode(&self, slave: u8, out: &mut [u8]) -> Result<usize, rtu::EncodeError> {
                match self {
                    #(#response_encode_arms,)*
                }
            }

            /// The value of field `index` of [`CommandId::response_fields`].
            pub fn field(&self, index: usize) -> Option<rtu::FieldValue<'_>> {
                use rtu::Message as _;
                match self {
                    #(#response_field_arms,)*
                }
            }

            /// Every field with its name and unit, in wire order.
            pub fn fields(&self) -> impl Iterator<Item = (rtu::FieldInfo, rtu::FieldValue<'_>)> + '_ {
                self.command().response_fields().iter().enumerate().filter_map(|(i, info)| Some((*info, self.field(i)?)))
            }
        }

        #(#froms)*

        /// Checks a reply to command `id`, sent to `slave`, and decodes it.
        pub fn decode_response(id: CommandId, slave: u8, frame: &[u8]) -> Result<Response, rtu::FrameError> {
            id.decode_response(slave, frame)
        }

        /// The command a request frame is for, by its function, start address
        /// and register count (the first in spec order if several match). Does
        /// not check the frame: decode it with [`CommandId::decode_request`].
        pub fn identify_request(frame: &[u8]) -> Option<CommandId> {
            rtu::identify_request(&COMMANDS, frame).and_then(|i| CommandId::ALL.get(i).copied())
        }

        #derived_table

        /// This module as data, for code that serves every sensor without naming one
        /// (`crate::SENSORS` lists them all).
        pub const MODULE: rtu::SensorModule = rtu::SensorModule { info: SENSOR, commands: &COMMANDS, derived: &DERIVED };
    }
}

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
        Node::Bin(Op::Pow, a, b) => {
            let (a, b) = (formula(a).0, formula(b).0);
            (quote!(rtu::derived::pow(#a, #b)), 3)
        }
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
fn derived_fn(d: &Derived) -> TokenStream {
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
fn derived_table(s: &Sensor) -> TokenStream {
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
    let n = Literal::usize_unsuffixed(entries.len());
    quote! {
        /// Every derived quantity of the sensor as data, in spec order: its
        /// inputs, and its function (`compute` takes the inputs in parameter order).
        pub const DERIVED: [rtu::DerivedInfo; #n] = [#(#entries),*];
    }
}

const RANGE_NOTE: &str = " Values outside the spec's range are refused before sending.";

/// `Device::set_slave_address` for a sensor with a write of role
/// `set_slave_address` and a read of role `serial_number`, both sent to the
/// device's own address: the verified change of `rtu::address`.
fn set_slave_address(s: &Sensor, names: &Names) -> Option<TokenStream> {
    let own = |role| {
        s.commands.iter().position(|c| c.role == Some(role) && c.fixed_slave.is_none()).map(|i| (i, &s.commands[i]))
    };
    let ((wi, write), (pi, _)) = (own(Role::SetSlaveAddress)?, own(Role::SerialNumber)?);
    // Validation gives the write exactly one named field, a `u8`.
    let [field] = field_gens(names, wi, write).try_into().ok()?;
    let field = field.name;
    let write_ty = ident(&names.commands[wi].ty);
    let probe_ty = ident(&names.commands[pi].ty);
    let d = doc(&format!(
        "Changes the probe's slave address to `new` (1..=247, not in use on the bus) with [`{}`], confirmed by the \
         probe's reply and verified by reading [`{}`] at `new`; the handle then talks to `new`. On failure the error \
         says where the probe answers (see `rtu::address::change_address`).",
        names.commands[wi].ty, names.commands[pi].ty
    ));
    Some(quote! {
        #d
        pub fn set_slave_address(&mut self, new: u8) -> Result<(), rtu::address::AddressChangeError> {
            rtu::address::change_address(self.client, self.address, new, &#write_ty { #field: new }, &#probe_ty)?;
            self.address = new;
            Ok(())
        }
    })
}

fn device(s: &Sensor, names: &Names, o: &Options) -> TokenStream {
    let cfg = match &o.std_feature {
        Some(feature) => quote!(#[cfg(feature = #feature)]),
        None => TokenStream::new(),
    };
    // One method per command, emitted twice from the same parts: blocking
    // (`Device`) and, when asked for, async (`AsyncDevice`).
    let mut methods = Vec::new();
    let mut async_methods = Vec::new();
    for (ci, c) in s.commands.iter().enumerate() {
        let n = &names.commands[ci];
        let ty = ident(&n.ty);
        let method = ident(&n.method);
        let gens = field_gens(names, ci, c);
        let title = one_line(&c.title);
        let title = title.trim_end_matches('.');
        // (doc, parameters, return type, request expression, reply mapping)
        let (d, params, ret, request, map) = match c.function {
            Function::Read => {
                let resp = ident(&n.response);
                if let [only] = gens.as_slice() {
                    let field = &only.name;
                    let fty = &only.ty;
                    let unit = only.field.unit.as_deref().map(|u| format!(" ({})", one_line(u))).unwrap_or_default();
                    let d = doc(&format!(
                        "{title}: sends [`{}`] and returns its `{}`{unit}.",
                        n.ty,
                        only.field.display_name()
                    ));
                    (d, quote!(), quote!(#fty), quote!(&#ty), quote!(.map(|reply| reply.#field)))
                } else {
                    let d = doc(&format!("{title}: sends [`{}`] and returns the reply.", n.ty));
                    (d, quote!(), quote!(#resp), quote!(&#ty), quote!())
                }
            }
            Function::Write => match gens.as_slice() {
                [] => {
                    let d = doc(&format!("{title}: sends [`{}`].", n.ty));
                    (d, quote!(), quote!(()), quote!(&#ty), quote!())
                }
                [only] => {
                    let field = &only.name;
                    let fty = &only.ty;
                    let d = doc(&format!(
                        "{title}: sends [`{}`] with `{}`.{}",
                        n.ty,
                        only.field.display_name(),
                        if only.field.range.is_some() { RANGE_NOTE } else { "" }
                    ));
                    (d, quote!(, #field: #fty), quote!(()), quote!(&#ty { #field }), quote!())
                }
                _ => {
                    let ranged = gens.iter().any(|g| g.field.range.is_some());
                    let d = doc(&format!(
                        "{title}: sends `request` ([`{}`]).{}",
                        n.ty,
                        if ranged { RANGE_NOTE } else { "" }
                    ));
                    (d, quote!(, request: #ty), quote!(()), quote!(&request), quote!())
                }
            },
        };
        methods.push(quote! {
            #d
            pub fn #method(&mut self #params) -> Result<#ret, rtu::Error> {
                self.call(#request) #map
            }
        });
        async_methods.push(quote! {
            #d
            pub async fn #method(&mut self #params) -> Result<#ret, rtu::Error> {
                self.call(#request).await #map
            }
        });
    }
    methods.extend(set_slave_address(s, names));
    let title = one_line(&s.title);
    let async_device = match &o.async_feature {
        Some(feature) => {
            let d = doc(&format!(
                "One {title} on a bus, from async code: [`Device`]'s methods as `async fn`s over a borrowed \
                 [`rtu::AsyncClient`] (tokio), with the same requests, checks and replies."
            ));
            quote! {
                #[cfg(feature = #feature)]
                #d
                pub struct AsyncDevice<'c, L> {
                    client: &'c mut rtu::AsyncClient<L>,
                    address: u8,
                }

                #[cfg(feature = #feature)]
                impl<'c, L: rtu::transport::AsyncLink> AsyncDevice<'c, L> {
                    /// The probe at `address` on `client`'s bus.
                    pub fn new(client: &'c mut rtu::AsyncClient<L>, address: u8) -> Self {
                        Self { client, address }
                    }

                    /// The probe's slave address.
                    pub fn address(&self) -> u8 {
                        self.address
                    }

                    /// Points the handle at another address, after the probe's
                    /// address was changed and verified.
                    pub fn set_address(&mut self, address: u8) {
                        self.address = address;
                    }

                    /// The client, for requests to other devices on the bus.
                    pub fn client(&mut self) -> &mut rtu::AsyncClient<L> {
                        self.client
                    }

                    /// Sends any command to this probe (or to the command's fixed
                    /// slave address) and returns the decoded reply.
                    pub async fn call<C: rtu::Command>(&mut self, command: &C) -> Result<C::Response, rtu::Error> {
                        self.client.call(C::LAYOUT.request_slave(self.address), command).await
                    }

                    #(#async_methods)*
                }
            }
        }
        None => TokenStream::new(),
    };
    let d = doc(&format!(
        "One {title} on a bus: a borrowed [`rtu::Client`] and the probe's slave address, with one method per command.\n\n\
         Reads are named after the command without its `get_` prefix and return the reply, or its only field; writes \
         keep the command's name and take the field (one field) or the request (several). Commands with a fixed slave \
         address (a read at the wildcard address 0xFF) use it instead of the device's."
    ));
    quote! {
        #cfg
        #d
        pub struct Device<'c, T> {
            client: &'c mut rtu::Client<T>,
            address: u8,
        }

        #cfg
        impl<'c, T: rtu::Transport> Device<'c, T> {
            /// The probe at `address` on `client`'s bus.
            pub fn new(client: &'c mut rtu::Client<T>, address: u8) -> Self {
                Self { client, address }
            }

            /// The probe's slave address.
            pub fn address(&self) -> u8 {
                self.address
            }

            /// Points the handle at another address, after the probe's
            /// address was changed and verified (see `rtu::address`).
            pub fn set_address(&mut self, address: u8) {
                self.address = address;
            }

            /// The client, for requests to other devices on the bus.
            pub fn client(&mut self) -> &mut rtu::Client<T> {
                self.client
            }

            /// Sends any command to this probe (or to the command's fixed
            /// slave address) and returns the decoded reply.
            pub fn call<C: rtu::Command>(&mut self, command: &C) -> Result<C::Response, rtu::Error> {
                self.client.call(C::LAYOUT.request_slave(self.address), command)
            }

            #(#methods)*
        }

        #async_device
    }
}
