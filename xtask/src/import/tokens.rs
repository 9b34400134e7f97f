//! Lines and tokens: a manual's text cut into cells, hex bytes and values.

/// A line with page debris removed.
pub(super) fn clean(line: &str) -> String {
    let mut l = line;
    // Debris a conversion may leave before a heading: `<|...|>`.
    if let Some(i) = l.find("|>")
        && l.trim_start().starts_with("<|")
    {
        l = &l[i + 2..];
    }
    l.replace(['\u{201c}', '\u{201d}'], "\"").replace('\u{ff1a}', ":").replace('\u{ff08}', "(").replace('\u{ff09}', ")")
}

/// Segments of a line separated by two or more spaces, with their columns.
pub(super) fn segments(line: &str) -> Vec<(usize, String)> {
    let chars: Vec<char> = line.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        while i < chars.len() && chars[i].is_whitespace() {
            i += 1;
        }
        if i >= chars.len() {
            break;
        }
        let start = i;
        let mut end = i;
        while i < chars.len() {
            if chars[i].is_whitespace() {
                let mut j = i;
                while j < chars.len() && chars[j].is_whitespace() {
                    j += 1;
                }
                if j - i >= 2 || j >= chars.len() {
                    break;
                }
            }
            i += 1;
            end = i;
        }
        out.push((start, chars[start..end].iter().collect::<String>().trim().to_string()));
    }
    out
}

pub(super) fn hex_token(t: &str) -> Option<Vec<u8>> {
    let t = t.trim_matches(|c: char| c == ',' || c == ';');
    let body = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X"))?;
    let digits: String = body.chars().take_while(|c| c.is_ascii_hexdigit()).collect();
    if digits.is_empty() || digits.len() % 2 == 1 && digits.len() > 1 {
        return None;
    }
    let digits = if digits.len() == 1 { format!("0{digits}") } else { digits };
    (0..digits.len()).step_by(2).map(|i| u8::from_str_radix(&digits[i..i + 2], 16).ok()).collect()
}

pub(super) fn bare_hex(t: &str) -> Option<u8> {
    if (1..=2).contains(&t.len()) && t.chars().all(|c| c.is_ascii_hexdigit()) {
        u8::from_str_radix(t, 16).ok()
    } else {
        None
    }
}

fn decimal(t: &str) -> Option<f32> {
    if t.contains('.') && t.chars().all(|c| c.is_ascii_digit() || c == '.' || c == '-' || c == '+') {
        t.parse::<f32>().ok().filter(|v| v.is_finite())
    } else {
        None
    }
}

/// A cell of a frame's Value row.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Item {
    Byte(u8),
    Float(String, f32),
    Text(String),
    Word(String),
}

impl Item {
    pub(super) fn size(&self) -> usize {
        match self {
            Item::Byte(_) => 1,
            Item::Float(..) => 4,
            Item::Text(t) => t.len(),
            Item::Word(_) => 0,
        }
    }
}

/// The Value row's cells; with `ints_as_floats`, bare integers (no `0x`)
/// are decimal values of 4-byte floats ("1", "0" under "3~6").
pub(super) fn value_items(rest: &str, ints_as_floats: bool) -> Vec<Item> {
    let mut items = Vec::new();
    let mut chars = rest.chars().peekable();
    let mut tokens: Vec<(String, bool)> = Vec::new();
    while let Some(&c) = chars.peek() {
        if c.is_whitespace() {
            chars.next();
        } else if c == '"' {
            chars.next();
            let mut s = String::new();
            for c in chars.by_ref() {
                if c == '"' {
                    break;
                }
                s.push(c);
            }
            tokens.push((s, true));
        } else {
            let mut s = String::new();
            while let Some(&c) = chars.peek() {
                if c.is_whitespace() || c == '"' {
                    break;
                }
                s.push(c);
                chars.next();
            }
            tokens.push((s, false));
        }
    }
    for (t, quoted) in tokens {
        if quoted {
            items.push(Item::Text(t));
        } else if let Some(bytes) = hex_token(&t) {
            items.extend(bytes.into_iter().map(Item::Byte));
        } else if ints_as_floats && t.chars().all(|c| c.is_ascii_digit() || c == '-') && t.parse::<f32>().is_ok() {
            let v = t.parse::<f32>().unwrap_or(0.0);
            items.push(Item::Float(t, v));
        } else if let Some(b) = bare_hex(&t) {
            items.push(Item::Byte(b));
        } else if let Some(v) = decimal(&t) {
            items.push(Item::Float(t, v));
        } else if let Some(Item::Word(w)) = items.last_mut() {
            w.push(' ');
            w.push_str(&t);
        } else {
            items.push(Item::Word(t));
        }
    }
    items
}

pub(super) fn byte_indices(line: &str) -> Vec<usize> {
    line.split(|c: char| !c.is_ascii_digit()).filter_map(|t| t.parse().ok()).collect()
}

pub(super) fn first_word_lower(line: &str) -> String {
    line.split_whitespace().next().unwrap_or("").to_ascii_lowercase()
}

pub(super) fn snake(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') && !out.is_empty() {
            out.push('_');
        }
    }
    let out = out.trim_end_matches('_').to_string();
    if out.starts_with(|c: char| c.is_ascii_digit()) { format!("n_{out}") } else { out }
}

pub(super) fn hex_in(line: &str) -> Vec<Vec<u8>> {
    line.split_whitespace().filter_map(hex_token).collect()
}
