//! Generates typed, allocation-free Rust codecs from Yosemitech spec files,
//! in the manner of `prost-build`: call it from a `build.rs`, write the
//! sources to `OUT_DIR` and `include!` them.
//!
//! ```no_run
//! // build.rs
//! fn main() -> Result<(), yosemitech_codegen::Error> {
//!     let out_dir = std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR");
//!     yosemitech_codegen::Config::new().compile("spec", out_dir)?;
//!     Ok(())
//! }
//! ```
//!
//! ```ignore
//! // src/lib.rs: one `pub mod <sensor>` per sensor of the spec directory.
//! include!(concat!(env!("OUT_DIR"), "/mod.rs"));
//! ```
//!
//! [`Config::compile`] writes one `<sensor>.rs` per sensor plus a `mod.rs`
//! that declares `pub mod <sensor> { include!("<sensor>.rs"); }` for each,
//! with the sensor's documentation, and prints `cargo:rerun-if-changed` for
//! the directory and every spec file it read. The including crate depends on
//! the runtime (`yosemitech-rtu`, or wherever [`Config::runtime_crate`]
//! points) and, when device handles are gated on a feature
//! ([`Config::std_feature`]), declares that feature.
//!
//! # What a sensor module contains
//!
//! For each command `get_ph` of the spec (names come only from validated
//! spec names, converted with `heck`):
//!
//! - `GetPh`: the request, a unit struct for reads and a struct of typed
//!   fields for writes. Its `Command` impl is three constants (the reply
//!   type, the name, the `Layout`); framing, CRC and checks are the
//!   runtime's provided methods, as `prost::Message` provides `encode`.
//! - `GetPhResponse`: the reply of a read, a struct of typed fields. Writes
//!   reply with `()` (the runtime checks the echo).
//! - both implement the runtime's `Message`: `FIELDS`, `from_data` and
//!   `to_data` over the register data as a fixed-size array, and
//!   `field(index)`; write requests have `validate()` for spec ranges.
//!   A message without data (a read's request) implements `NoData`.
//! - an enum per `enum` field with an `Unknown(raw)` arm, `from_raw`, `raw`
//!   and `name`.
//!
//! And per sensor: `SENSOR` (a `SensorInfo`), one `pub const` per spec
//! constant, `COMMANDS` (one `CommandEntry` per command: name, title,
//! layout, fields and the typed codecs as function pointers), the command
//! set declared with the runtime's `command_set!` over it (`CommandId`: `ALL`,
//! `name`, `from_name`, `layout`, decoding; `Request` and `Response` enums
//! over every command; `decode_response`, `identify_request`), `DERIVED`,
//! `MODULE` (the module as data), and (unless disabled) a `Device` handle
//! declared with `device_handle!` and given one method per command.
//!
//! What every module would repeat is the runtime's, once: the command set's
//! dispatch and the handles' shared methods (`new`, `address`, `set_address`,
//! `client`, `call`) are `macro_rules!` of `yosemitech-rtu`, so a module
//! declares its commands and the compiler, not the generator, writes the
//! `match`es.
//!
//! The generated code allocates nothing, has no `unwrap` and no indexing
//! that could panic (array accesses are constant indices into arrays of
//! known length, and `CommandId` indexes `COMMANDS` by its discriminant,
//! declared in the table's order), and is clippy-clean.
//!
//! Feature `pretty` formats the output with `prettyplease` (the readable
//! copy `cargo xtask codegen` writes); a build script does not need it, so
//! the crates that generate at build time compile neither it nor `syn`.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod naming;
mod sensor;
pub mod text;

use std::fmt;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use proc_macro2::TokenStream;
use yosemitech_spec::{Diagnostics, Spec};

use naming::Names;

/// The file [`Config::compile`] writes next to the sensor files, declaring one
/// module per sensor. No sensor can be called `mod` (a keyword), so it never
/// collides with a sensor's file.
pub const MODULES_FILE: &str = "mod.rs";

