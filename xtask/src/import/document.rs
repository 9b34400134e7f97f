//! The draft as the spec crate's document types: what the importer writes is
//! whatever those types serialize to, so a draft has the schema's shape by
//! construction. What the importer could not decide becomes a [`Todo`] at the
//! key it concerns, written as a comment by [`super::annotate`].

use std::collections::BTreeMap;

use serde::de::DeserializeOwned;
use serde::de::value::StrDeserializer;
use yosemitech_spec::Spanned;
use yosemitech_spec::document::{
    AddressRangeDoc, CommandDoc, CommandErratumDoc, CrcDoc, ExampleDoc, ExampleErratumDoc, FieldDoc, FieldTypeDoc,
    FigureDoc, FlagDoc, IncludeDoc, ManualDoc, ParityDoc, SensorDoc, SerialDoc, SourceDoc, SpecFile, StatedValue,
    TableSaysDoc, VariantDoc,
};

use super::draft::{DCommand, DExample, DField, Draft, DraftFrame};
use super::header::Header;
use super::parse::variant_name;
use super::render::{CommandRender, one_line_text};

/// A point a person must resolve, at the key path it concerns
/// (`sensor.serial`, `commands[2]`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Todo {
    /// The key path, as [`super::annotate::key_paths`] names the lines.
    pub at: String,
    /// What to resolve, on one line.
    pub text: String,
}

impl Todo {
    fn new(at: impl Into<String>, text: impl AsRef<str>) -> Self {
        Todo { at: at.into(), text: one_line_text(text.as_ref()) }
    }
}

/// The document value a spelling names (`"f32"`, `"read"`): the spec crate's
/// own deserializer decides, so the importer keeps no copy of the spellings.
fn spelled<T: DeserializeOwned>(text: &str) -> Option<T> {
    T::deserialize(StrDeserializer::<serde::de::value::Error>::new(text)).ok()
}

fn figure(label: &str) -> FigureDoc {
    match label.parse() {
        Ok(n) if label.chars().all(|c| c.is_ascii_digit()) => FigureDoc::Number(n),
        _ => FigureDoc::Text(label.to_string()),
    }
}

pub(super) fn figures(labels: &[String]) -> Vec<FigureDoc> {
    labels.iter().map(|l| figure(l)).collect()
}

fn text(t: impl Into<String>) -> Option<Spanned<String>> {
    Some(Spanned::unplaced(t.into()))
}

/// The sensor file a draft becomes, and its TODOs.
pub(super) fn spec_file(d: &Draft, h: &Header, name: &str, file: &str) -> (SpecFile, Vec<Todo>) {
    let mut todos = Vec::new();
    let serial = match h.baud {
        Some(baud) => {
            if h.data_bits.is_none() || h.parity.is_none() || h.stop_bits.is_none() {
                todos.push(Todo::new("sensor.serial", "data bits, parity or stop bits not stated; defaults 8N1 shown"));
            }
            serial_doc(baud, h)
        }
        None => {
            todos.push(Todo::new("sensor.serial", "the manual states no baud rate; 9600 8N1 shown"));
            serial_doc(9600, h)
        }
    };
    let revision = h.revision.clone().unwrap_or_else(|| {
        todos.push(Todo::new("sensor.manual.revision", "the manual's scope line names no revision"));
        String::new()
    });
    let sensor = SensorDoc {
        name: Spanned::unplaced(name.to_string()),
        title: Spanned::unplaced(if h.title.is_empty() { name } else { &h.title }.to_string()),
        doc: Spanned::unplaced(format!("Imported from {file}.")),
        model: None,
        model_code: None,
        also_model_codes: Vec::new(),
        aliases: Vec::new(),
        manual: Some(ManualDoc {
            title: Spanned::unplaced(h.manual_title.clone()),
            revision: Spanned::unplaced(revision),
            software: h.software.clone().map(Spanned::unplaced),
            file: text(file),
            serial_claims: Vec::new(),
        }),
        provenance: None,
        revisions: Vec::new(),
        serial,
        addresses: AddressRangeDoc { min: Spanned::unplaced(1), max: Spanned::unplaced(247) },
        default_address: Spanned::unplaced(1),
    };
    // One include per fragment file, listing the commands taken from it.
    let mut include: Vec<Spanned<IncludeDoc>> = Vec::new();
    for (fragment, command) in d.commands.iter().filter_map(|c| c.uses.as_ref()) {
        let only = Spanned::unplaced(command.clone());
        match include.iter_mut().find(|i| i.value.file == *fragment) {
            Some(i) => i.value.only.get_or_insert_with(Vec::new).push(only),
            None => include.push(Spanned::unplaced(IncludeDoc { file: fragment.clone(), only: Some(vec![only]) })),
        }
    }
    include.sort_by(|a, b| a.value.file.cmp(&b.value.file));
    let mut erratum_id = 0;
    let mut next_id = || {
        erratum_id += 1;
        format!("import-{erratum_id}")
    };
    let mut commands = Vec::new();
    for (k, c) in d.commands.iter().enumerate() {
        let mut o =
            CommandRender { manual: None, since: None, todos: None, table_notes: Vec::new(), next_id: &mut next_id };
        let (doc, command_todos) = command_doc(c, &mut o);
        todos.extend(command_todos.into_iter().map(|t| Todo { at: format!("commands[{k}]{}", t.at), ..t }));
        commands.push(doc);
    }
    let spec = SpecFile {
        sensor: Some(sensor),
        fragment: None,
        include,
        commands,
        procedure: None,
        constants: Vec::new(),
        errata: Vec::new(),
        derived: Vec::new(),
    };
    (spec, todos)
}

