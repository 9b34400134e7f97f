//! What the cover and the first chapter say about the manual.

/// What the cover and the first chapter say about the manual.
#[derive(Debug, Clone)]
pub(crate) struct Header {
    pub(crate) title: String,
    pub(crate) manual_title: String,
    pub(crate) revision: Option<String>,
    pub(crate) software: Option<String>,
    pub(crate) baud: Option<u32>,
    pub(crate) data_bits: Option<u8>,
    pub(crate) parity: Option<&'static str>,
    pub(crate) stop_bits: Option<u8>,
}

/// The revision number printed within a dozen characters after `key` in
/// `text` ("hardware Rev1.0": "1.0"), if any.
fn revision_after(text: &str, key: &str) -> Option<String> {
    let i = text.find(key)?;
    let rest = &text[i + key.len()..];
    let j = rest.find("rev")?;
    if j > 12 {
        return None;
    }
    let v: String = rest[j + 3..].trim_start().chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    let v = v.trim_end_matches('.').to_string();
    (!v.is_empty()).then_some(v)
}

pub(super) fn parse_header(lines: &[String]) -> Header {
    // Cover: the non-empty lines before the table of contents, minus the company lines.
    let mut cover = Vec::new();
    for l in lines.iter().take(40) {
        let t = l.trim();
        let lower = t.to_ascii_lowercase();
        if lower.contains("table of contents") || lower.contains("contents") && t.len() < 20 {
            break;
        }
        if t.is_empty()
            || lower.contains("technolog")
            || lower == "yosemitech"
            || t.contains(" / ")
            || t.chars().all(|c| c.is_ascii_digit())
        {
            continue;
        }
        cover.push(t.split("  ").next().unwrap_or(t).trim().to_string());
    }
    let split = cover.iter().position(|l| l.to_ascii_uppercase().contains("MODBUS")).unwrap_or(cover.len());
    let title = cover[..split].join(" ");
    let manual_title =
        if split < cover.len() { format!("{}, {}", title, cover[split..].join(" ")) } else { title.clone() };
    let text: String = lines.join("\n");
    let lower = text.to_ascii_lowercase();
    // Scope line: "... hardware Rev1.0 and software Rev1.7 or later".
    let scope = lower.find("scope").map(|i| &lower[i..]).unwrap_or("");
    let scope_end = scope.find("later").map_or(scope.len().min(600), |e| e + 5);
    let scope = &scope[..scope_end];
    let (hw, sw) = (revision_after(scope, "hardware"), revision_after(scope, "software"));
    let later = scope.contains("or later");
    let revision = match (&hw, &sw) {
        (Some(h), Some(s)) => Some(format!("HW Rev{h} / SW Rev{s}{}", if later { " or later" } else { "" })),
        (None, Some(s)) => Some(format!("SW Rev{s}{}", if later { " or later" } else { "" })),
        _ => None,
    };
    let number_before = |key: &str| -> Option<u32> {
        let i = lower.find(key)?;
        let before = lower[..i].trim_end();
        let digits: String =
            before.chars().rev().take_while(|c| c.is_ascii_digit()).collect::<Vec<_>>().into_iter().rev().collect();
        digits.parse().ok()
    };
    let baud = lower.match_indices("baud rate").find_map(|(i, k)| {
        let rest: String = lower[i + k.len()..].chars().take(40).collect();
        let d: String = rest.chars().skip_while(|c| !c.is_ascii_digit()).take_while(|c| c.is_ascii_digit()).collect();
        d.parse::<u32>().ok().filter(|b| (300..=1_000_000).contains(b))
    });
    let parity = if lower.contains("no parity") {
        Some("none")
    } else if lower.contains("even parity") {
        Some("even")
    } else if lower.contains("odd parity") {
        Some("odd")
    } else {
        None
    };
    Header {
        title,
        manual_title,
        revision,
        software: sw,
        baud,
        data_bits: number_before("data bits").and_then(|v| u8::try_from(v).ok()),
        parity,
        stop_bits: number_before("stop bit").and_then(|v| u8::try_from(v).ok()),
    }
}