/// How to generate code. Build with [`Config::new`] and the setters, then
/// call [`Config::compile`] (build scripts) or [`Config::generate`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Config {
    runtime: String,
    device_handles: bool,
    std_feature: Option<String>,
    async_feature: Option<String>,
}

impl Default for Config {
    fn default() -> Self {
        Self::new()
    }
}

impl Config {
    /// The defaults: runtime `::yosemitech_rtu`, device handles on, gated on
    /// the feature `std`.
    pub fn new() -> Self {
        Self {
            runtime: "::yosemitech_rtu".into(),
            device_handles: true,
            std_feature: Some("std".into()),
            async_feature: None,
        }
    }

    /// The path of the runtime crate in generated code (default
    /// `::yosemitech_rtu`), e.g. `crate::rtu` for a crate that re-exports it.
    /// Checked when generating ([`Error::RuntimePath`]).
    pub fn runtime_crate(&mut self, path: impl Into<String>) -> &mut Self {
        self.runtime = path.into();
        self
    }

    /// Whether to generate `Device` handles (blocking, over the runtime's
    /// `Client`; they need the runtime's `std` feature). Default on.
    pub fn device_handles(&mut self, on: bool) -> &mut Self {
        self.device_handles = on;
        self
    }

    /// The cargo feature that gates std-only items (device handles) with
    /// `#[cfg(feature = "...")]`; `None` emits them unconditionally. Default
    /// `Some("std")`: the including crate must declare that feature.
    pub fn std_feature(&mut self, feature: Option<&str>) -> &mut Self {
        self.std_feature = feature.map(str::to_owned);
        self
    }

    /// The cargo feature that gates async device handles (`AsyncDevice`,
    /// the blocking `Device`'s methods as `async fn`s over the runtime's
    /// tokio `AsyncClient`, which needs the runtime's `tokio` feature) with
    /// `#[cfg(feature = "...")]`; `None` (the default) generates none. Only
    /// with [`Config::device_handles`] on.
    pub fn async_device_handles(&mut self, feature: Option<&str>) -> &mut Self {
        self.async_feature = feature.map(str::to_owned);
        self
    }

    /// Loads and validates the spec files in `spec_dirs` (directories or
    /// files) and generates one module per sensor.
    pub fn generate<P: AsRef<Path>>(&self, spec_dirs: &[P]) -> Result<Generated, Error> {
        let paths: Vec<PathBuf> = spec_dirs.iter().map(|p| p.as_ref().to_path_buf()).collect();
        let spec = yosemitech_spec::load_paths(&paths).map_err(Error::Spec)?;
        self.generate_spec(&spec)
    }