fn serial_doc(baud: u32, h: &Header) -> SerialDoc {
    SerialDoc {
        baud: Spanned::unplaced(baud),
        data_bits: Spanned::unplaced(h.data_bits.map_or(8, u32::from)),
        parity: h.parity.and_then(spelled).unwrap_or(ParityDoc::None),
        stop_bits: Spanned::unplaced(h.stop_bits.map_or(1, u32::from)),
    }
}

/// One drafted command, and its TODOs at key paths relative to the command
/// (`""`: the command itself).
pub(crate) fn command_doc(c: &DCommand, o: &mut CommandRender<'_>) -> (CommandDoc, Vec<Todo>) {
    let mut todos: Vec<Todo> = o
        .todos
        .unwrap_or(&c.todos)
        .iter()
        .map(|t| Todo::new("", format!("section {}: {}", c.section, one_line_text(t))))
        .collect();
    let manual = || o.manual.map(|m| Spanned::unplaced(m.to_string()));
    let used = c.uses.as_ref().map(|(_, n)| Spanned::unplaced(n.clone()));
    let defined = used.is_none();
    let mut doc = CommandDoc {
        name: defined.then(|| Spanned::unplaced(c.name.clone())),
        uses: used,
        title: text(c.title.clone()),
        since: o.since.map(|s| Spanned::unplaced(s.to_string())),
        role: None,
        calibrates: None,
        units: None,
        doc: defined.then(|| Spanned::unplaced(format!("Section {} of the manual.", c.section))),
        source: Some(SourceDoc {
            section: Spanned::unplaced(c.section.clone()),
            figures: figures(&c.figures),
            manual: manual(),
        }),
        provenance: None,
        function: None,
        address: None,
        count: None,
        trigger: None,
        fixed_slave: None,
        extra_byte_counts: Vec::new(),
        fields: None,
        examples: Vec::new(),
        errata: Vec::new(),
    };
    if defined {
        doc.function =
            c.function.and_then(|f| spelled(if f == 0x03 { "read" } else { "write" })).map(Spanned::unplaced);
        doc.address = c.address.map(|a| Spanned::unplaced(u32::from(a)));
        doc.count = c.count.map(|n| Spanned::unplaced(u32::from(n)));
        let is_trigger_read = c.function == Some(0x03)
            && c.fields.is_empty()
            && c.examples
                .iter()
                .any(|e| e.response.as_ref().is_some_and(|r| r.open_ended && r.bytes.get(2) == Some(&Some(0))));
        if c.count.is_some_and(|n| n == 0 || is_trigger_read) {
            doc.trigger = Some(Spanned::unplaced(true));
        }
        let slave = |e: &DExample| e.request.as_ref().and_then(|r| r.bytes.first().copied().flatten());
        if c.examples.iter().any(|e| slave(e) == Some(0xFF)) {
            doc.fixed_slave = Some(Spanned::unplaced(0xFF));
        }
        if !c.fields.is_empty() {
            doc.fields = Some(Spanned::unplaced(c.fields.iter().map(field_doc).collect()));
        }
    }
    for (k, (fig, key, value)) in c.table_errata.iter().enumerate() {
        let note = o
            .table_notes
            .get(k)
            .cloned()
            .unwrap_or_else(|| "The register table disagrees with the printed frames; the frames are used.".into());
        let (erratum, todo) = table_erratum_doc((o.next_id)(), fig, key, value, manual(), note);
        todos.extend(todo.map(|t| Todo::new(format!(".errata[{k}]"), t)));
        doc.errata.push(erratum);
    }
    for e in &c.examples {
        doc.examples.push(example_doc(e, &e.figures, manual(), stated_values(c, e), o.next_id));
    }
    (doc, todos)
}

fn field_doc(f: &DField) -> FieldDoc {
    let ty = spelled(f.ty).unwrap_or(FieldTypeDoc::Reserved);
    let size = matches!(ty, FieldTypeDoc::Reserved | FieldTypeDoc::Ascii | FieldTypeDoc::Enum | FieldTypeDoc::Flags)
        .then(|| Spanned::unplaced(f.size as u32));
    let named = |fallback: &str, doc: &str| (text(f.name.as_deref().unwrap_or(fallback)), text(doc));
    let (name, doc) = match ty {
        FieldTypeDoc::Reserved => (None, None),
        FieldTypeDoc::Ascii => named("text", "Text."),
        FieldTypeDoc::Enum | FieldTypeDoc::Flags => named("code", "Code (see the section's table)."),
        _ => named("value", "Value."),
    };
    let codes = || {
        f.codes
            .iter()
            .map(|(v, label)| (Spanned::unplaced(variant_name(label, *v)), u32::from(*v), text(label.clone())))
    };
    FieldDoc {
        name,
        ty: Spanned::unplaced(ty),
        offset: None,
        byte_order: f.order.and_then(spelled).map(Spanned::unplaced),
        size,
        padding: None,
        fill: None,
        unit: None,
        doc,
        range: None,
        typical: None,
        variants: (ty == FieldTypeDoc::Enum).then(|| {
            Spanned::unplaced(
                codes().map(|(name, value, doc)| VariantDoc { name, value: Spanned::unplaced(value), doc }).collect(),
            )
        }),
        flags: (ty == FieldTypeDoc::Flags).then(|| {
            Spanned::unplaced(
                codes().map(|(name, mask, doc)| FlagDoc { name, mask: Spanned::unplaced(mask), doc }).collect(),
            )
        }),
        absent: None,
        examples: Vec::new(),
    }
}

