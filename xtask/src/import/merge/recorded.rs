//! What the spec records: its examples' frames, figures, table errata and erratum ids.

use yosemitech_spec::{CommandErratum, CommandSpec, Example, Sensor, Spec};

use super::super::{DCommand, DExample, DraftFrame, printed_key};

/// The figures of a list, as the review shows them.
pub(super) fn figs(f: &[yosemitech_spec::Figure]) -> Vec<String> {
    f.iter().map(ToString::to_string).collect()
}

/// The recorded example's frames, in the draft's form.
pub(super) fn frames_of(x: &Example) -> (Option<DraftFrame>, Option<DraftFrame>) {
    (x.request.as_ref().map(printed_key), x.response.as_ref().map(printed_key))
}

/// What a command erratum's table prints, as the draft writes it.
pub(super) fn table_says(e: &CommandErratum) -> Vec<(&'static str, String)> {
    let mut out = Vec::new();
    if let Some(a) = e.table_address {
        out.push(("address", format!("0x{a:04X}")));
    }
    if let Some(n) = e.table_count {
        out.push(("count", n.to_string()));
    }
    if let Some(f) = e.table_function {
        out.push(("function", if f == yosemitech_rtu::Function::Read { "read".into() } else { "write".into() }));
    }
    out
}

pub(super) fn same_table(e: &CommandErratum, key: &str, val: &str) -> bool {
    table_says(e).iter().any(|(k, v)| *k == key && v.eq_ignore_ascii_case(val))
}

/// A table erratum someone already recorded: on this command for another
/// manual, or on the same shared command in another loaded sensor.
pub(super) fn known_table_erratum(
    spec: &Spec,
    sensor: &Sensor,
    name: &str,
    shared_from: Option<&str>,
    key: &str,
    val: &str,
) -> Option<String> {
    if let Some(c) = sensor.command(name)
        && let Some(e) = c.errata.iter().find(|e| same_table(e, key, val))
    {
        let m =
            e.manual.clone().or_else(|| sensor.manual.as_ref().and_then(|m| m.software.clone())).unwrap_or_default();
        return Some(format!("{} (SW {m})", e.id));
    }
    let frag = shared_from?;
    spec.sensors.iter().filter(|s| s.name != sensor.name).find_map(|s| {
        let c = s.commands.iter().find(|c| c.name == name && c.shared_from.as_deref() == Some(frag))?;
        let e = c.errata.iter().find(|e| same_table(e, key, val))?;
        Some(format!("{}'s {}", s.name, e.id))
    })
}

/// The figures of this manual for a recorded example, through the
/// command's section: the n-th figure of the spec's source for the
/// command is the n-th figure of the manual's section, when both list as
/// many; else the draft's own figures.
pub(super) fn mapped_figures(
    c: &CommandSpec,
    d: &DCommand,
    x: &Example,
    default_sw: &str,
    de: &DExample,
) -> Vec<String> {
    let source_manual = c.source.manual.as_deref().unwrap_or(default_sw);
    let x_manual = x.manual.as_deref().unwrap_or(default_sw);
    let old = figs(&c.source.figures);
    if x_manual == source_manual && old.len() == d.figures.len() && !old.is_empty() {
        let mapped: Option<Vec<String>> = x
            .figures
            .iter()
            .map(|f| old.iter().position(|o| *o == f.to_string()).map(|i| d.figures[i].clone()))
            .collect();
        if let Some(m) = mapped
            && de.figures.iter().all(|f| m.contains(f))
        {
            return m;
        }
    }
    de.figures.clone()
}

/// The id generator for errata the merge drafts: `<model>-<n>` after the
/// highest such id of the file (`docs/spec-language.md`), else `import-<n>`.
pub(super) fn id_generator(sensor: &Sensor) -> impl FnMut() -> String {
    let prefix = sensor.model.clone().unwrap_or_else(|| "import".into());
    let mut ids: Vec<String> = sensor.errata.iter().map(|e| e.id.clone()).collect();
    for c in &sensor.commands {
        ids.extend(c.errata.iter().map(|e| e.id.clone()));
        ids.extend(c.examples.iter().filter_map(|e| e.erratum.as_ref().map(|x| x.id.clone())));
    }
    let mut n = ids
        .iter()
        .filter_map(|id| id.strip_prefix(&format!("{prefix}-")).and_then(|r| r.parse::<u32>().ok()))
        .max()
        .unwrap_or(0);
    move || {
        n += 1;
        format!("{prefix}-{n}")
    }
}