    /// Generates one module per sensor of an already loaded spec.
    pub fn generate_spec(&self, spec: &Spec) -> Result<Generated, Error> {
        let runtime =
            runtime_path(&self.runtime).map_err(|reason| Error::RuntimePath { path: self.runtime.clone(), reason })?;
        let options = sensor::Options {
            runtime,
            device_handles: self.device_handles,
            std_feature: self.std_feature.clone(),
            async_feature: self.async_feature.clone(),
        };
        let mut sensors = Vec::new();
        let mut modules = TokenStream::new();
        // Commands several sensors share are generated once, in a module per
        // fragment; each sensor module re-exports them.
        let mut shared = Vec::new();
        for fragment in &spec.fragments {
            if spec.sensors.iter().any(|s| s.name == fragment.name) {
                return Err(Error::NameCollision {
                    sensor: fragment.name.clone(),
                    detail: format!("the fragment `{}` and a sensor have the same module name", fragment.name),
                });
            }
            let Some(generated) = sensor::fragment_module(fragment, &options)? else { continue };
            let source = format_tokens(&fragment.name, generated.tokens.clone(), &header(&fragment.file))?;
            modules.extend(sensor::fragment_declaration(
                fragment,
                &generated.commands,
                &format!("{}.rs", fragment.name),
            ));
            sensors.push(GeneratedSensor {
                name: fragment.name.clone(),
                file_name: format!("{}.rs", fragment.name),
                source,
            });
            shared.push(generated);
        }
        for s in &spec.sensors {
            let names = Names::plan(s)?;
            let tokens = sensor::module(s, &names, &options, &shared)?;
            let source = format_tokens(&s.name, tokens, &header(&s.file))?;
            let device = options.device_handles.then_some(&names);
            modules.extend(sensor::module_declaration(s, device, &format!("{}.rs", s.name)));
            sensors.push(GeneratedSensor { name: s.name.clone(), file_name: format!("{}.rs", s.name), source });
        }
        let module_refs: Vec<TokenStream> = spec
            .sensors
            .iter()
            .map(|s| {
                let m = quote::format_ident!("{}", s.name);
                quote::quote!(#m::MODULE)
            })
            .collect();
        let runtime_path = &options.runtime;
        modules.extend(quote::quote! {
            /// Every generated sensor module, in spec-file order, as data: for code
            /// that serves any sensor of the spec without naming one. A slice, so
            /// that a sensor added to the spec changes no type.
            pub const SENSORS: &[#runtime_path::SensorModule] = &[#(#module_refs),*];
        });
        let files: Vec<String> = spec.sensors.iter().filter_map(|s| file_name(&s.file)).collect();
        let modules = format_tokens(MODULES_FILE, modules, &format!("from {}", files.join(", ")))?;
        Ok(Generated { sensors, modules })
    }

    /// For build scripts: generates from `spec_dir`, writes `<sensor>.rs`
    /// and [`MODULES_FILE`] to `out_dir` (only files whose content changed),
    /// and prints `cargo:rerun-if-changed` for the directory and every spec
    /// file read (included fragments too), also when loading fails.
    pub fn compile(&self, spec_dir: impl AsRef<Path>, out_dir: impl AsRef<Path>) -> Result<Generated, Error> {
        let spec_dir = spec_dir.as_ref();
        let out_dir = out_dir.as_ref();
        println!("cargo:rerun-if-changed={}", spec_dir.display());
        let spec = match yosemitech_spec::load_paths(&[spec_dir.to_path_buf()]) {
            Ok(spec) => spec,
            Err(diagnostics) => {
                // Re-run when any file of the directory changes, so that a fix is picked up.
                if let Ok(entries) = fs::read_dir(spec_dir) {
                    for entry in entries.flatten() {
                        println!("cargo:rerun-if-changed={}", entry.path().display());
                    }
                }
                return Err(Error::Spec(diagnostics));
            }
        };
        for file in spec.files() {
            println!("cargo:rerun-if-changed={}", file.display());
        }
        let generated = self.generate_spec(&spec)?;
        generated.write_to(out_dir)?;
        Ok(generated)
    }
}

/// The generated sources.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Generated {
    /// One module per shared fragment (its commands, generated once), then
    /// one module per sensor, in spec order.
    pub sensors: Vec<GeneratedSensor>,
    /// The contents of [`MODULES_FILE`]: `pub mod <sensor> { include!("<sensor>.rs"); }` for each sensor.
    pub modules: String,
}

impl Generated {
    /// Every file as (file name, contents): the sensors, then [`MODULES_FILE`].
    pub fn files(&self) -> Vec<(String, &str)> {
        let mut files: Vec<(String, &str)> =
            self.sensors.iter().map(|s| (s.file_name.clone(), s.source.as_str())).collect();
        files.push((MODULES_FILE.to_owned(), &self.modules));
        files
    }

    /// Writes every file to `dir` (created if missing), skipping files whose
    /// contents are already the same (so their timestamps stay).
    pub fn write_to(&self, dir: &Path) -> Result<(), Error> {
        fs::create_dir_all(dir).map_err(|source| Error::Io { path: dir.to_path_buf(), source })?;
        for (name, contents) in self.files() {
            let path = dir.join(name);
            if fs::read_to_string(&path).is_ok_and(|old| old == contents) {
                continue;
            }
            fs::write(&path, contents).map_err(|source| Error::Io { path, source })?;
        }
        Ok(())
    }