/// A table erratum: where the register table and the printed frames
/// disagree. With a TODO when the table's words are not a `table:` the spec
/// reads (`address: 0x2600`).
pub(super) fn table_erratum_doc(
    id: String,
    fig: &str,
    key: &str,
    value: &str,
    manual: Option<Spanned<String>>,
    note: String,
) -> (CommandErratumDoc, Option<String>) {
    let table: Option<TableSaysDoc> = yosemitech_spec::from_yaml_str(&format!("{key}: {value}")).ok();
    let todo = table.is_none().then(|| format!("the table prints {key} {value}"));
    let erratum = CommandErratumDoc {
        id: Spanned::unplaced(id),
        figure: (!fig.is_empty()).then(|| Spanned::unplaced(figure(fig))),
        manual,
        table: table.unwrap_or(TableSaysDoc { address: None, count: None, function: None }),
        note: Spanned::unplaced(note),
    };
    (erratum, todo)
}

/// An example's `values:`, from the values a manual states as text
/// (`7.0`, `"Calibrated"`), by field name.
pub(super) type StatedValues = Option<Spanned<BTreeMap<String, Spanned<StatedValue>>>>;

/// The values of a drafted example, by the names of the drafted fields.
fn stated_values(c: &DCommand, e: &DExample) -> StatedValues {
    (!e.values.is_empty() || c.fields.iter().all(|f| f.name.is_none())).then(|| {
        let named = e.values.iter().filter_map(|(offset, value)| {
            let name = c.fields.iter().find(|f| f.offset == *offset).and_then(|f| f.name.clone())?;
            Some((name, value.as_str()))
        });
        stated(named)
    })
}

/// Values by name, each read as YAML would (`7.0` a number), else as text.
fn stated<'a>(named: impl Iterator<Item = (String, &'a str)>) -> Spanned<BTreeMap<String, Spanned<StatedValue>>> {
    let read =
        |value: &str| yosemitech_spec::from_yaml_str(value).unwrap_or_else(|_| StatedValue::Text(value.to_owned()));
    Spanned::unplaced(named.map(|(name, value)| (name, Spanned::unplaced(read(value)))).collect())
}

/// An example of frames a manual prints, cited as `figures` (which may
/// differ from the draft's own labels when merged into a recorded command).
pub(super) fn example_doc(
    e: &DExample,
    figure_labels: &[String],
    manual: Option<Spanned<String>>,
    values: StatedValues,
    next_id: &mut dyn FnMut() -> String,
) -> ExampleDoc {
    let printed = |f: &Option<DraftFrame>| f.as_ref().map(|f| Spanned::unplaced(f.text()));
    let crc =
        |f: &Option<DraftFrame>| f.as_ref().filter(|f| f.crc.is_none()).map(|_| Spanned::unplaced(CrcDoc::Missing));
    let wrong = [("request", &e.request), ("response", &e.response)]
        .into_iter()
        .filter_map(|(key, f)| Some((key, f.as_ref().filter(|f| f.crc_wrong())?)))
        .next_back();
    let erratum = wrong.map(|(key, f)| {
        let at = if key == "request" { 0 } else { e.figures.len().saturating_sub(1) };
        let correct = f.computed_crc().unwrap_or([0, 0]);
        let printed = f.crc.unwrap_or([0, 0]);
        let corrected = text(f.spec_text(Some(correct)));
        ExampleErratumDoc {
            id: Spanned::unplaced(next_id()),
            figure: Spanned::unplaced(figure(e.figures.get(at).map_or("", String::as_str))),
            printed: Spanned::unplaced(format!(
                "The printed CRC {:02X} {:02X} is wrong; the frame's CRC is {:02X} {:02X}.",
                printed[0], printed[1], correct[0], correct[1]
            )),
            corrected_request: if key == "request" { corrected.clone() } else { None },
            corrected_response: if key == "response" { corrected } else { None },
            printed_decodes: Spanned::unplaced(false),
        }
    });
    ExampleDoc {
        figures: figures(figure_labels),
        manual,
        request: printed(&e.request),
        request_crc: crc(&e.request),
        response: printed(&e.response),
        response_crc: crc(&e.response),
        values,
        doc: None,
        erratum,
        also_in: Vec::new(),
    }
}
