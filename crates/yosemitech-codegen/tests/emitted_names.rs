//! The names a generated module declares for itself are the ones
//! `yosemitech_spec::names` lists, which validation keeps spec names away
//! from: every top-level item the generator emits is either the spec's own
//! (a command, its reply, a field's enum, a constant, a derived quantity)
//! or on that list, and everything on the list is emitted.

use std::collections::BTreeSet;
use std::path::PathBuf;

use yosemitech_spec::names::{MODULE_CONSTS, MODULE_FUNCTIONS, MODULE_TYPES, camel, shouty};

/// The spec's own names, across every sensor (shared commands included).
struct SpecNames {
    types: BTreeSet<String>,
    consts: BTreeSet<String>,
    functions: BTreeSet<String>,
}

fn spec_names(spec: &yosemitech_spec::Spec) -> SpecNames {
    let mut names = SpecNames { types: BTreeSet::new(), consts: BTreeSet::new(), functions: BTreeSet::new() };
    for sensor in &spec.sensors {
        for c in &sensor.commands {
            names.types.insert(camel(&c.name));
            names.types.insert(format!("{}Response", camel(&c.name)));
        }
        names.consts.extend(sensor.constants.iter().map(|c| shouty(&c.name)));
        names.functions.extend(sensor.derived.iter().map(|d| d.name.clone()));
    }
    names
}

/// What `rtu::command_set!` declares in the module that invokes it.
const COMMAND_SET_DECLARES: [&str; 5] = ["CommandId", "Request", "Response", "decode_response", "identify_request"];

/// The items a declaring macro of the runtime stands for: a device handle's
/// body is its `struct`; a command set declares `COMMAND_SET_DECLARES`.
fn declared_by(m: &syn::ItemMacro) -> Vec<syn::Item> {
    let Some(name) = m.mac.path.segments.last().map(|s| s.ident.to_string()) else {
        return Vec::new();
    };
    if name == "command_set" {
        return COMMAND_SET_DECLARES
            .iter()
            .map(|n| {
                let ident = syn::Ident::new(n, proc_macro2::Span::call_site());
                if n.starts_with(char::is_lowercase) {
                    syn::parse_quote!(fn #ident() {})
                } else {
                    syn::parse_quote!(struct #ident;)
                }
            })
            .collect();
    }
    syn::parse2::<syn::File>(m.mac.tokens.clone()).map(|f| f.items).unwrap_or_default()
}

/// The last segment of every type a struct's fields have: a field's enum
/// is the spec's when some message carries it.
fn field_types(file: &syn::File, out: &mut BTreeSet<String>) {
    for item in &file.items {
        if let syn::Item::Struct(s) = item {
            for field in &s.fields {
                if let syn::Type::Path(p) = &field.ty
                    && let Some(last) = p.path.segments.last()
                {
                    out.insert(last.ident.to_string());
                }
            }
        }
    }
}

#[test]
fn every_emitted_name_is_the_specs_or_on_the_reserved_list() {
    let spec_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../spec");
    let spec = yosemitech_spec::load_paths(&[spec_dir]).unwrap_or_else(|e| panic!("{e}"));
    let generated = yosemitech_codegen::Config::new()
        .std_feature(Some("std"))
        .async_device_handles(Some("tokio"))
        .generate_spec(&spec)
        .unwrap_or_else(|e| panic!("{e}"));
    let own = spec_names(&spec);
    let files: Vec<(String, syn::File)> = generated
        .sensors
        .iter()
        .map(|s| (s.file_name.clone(), syn::parse_file(&s.source).unwrap_or_else(|e| panic!("{}: {e}", s.file_name))))
        .collect();
    let mut enums_in_fields = BTreeSet::new();
    for (_, file) in &files {
        field_types(file, &mut enums_in_fields);
    }

    let mut emitted: BTreeSet<String> = BTreeSet::new();
    let mut strays = Vec::new();
    for (name, file) in &files {
        let declared = file.items.iter().flat_map(|item| match item {
            syn::Item::Macro(m) => declared_by(m),
            other => vec![other.clone()],
        });
        for item in &declared.collect::<Vec<_>>() {
            let (ident, reserved, spec_own) = match item {
                syn::Item::Struct(s) => (s.ident.to_string(), MODULE_TYPES, own.types.contains(&s.ident.to_string())),
                syn::Item::Enum(e) => {
                    let ident = e.ident.to_string();
                    let spec_own = enums_in_fields.contains(&ident);
                    (ident, MODULE_TYPES, spec_own)
                }
                syn::Item::Const(c) => (c.ident.to_string(), MODULE_CONSTS, own.consts.contains(&c.ident.to_string())),
                syn::Item::Fn(f) => {
                    let ident = f.sig.ident.to_string();
                    (ident.clone(), MODULE_FUNCTIONS, own.functions.contains(&ident))
                }
                syn::Item::Use(u) => match &u.tree {
                    syn::UseTree::Rename(r) => (r.rename.to_string(), MODULE_FUNCTIONS, false),
                    _ => continue,
                },
                _ => continue,
            };
            if reserved.contains(&ident.as_str()) {
                emitted.insert(ident);
            } else if !spec_own {
                strays.push(format!("{name}: `{ident}` is neither the spec's nor on the reserved list"));
            }
        }
    }
    assert!(strays.is_empty(), "{strays:#?}");
    let listed: BTreeSet<String> =
        MODULE_TYPES.iter().chain(MODULE_CONSTS).chain(MODULE_FUNCTIONS).map(|n| (*n).to_owned()).collect();
    let never: Vec<&String> = listed.difference(&emitted).collect();
    assert!(never.is_empty(), "reserved but never emitted: {never:?}");
}
