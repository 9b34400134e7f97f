//! `--into`: is the manual one of the target probe's? Its command set,
//! its cover title and the model code of the serial numbers it prints,
//! against every loaded spec; a refusal names the spec it seems to belong to.

use yosemitech_spec::{Sensor, Spec};

use super::Draft;
use super::review::Identified;

/// A command's wire identity: function code, start address, register count.
type WireKey = (u8, u16, u16);

/// The serial numbers a manual prints (`YL0914010022`), in order, once each.
pub(crate) fn printed_serials(lines: &[String]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for l in lines {
        for (i, _) in l.match_indices("YL") {
            let digits: String = l[i + 2..].chars().take_while(char::is_ascii_digit).collect();
            if digits.len() >= 4 {
                let sn = format!("YL{digits}");
                if !out.contains(&sn) {
                    out.push(sn);
                }
            }
        }
    }
    out
}

fn draft_keys(d: &Draft) -> Vec<WireKey> {
    d.commands.iter().filter_map(|c| Some((c.function?, c.address?, c.count?))).collect()
}

fn sensor_keys(s: &Sensor) -> Vec<WireKey> {
    s.commands.iter().map(|c| (c.function.code(), c.address, c.count)).collect()
}

/// How well a manual's commands match each loaded sensor's: a Jaccard
/// index weighted by rarity (a command every probe has, like the serial
/// number, counts less than the measurement reads only one probe has).
fn scores(spec: &Spec, d: &Draft) -> Vec<(f64, usize)> {
    let keys = draft_keys(d);
    let per_sensor: Vec<Vec<WireKey>> = spec.sensors.iter().map(sensor_keys).collect();
    let weight = |k: &WireKey| {
        let df = per_sensor.iter().filter(|s| s.contains(k)).count();
        1.0 / df.max(1) as f64
    };
    per_sensor
        .iter()
        .map(|s| {
            let shared: Vec<&WireKey> = keys.iter().filter(|k| s.contains(k)).collect();
            let inter: f64 = shared.iter().map(|k| weight(k)).sum();
            let union: f64 =
                keys.iter().map(weight).sum::<f64>() + s.iter().filter(|k| !keys.contains(k)).map(weight).sum::<f64>();
            (if union > 0.0 { inter / union } else { 0.0 }, shared.len())
        })
        .collect()
}

/// The sensor's file as the user named it, for messages.
pub(crate) fn shown(s: &Sensor) -> String {
    s.file.display().to_string()
}

fn sensor_label(s: &Sensor) -> String {
    match (&s.model, &s.model_code) {
        (Some(m), Some(c)) => format!("{} ({m}, model code {c})", s.name),
        (Some(m), None) => format!("{} ({m})", s.name),
        (None, Some(c)) => format!("{} (model code {c})", s.name),
        (None, None) => s.name.clone(),
    }
}

