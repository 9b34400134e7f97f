//! One sensor's module: tokens for every generated item.

use std::fmt::Write as _;

use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::quote;
use yosemitech_rtu::{DataBits, Function, LineSettings, Parity, StopBits};
use yosemitech_spec::{CommandSpec, FieldKind, Sensor};

use crate::Error;
use crate::naming::Names;
use crate::text::{self, doc, lit, one_line};

mod constants;
mod derived;
mod device;
mod dispatch;
mod fields;
mod message;

use constants::{constant, enum_type};
use derived::derived_fn;
use device::device;
use dispatch::dispatch;
use message::{command, command_doc};

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
