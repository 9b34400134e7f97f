//! The measurement procedure: the commands sent before and after, the reads
//! averaged, their number and the waits between them.
//!
//! A procedure resolves only when every command it names is one of the
//! sensor's, each `read` is a read that gives values and each `before` and
//! `after` step is sent without values; at least one command is read,
//! 1..=1000 times, and no wait is longer than a day.

use crate::Spanned;

use crate::check::check_text;
use crate::diag::{Pos, Reporter};
use crate::document::ProcedureDoc;
use crate::model::{CommandSpec, Procedure};
use crate::names::escape;

use super::sensor::{resolve_provenance, resolve_source};

/// The procedure, with every command it names checked against the sensor's.
pub(super) fn resolve_procedure(p: &ProcedureDoc, commands: &[CommandSpec], r: &mut Reporter<'_>) -> Option<Procedure> {
    let mut ok = true;
    let names: Vec<&str> = commands.iter().map(|c| c.name.as_str()).collect();
    let steps = |list: &[Spanned<String>], what: &str, r: &mut Reporter<'_>, ok: &mut bool| -> Vec<String> {
        let mut out = Vec::new();
        for (i, name) in list.iter().enumerate() {
            let key = format!("procedure.{what}[{i}]");
            match commands.iter().find(|c| c.name == name.value) {
                None => {
                    let help = match crate::suggest::closest(&name.value, &names) {
                        Some(best) => format!("did you mean `{best}`?"),
                        None => format!(
                            "the sensor's commands are {}; name one of them, or add it to `commands`",
                            names.join(", ")
                        ),
                    };
                    r.error(
                        Pos::at(name),
                        key,
                        format!("the sensor has no command called `{}`", escape(&name.value)),
                        Some(help),
                    );
                    *ok = false;
                }
                Some(c) if what == "read" && !(c.is_read() && c.named_fields().next().is_some()) => {
                    r.error(
                        Pos::at(name),
                        key,
                        format!("`{}` is not a read that gives values", c.name),
                        Some("`read` lists the reads whose values the procedure averages".into()),
                    );
                    *ok = false;
                }
                Some(c) if what != "read" && !c.takes_no_values() => {
                    r.error(
                        Pos::at(name),
                        key,
                        format!("`{}` needs values to send", c.name),
                        Some(format!("`{what}` lists commands sent without values: triggers and reads")),
                    );
                    *ok = false;
                }
                Some(c) => out.push(c.name.clone()),
            }
        }
        out
    };
    let before = steps(&p.before, "before", r, &mut ok);
    let read = steps(&p.read.value, "read", r, &mut ok);
    let after = steps(&p.after, "after", r, &mut ok);
    if p.read.value.is_empty() {
        r.error(Pos::at(&p.read), "procedure.read", "a procedure reads at least one command", None);
        ok = false;
    }
    let readings = p.readings.as_ref().map_or(1, |n| n.value);
    if let Some(n) = &p.readings
        && !(1..=1000).contains(&n.value)
    {
        r.error(Pos::at(n), "procedure.readings", format!("{} readings: use 1..=1000", n.value), None);
        ok = false;
    }
    const DAY_MS: u32 = 86_400_000;
    for (value, key) in [(&p.warm_up_ms, "procedure.warm_up_ms"), (&p.interval_ms, "procedure.interval_ms")] {
        if let Some(v) = value
            && v.value > DAY_MS
        {
            r.error(Pos::at(v), key, format!("{} ms is longer than a day", v.value), None);
            ok = false;
        }
    }
    let source = p.source.as_ref().map(|s| resolve_source(s, "procedure.source", r));
    let provenance = p.provenance.as_ref().map(|doc| {
        let at = doc.sources.first().map_or(Pos { line: 0, column: 0 }, Pos::at);
        resolve_provenance(doc, "procedure.provenance", at, r)
    });
    let doc = p.doc.as_ref().map(|d| check_text(d, "procedure.doc", r));
    ok.then(|| Procedure {
        source,
        provenance,
        doc,
        before,
        warm_up_ms: p.warm_up_ms.as_ref().map_or(0, |v| v.value),
        read,
        readings,
        interval_ms: p.interval_ms.as_ref().map_or(0, |v| v.value),
        after,
    })
}