    /// The sensor called `name`.
    pub fn sensor(&self, name: &str) -> Option<&GeneratedSensor> {
        self.sensors.iter().find(|s| s.name == name)
    }
}

/// The generated module of one sensor or shared fragment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GeneratedSensor {
    /// The sensor's or fragment's (module's) name.
    pub name: String,
    /// `<name>.rs`.
    pub file_name: String,
    /// Formatted Rust source: the module's items, for `include!`.
    pub source: String,
}

/// Why code could not be generated.
///
/// `Debug` shows the same text as `Display`, so a build script that returns
/// it from `main` prints the full rustc-style diagnostics.
#[non_exhaustive]
pub enum Error {
    /// The spec did not load: every problem, rustc-style.
    Spec(Diagnostics),
    /// Two generated items of one sensor would have the same name.
    NameCollision {
        /// The sensor.
        sensor: String,
        /// What collides.
        detail: String,
    },
    /// A spec value cannot be expressed in generated code.
    Unsupported {
        /// The sensor.
        sensor: String,
        /// What is wrong.
        detail: String,
    },
    /// [`Config::runtime_crate`] is not a Rust path.
    RuntimePath {
        /// The path given.
        path: String,
        /// Why it does not parse.
        reason: String,
    },
    /// The generated tokens did not parse as Rust (a bug in this crate).
    Internal {
        /// The file being generated.
        file: String,
        /// The parser's message.
        reason: String,
    },
    /// Writing a file failed.
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: io::Error,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Spec(diagnostics) => write!(f, "{diagnostics}"),
            Self::NameCollision { sensor, detail } => {
                write!(f, "error: sensor `{sensor}`: generated names collide: {detail}")
            }
            Self::Unsupported { sensor, detail } => write!(f, "error: sensor `{sensor}`: {detail}"),
            Self::RuntimePath { path, reason } => {
                write!(f, "error: the runtime crate path `{path}` is not a Rust path: {reason}")
            }
            Self::Internal { file, reason } => {
                write!(f, "error: internal: the code generated for {file} does not parse: {reason}")
            }
            Self::Io { path, source } => write!(f, "error: cannot write {}: {source}", path.display()),
        }
    }
}

impl fmt::Debug for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Spec(diagnostics) => Some(diagnostics),
            Self::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

fn file_name(path: &Path) -> Option<String> {
    path.file_name().map(|n| n.to_string_lossy().into_owned())
}

/// The first line of every generated file; names the spec file by its file
/// name only, so the output does not depend on where the checkout lives.
fn header(spec_file: &Path) -> String {
    format!("from {}", file_name(spec_file).unwrap_or_default())
}

fn format_tokens(what: &str, tokens: TokenStream, from: &str) -> Result<String, Error> {
    let from: String = from.chars().map(|c| if c.is_control() { ' ' } else { c }).collect();
    Ok(format!(
        "// @generated by yosemitech-codegen {from}. Do not edit: change the spec and regenerate.\n\n{}",
        render(what, tokens)?
    ))
}

/// The tokens as rustfmt would lay them out, for people to read.
#[cfg(feature = "pretty")]
fn render(what: &str, tokens: TokenStream) -> Result<String, Error> {
    let file: syn::File =
        syn::parse2(tokens).map_err(|e| Error::Internal { file: what.to_owned(), reason: e.to_string() })?;
    Ok(space_items(&lay_out_declarations(&prettyplease::unparse(&file))))
}