/// Decides whether the manual is one of `target`'s. Three signals: the
/// command set (a weighted match of function, address and count), the
/// cover title's distinctive words, and the model code of the serial
/// numbers it prints. The manuals are one template, so the commands alone
/// do not tell probes apart (the Y514 and Y551 manuals print the same
/// frames), and several manuals print a sibling's serial number: the
/// target is accepted when its commands fit (no other spec's fit clearly
/// better) and its title or its model code agrees. `Err` is the refusal,
/// naming the loaded spec the manual seems to belong to.
pub(crate) fn identify(spec: &Spec, target: usize, d: &Draft) -> Result<Identified, String> {
    let serials = printed_serials(&d.lines);
    let codes: Vec<String> = serials.iter().filter_map(|s| s.get(2..4)).map(str::to_string).collect();
    let code = codes.first().cloned();
    let scores = scores(spec, d);
    let t = &spec.sensors[target];
    let (t_score, t_shared) = scores[target];
    let manual_commands = draft_keys(d).len();
    let words = title_words(&format!("{} {}", d.header.title, d.header.manual_title));
    let titled = |s: &Sensor| {
        let mut own = title_words(&s.title);
        for m in s.manuals() {
            own.extend(title_words(&m.title));
        }
        words.iter().any(|w| own.contains(w))
    };
    let coded = |s: &Sensor| code.is_some() && s.model_code == code;
    let agrees = |s: &Sensor| titled(s) || coded(s);
    let describe = |i: usize| {
        let s = &spec.sensors[i];
        let why = match (titled(s), coded(s)) {
            (true, true) => "title and model code agree",
            (true, false) => "title agrees",
            (false, true) => "model code agrees",
            (false, false) => "closest commands; title and model code differ",
        };
        format!("{} ({}; {} of the manual's {manual_commands} commands; {why})", shown(s), sensor_label(s), scores[i].1)
    };
    // The best other spec: one whose title or code agrees first, then by commands.
    let best = scores
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != target)
        .max_by(|a, b| {
            let ka = (agrees(&spec.sensors[a.0]), a.1.0);
            let kb = (agrees(&spec.sensors[b.0]), b.1.0);
            ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
        })
        .map(|(i, s)| (i, *s));
    let best_by_commands = scores
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != target)
        .max_by(|a, b| a.1.0.total_cmp(&b.1.0))
        .map(|(i, s)| (i, *s));
    let printed = match &code {
        Some(c) => format!("its serial number {} carries model code {c}", serials.first().cloned().unwrap_or_default()),
        None => "it prints no serial number".into(),
    };
    let facts = format!(
        "{printed}{}, its title is \"{}\", and {t_shared} of its {manual_commands} commands are in that spec",
        t.model_code.as_ref().map(|c| format!(" ({} is {c})", t.name)).unwrap_or_default(),
        d.header.title
    );
    let refuse = |reason: &str, other: Option<usize>| {
        let belongs = match other {
            Some(o) => format!("it seems to belong to {}", describe(o)),
            None => {
                "no loaded spec fits it: import it as a new sensor (`cargo xtask import MANUAL --name NAME`)".into()
            }
        };
        Err(format!("not a manual of `{}` ({}): {reason}; {facts}; {belongs}", t.name, shown(t)))
    };
    let candidate = |min: f64| best.filter(|(_, (sc, _))| *sc >= min).map(|(i, _)| i);
    // Commands that fit another spec clearly better.
    if let Some((b, (b_score, _))) = best_by_commands
        && b_score > t_score + 0.15
    {
        let named = best.filter(|(i, (sc, _))| agrees(&spec.sensors[*i]) && *sc > t_score + 0.15).map_or(b, |(i, _)| i);
        return refuse("its commands fit another spec better", Some(named));
    }
    if t_score < 0.3 {
        return refuse("its commands do not fit", candidate(0.3));
    }
    let identity_known = !words.is_empty() || code.is_some();
    if identity_known && !agrees(t) {
        return refuse("neither its title nor its model code is this probe's", candidate(t_score - 0.15));
    }
    // The printed code is another loaded probe's, whose commands fit as well, and the title does not decide.
    if !titled(t) && !coded(t) && code.is_some() {
        let other =
            spec.sensors.iter().enumerate().find(|(i, s)| *i != target && coded(s) && scores[*i].0 >= t_score - 0.05);
        if let Some((o, _)) = other {
            return refuse("its model code is another probe's", Some(o));
        }
    }
    let note = (code.is_some() && !coded(t)).then(|| {
        format!(
            "the manual prints model code {} where {} is {}: a sibling's serial number, as several manuals print; the title and the commands decide",
            code.clone().unwrap_or_default(),
            t.name,
            t.model_code.clone().unwrap_or_default()
        )
    });
    Ok(Identified {
        serial_numbers: serials,
        model_code: code,
        spec_model_code: t.model_code.clone(),
        commands_in_manual: manual_commands,
        commands_in_spec: t.commands.len(),
        shared: t_shared,
        score: (t_score * 100.0).round() / 100.0,
        note,
    })
}

/// The words of a title that tell probes apart (not "MODBUS", "sensor", ...).
fn title_words(title: &str) -> Vec<String> {
    const COMMON: &[&str] = &[
        "modbus",
        "rtu",
        "programmer",
        "programmers",
        "manuel",
        "manual",
        "manuals",
        "sensor",
        "sensors",
        "probe",
        "probes",
        "optical",
        "for",
        "the",
        "and",
        "or",
        "of",
        "with",
        "instruction",
        "instructions",
        "yosemitech",
        "digital",
        "self",
        "cleaning",
        "wiper",
        "en",
    ];
    let mut out: Vec<String> = Vec::new();
    for w in title.split(|c: char| !c.is_ascii_alphanumeric()).map(str::to_ascii_lowercase) {
        if w.len() >= 2 && !COMMON.contains(&w.as_str()) && !w.chars().all(|c| c.is_ascii_digit()) && !out.contains(&w)
        {
            out.push(w);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serial_numbers_and_title_words() {
        let lines = vec!["For example: \"YL0914010022\" and YL0914010022".to_string(), "YL12 YLX".into()];
        assert_eq!(printed_serials(&lines), vec!["YL0914010022".to_string()]);
        assert_eq!(title_words("Optical Nitrogen Sensor, MODBUS RTU Programmer Manuel"), vec!["nitrogen"]);
        assert_eq!(title_words("Multi - Parameter Sensor"), vec!["multi", "parameter"]);
    }
}
