//! `--into`: the manual's procedure chapter against the spec's `procedure`
//! and `constants`. Procedures are not drafted; the review lists the
//! durations, counts and factors the chapter states, whether the spec has
//! them, and the procedure's commands the chapter does not name.

use yosemitech_spec::Sensor;

use super::Draft;
use super::review::ProcedureRow;

/// Section 3 of the manual: its first figure, page and the numbers it states.
struct ProcedureText {
    figure: Option<String>,
    page: Option<u32>,
    text: String,
    /// (value, unit word) of numbers with a unit: `10 s`, `3 seconds`, `10 times`.
    numbers: Vec<(f64, String)>,
    /// Decimal factors without a unit (`0.64`), and numbers after `*`.
    factors: Vec<f64>,
}

fn procedure_text(d: &Draft) -> Option<ProcedureText> {
    let lines = d.lines.get(d.chapter_end..)?;
    if lines.is_empty() {
        return None;
    }
    let page = {
        let before = d.lines.get(..=d.chapter_end)?;
        let ff: usize = before.iter().map(|l| l.matches('\u{c}').count()).sum();
        let any = d.lines.iter().any(|l| l.contains('\u{c}'));
        any.then_some(1 + ff as u32)
    };
    let figure = lines.iter().find_map(|l| {
        let t = l.trim().trim_start_matches('\u{c}');
        let r = t.strip_prefix("Figure")?;
        let n: String = r.trim_start().chars().take_while(char::is_ascii_digit).collect();
        (!n.is_empty()).then_some(n)
    });
    let text = lines.join("\n");
    let mut numbers = Vec::new();
    let mut factors = Vec::new();
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        if !chars[i].is_ascii_digit() || (i > 0 && (chars[i - 1].is_ascii_alphanumeric() || chars[i - 1] == '.')) {
            i += 1;
            continue;
        }
        let start = i;
        while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
            i += 1;
        }
        let num: String = chars[start..i].iter().collect::<String>().trim_end_matches('.').to_string();
        let Ok(v) = num.parse::<f64>() else { continue };
        let mut j = i;
        while j < chars.len() && chars[j] == ' ' {
            j += 1;
        }
        let word: String = chars[j..].iter().take_while(|c| c.is_ascii_alphabetic()).collect::<String>().to_lowercase();
        let after_star = chars[..start].iter().rev().find(|c| **c != ' ') == Some(&'*');
        let unit = match word.as_str() {
            "s" | "sec" | "secs" | "second" | "seconds" => Some("s"),
            "ms" => Some("ms"),
            "min" | "mins" | "minute" | "minutes" => Some("min"),
            "times" | "consecutive" | "readings" | "measurements" => Some("times"),
            _ => None,
        };
        match unit {
            Some(u) => numbers.push((v, u.to_string())),
            None if num.contains('.') || after_star => factors.push(v),
            None => {}
        }
    }
    Some(ProcedureText { figure, page, text, numbers, factors })
}

/// Compares section 3 with the spec's procedure and constants.
pub(crate) fn compare_procedure(sensor: &Sensor, d: &Draft, software: &str) -> Vec<ProcedureRow> {
    let Some(p) = procedure_text(d) else { return Vec::new() };
    let mut rows = Vec::new();
    let figure = p.figure.clone();
    let row = |what: String, manual: String, spec: Option<String>| ProcedureRow {
        what,
        manual,
        spec,
        figure: figure.clone(),
        page: p.page,
    };
    let proc = sensor.procedure.as_ref();
    let mut durations: Vec<(String, f64)> = Vec::new();
    let mut counts: Vec<(String, f64)> = Vec::new();
    if let Some(pr) = proc {
        if pr.warm_up_ms > 0 {
            durations.push(("procedure.warm_up_ms".into(), f64::from(pr.warm_up_ms)));
        }
        if pr.interval_ms > 0 {
            durations.push(("procedure.interval_ms".into(), f64::from(pr.interval_ms)));
        }
        if pr.readings > 1 {
            counts.push(("procedure.readings".into(), f64::from(pr.readings)));
        }
    }
    let mut factors: Vec<(String, f64)> = Vec::new();
    for c in &sensor.constants {
        for v in &c.values {
            match c.unit.as_deref() {
                Some("ms") => durations.push((format!("constant {}", c.name), *v)),
                _ if !c.is_list && v.fract() == 0.0 => counts.push((format!("constant {}", c.name), *v)),
                _ => factors.push((format!("constant {}", c.name), *v)),
            }
        }
    }
    let mut seen_spec: Vec<String> = Vec::new();
    let mut seen_manual: Vec<String> = Vec::new();
    for (v, unit) in &p.numbers {
        let shown = format!("{} {unit}", trim_num(*v));
        if seen_manual.contains(&shown) {
            continue;
        }
        seen_manual.push(shown.clone());
        let (ms, pool) = match unit.as_str() {
            "s" => (v * 1000.0, &durations),
            "ms" => (*v, &durations),
            "min" => (v * 60_000.0, &durations),
            _ => (*v, &counts),
        };
        let hits: Vec<String> = pool
            .iter()
            .filter(|(_, x)| (x - ms).abs() < 1e-6)
            .map(|(n, x)| format!("{n} = {}", trim_num(*x)))
            .collect();
        seen_spec.extend(pool.iter().filter(|(_, x)| (x - ms).abs() < 1e-6).map(|(n, _)| n.clone()));
        rows.push(row(shown, String::new(), (!hits.is_empty()).then(|| hits.join(", "))));
    }
    for v in &p.factors {
        let shown = trim_num(*v);
        if seen_manual.contains(&shown) {
            continue;
        }
        seen_manual.push(shown.clone());
        let hits: Vec<String> = factors
            .iter()
            .filter(|(_, x)| ((x - v) / v.abs().max(1e-9)).abs() < 1e-4)
            .map(|(n, x)| format!("{n} = {}", trim_num(*x)))
            .collect();
        seen_spec
            .extend(factors.iter().filter(|(_, x)| ((x - v) / v.abs().max(1e-9)).abs() < 1e-4).map(|(n, _)| n.clone()));
        rows.push(row(shown, String::new(), (!hits.is_empty()).then(|| hits.join(", "))));
    }
    for (n, x) in durations.iter().chain(&counts) {
        if !seen_spec.contains(n) && n.starts_with("procedure.") {
            rows.push(row(format!("{n} = {}", trim_num(*x)), format!("not stated in SW {software}'s section 3"), None));
        }
    }
    // The commands the procedure sends, by their titles.
    if let Some(pr) = proc {
        let text = p.text.to_ascii_lowercase();
        for (list, names) in [("before", &pr.before), ("read", &pr.read), ("after", &pr.after)] {
            for n in names {
                let Some(c) = sensor.command(n) else { continue };
                let title = c.title.to_ascii_lowercase();
                let words: Vec<&str> = title.split_whitespace().filter(|w| w.len() > 3).take(3).collect();
                let named = !words.is_empty() && words.iter().all(|w| text.contains(w));
                if !named {
                    rows.push(row(
                        format!("procedure.{list}: {n} (\"{}\")", c.title),
                        format!("not named in SW {software}'s section 3"),
                        None,
                    ));
                }
            }
        }
    }
    rows
}

fn trim_num(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 { format!("{}", v as i64) } else { format!("{v}") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_print_plainly() {
        assert_eq!(trim_num(10000.0), "10000");
        assert_eq!(trim_num(0.64), "0.64");
    }
}