/// The runtime's declaring macros (`command_set!`, `device_handle!`,
/// `async_device_handle!`) laid out as a person would write them: prettyplease
/// fills a macro's body like a paragraph, since it cannot know its grammar.
/// A body that is an item (a handle's documented `struct`) is laid out as
/// one; a command set gets its table name and then one command a line.
#[cfg(feature = "pretty")]
fn lay_out_declarations(source: &str) -> String {
    let mut out = String::with_capacity(source.len());
    let mut lines = source.lines();
    while let Some(line) = lines.next() {
        out.push_str(line);
        out.push('\n');
        let declaring = ["command_set! {", "device_handle! {"].iter().any(|m| line.ends_with(m));
        if !declaring || line.starts_with(' ') {
            continue;
        }
        let mut body = String::new();
        for inner in lines.by_ref() {
            if inner == "}" {
                break;
            }
            body.push_str(inner);
            body.push('\n');
        }
        out.push_str(&declaration_body(&body));
        out.push_str("}\n");
    }
    out
}

#[cfg(feature = "pretty")]
fn declaration_body(body: &str) -> String {
    let Ok(tokens) = body.parse::<TokenStream>() else {
        return body.to_owned();
    };
    if let Ok(file) = syn::parse2::<syn::File>(tokens.clone()) {
        let items = prettyplease::unparse(&file);
        return items.lines().map(|l| if l.is_empty() { "\n".to_owned() } else { format!("    {l}\n") }).collect();
    }
    // One entry a line: the pieces between top-level `;` and `,`.
    let mut out = String::new();
    let mut entry = String::new();
    for token in tokens {
        match &token {
            proc_macro2::TokenTree::Punct(p) if matches!(p.as_char(), ';' | ',') => {
                out.push_str(&format!("    {}{}\n", entry.trim_end(), p.as_char()));
                entry.clear();
            }
            proc_macro2::TokenTree::Punct(p) if p.spacing() == proc_macro2::Spacing::Joint => entry.push(p.as_char()),
            proc_macro2::TokenTree::Group(g) if g.delimiter() == proc_macro2::Delimiter::Parenthesis => {
                entry.truncate(entry.trim_end().len());
                entry.push_str(&format!("({})", g.stream()));
                entry.push(' ');
            }
            other => {
                entry.push_str(&other.to_string());
                entry.push(' ');
            }
        }
    }
    if !entry.trim().is_empty() {
        out.push_str(&format!("    {}\n", entry.trim_end()));
    }
    out
}

/// The tokens as the compiler reads them: one item a line.
#[cfg(not(feature = "pretty"))]
fn render(_what: &str, tokens: TokenStream) -> Result<String, Error> {
    Ok(tokens.to_string())
}

/// The runtime crate's path as tokens: `::yosemitech_rtu`, `crate::rtu`,
/// checked to be `::`-separated identifiers.
fn runtime_path(path: &str) -> Result<TokenStream, String> {
    let body = path.strip_prefix("::").unwrap_or(path);
    let segments: Vec<&str> = body.split("::").collect();
    let is_ident = |s: &str| {
        let mut chars = s.chars();
        chars.next().is_some_and(|c| c == '_' || c.is_ascii_alphabetic())
            && chars.all(|c| c == '_' || c.is_ascii_alphanumeric())
    };
    if let Some(bad) = segments.iter().find(|s| !is_ident(s.trim())) {
        return Err(format!("`{bad}` is not an identifier"));
    }
    path.parse().map_err(|e: proc_macro2::LexError| e.to_string())
}

/// A blank line between top-level items, as rustfmt-formatted code has.
/// (No generated string literal spans lines, so lines are safe to inspect.)
#[cfg(feature = "pretty")]
fn space_items(source: &str) -> String {
    let mut out = String::with_capacity(source.len() + source.len() / 20);
    let mut previous: Option<&str> = None;
    for line in source.lines() {
        let ends_item =
            previous.is_some_and(|p| p == "}" || (!p.starts_with(' ') && (p.ends_with(';') || p.ends_with("{}"))));
        if ends_item && !line.is_empty() && !line.starts_with(' ') && !line.starts_with('}') {
            out.push('\n');
        }
        out.push_str(line);
        out.push('\n');
        previous = Some(line);
    }
    out
}
