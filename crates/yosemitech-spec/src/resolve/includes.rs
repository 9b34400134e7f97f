//! Includes and fragments: the include paths a file names, the fragment
//! commands they bring in (all of them, or those `only` lists), and what a
//! fragment file may hold.
//!
//! An include is a relative path to a `.yaml` sibling that is a fragment;
//! chains nest at most [`MAX_INCLUDE_DEPTH`] files, every cycle is reported
//! once (at the include that closes it), and a command reached twice is
//! collected once. When an include cannot be used, the walk says so, so that
//! a `use` of one of its commands is not reported as missing as well.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use crate::diag::{Diagnostic, Pos, Reporter};
use crate::document::SpecFile;
use crate::names::escape;
use crate::sources::sibling;

use super::command::command_key;
use super::{Def, MAX_INCLUDE_DEPTH, Parsed, shown, top_key_pos};
use crate::check::{check_name, check_text};

/// Why an include entry cannot name a fragment file, or the file it names.
pub(super) fn include_target(file: &Path, include: &str) -> Result<PathBuf, String> {
    let path = Path::new(include);
    if include.trim().is_empty() {
        return Err("the include path is empty".into());
    }
    if path.is_absolute() || include.starts_with('/') || include.starts_with('\\') {
        return Err("it is an absolute path".into());
    }
    if !matches!(path.extension().and_then(|e| e.to_str()), Some("yaml" | "yml")) {
        return Err("it is not a `.yaml` file".into());
    }
    Ok(sibling(file, include))
}

pub(super) fn check_fragment(doc: &SpecFile, r: &mut Reporter<'_>) {
    if let Some(f) = &doc.fragment {
        check_name(&f.name, "fragment.name", r);
        check_text(&f.doc, "fragment.doc", r);
    }
    for (key, present) in [
        ("constants", !doc.constants.is_empty()),
        ("errata", !doc.errata.is_empty()),
        ("procedure", doc.procedure.is_some()),
        ("derived", !doc.derived.is_empty()),
    ] {
        if present {
            r.error(
                top_key_pos(r.text, key),
                key,
                format!("a fragment cannot hold `{key}`"),
                Some("a fragment holds only `commands` and `include`; move this to the sensor files".into()),
            );
        }
    }
    for (i, c) in doc.commands.iter().enumerate() {
        if let Some(u) = &c.uses {
            r.error(
                Pos::at(u),
                format!("{}.use", command_key(i, c)),
                "`use` belongs in sensor files, not fragments",
                Some("a fragment defines commands with `name`; sensor files `use` them".into()),
            );
        }
        if let Some(since) = &c.since {
            r.error(
                Pos::at(since),
                format!("{}.since", command_key(i, c)),
                "`since` belongs in sensor files: firmware revisions are a probe's own",
                Some("give `since` in the sensor file's `use` entry".into()),
            );
        }
    }
}

/// Depth-first over includes, collecting fragment commands; reports cycles
/// (each once) and includes of files that are not fragments. Returns false
/// when some included file could not be used, so that its commands are
/// unknown rather than missing.
pub(super) fn collect_includes<'d>(
    files: &'d BTreeMap<PathBuf, Parsed>,
    file: &Path,
    stack: &mut Vec<PathBuf>,
    out: &mut Vec<Def<'d>>,
    diags: &mut Vec<Diagnostic>,
    cycles: &mut BTreeSet<BTreeSet<PathBuf>>,
) -> bool {
    let Some(parsed) = files.get(file) else { return false };
    let Some(doc) = &parsed.doc else { return false };
    let mut complete = true;
    for (i, inc) in doc.include.iter().enumerate() {
        // Invalid include paths were reported while parsing.
        let Ok(path) = include_target(file, &inc.value.file) else {
            complete = false;
            continue;
        };
        let mut r = Reporter { file, text: &parsed.text, out: diags };
        if let Some(start) = stack.iter().position(|p| *p == path) {
            let members: BTreeSet<PathBuf> = stack[start..].iter().cloned().collect();
            if cycles.insert(members) {
                let chain: Vec<String> = stack[start..].iter().chain([&path]).map(|p| shown(p, file)).collect();
                r.error(
                    Pos::at(inc),
                    format!("include[{i}]"),
                    format!("include cycle: {}", chain.join(" -> ")),
                    Some("a fragment may not include itself, directly or through others; remove this include".into()),
                );
            }
            continue;
        }
        if stack.len() >= MAX_INCLUDE_DEPTH {
            r.error(
                Pos::at(inc),
                format!("include[{i}]"),
                format!("includes nest deeper than {MAX_INCLUDE_DEPTH} files"),
                Some("include the fragments from the sensor file directly".into()),
            );
            complete = false;
            continue;
        }

        // Unreadable or broken files were reported where they are.
        let Some(inc_doc) = files.get(&path).and_then(|p| p.doc.as_ref()) else {
            complete = false;
            continue;
        };
        let Some(fragment) = &inc_doc.fragment else {
            let what = match &inc_doc.sensor {
                Some(s) => format!("it describes the sensor `{}`", escape(&s.name.value)),
                None => "it has no `fragment:` section".into(),
            };
            r.error(
                Pos::at(inc),
                format!("include[{i}]"),
                format!("`{}` is not a fragment: {what}", escape(&inc.value.file)),
                Some("only files with a `fragment:` section can be included".into()),
            );
            complete = false;
            continue;
        };
        stack.push(path.clone());
        complete &= collect_includes(files, &path, stack, out, diags, cycles);
        stack.pop();
        let Some((path_ref, _)) = files.get_key_value(&path) else { continue };
        let mut r = Reporter { file, text: &parsed.text, out: diags };
        let defined: Vec<&str> =
            inc_doc.commands.iter().filter_map(|c| c.name.as_ref().map(|n| n.value.as_str())).collect();
        if let Some(only) = &inc.value.only {
            for (j, name) in only.iter().enumerate() {
                if !defined.contains(&name.value.as_str()) {
                    let help = match crate::suggest::closest(&name.value, &defined) {
                        Some(best) => {
                            format!("did you mean `{best}`? `{}` defines: {}", inc.value.file, defined.join(", "))
                        }
                        None => format!("`{}` defines: {}", inc.value.file, defined.join(", ")),
                    };
                    r.error(
                        Pos::at(name),
                        format!("include[{i}].only[{j}]"),
                        format!("`{}` defines no command called `{}`", escape(&inc.value.file), escape(&name.value)),
                        Some(help),
                    );
                }
            }
        }
        for (index, c) in inc_doc.commands.iter().enumerate() {
            let Some(name) = &c.name else { continue };
            let taken = inc.value.only.as_ref().is_none_or(|only| only.iter().any(|o| o.value == name.value));
            if taken && !out.iter().any(|d| d.file == path_ref.as_path() && d.index == index) {
                out.push(Def { file: path_ref.as_path(), doc: c, index, fragment: Some(fragment.name.value.clone()) });
            }
        }
    }
    complete
}
