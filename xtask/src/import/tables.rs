//! The register table and the code tables of a command section.

use super::tokens::{bare_hex, first_word_lower, hex_in, hex_token, segments};

/// The register table: (address, count, function, labels of the register columns).
pub(super) fn register_table(sec: &[String]) -> Option<(u16, u16, Option<u8>, Vec<String>)> {
    for (i, l) in sec.iter().enumerate() {
        let lower = l.to_ascii_lowercase();
        if first_word_lower(l) == "definition" || !(lower.contains("start") && lower.contains("address")) {
            continue;
        }
        if !lower.contains("number") && !lower.contains("register") {
            continue;
        }
        for v in sec.iter().skip(i + 1).take(4) {
            let t = v.trim();
            if !t.starts_with("0x") && !t.starts_with("0X") {
                continue;
            }
            let hex = hex_in(t);
            if hex.len() < 2 {
                break;
            }
            let addr = hex[0].iter().fold(0u32, |a, b| a << 8 | u32::from(*b));
            let count = hex[1].iter().fold(0u32, |a, b| a << 8 | u32::from(*b));
            let function = if hex.len() >= 3 { hex.last().and_then(|h| h.last().copied()) } else { None };
            let labels: Vec<String> = segments(t)
                .into_iter()
                .map(|(_, s)| s)
                .filter(|s| hex_token(s.split_whitespace().next().unwrap_or("")).is_none())
                .collect();
            return Some((u16::try_from(addr).ok()?, u16::try_from(count).ok()?, function, labels));
        }
    }
    None
}

/// A code table in the section: a row of a label and at least two codes,
/// with the labels of each code from the neighbouring line: (value, label).
pub(super) fn code_table(sec: &[String], after: usize) -> Vec<(u16, String)> {
    for (i, l) in sec.iter().enumerate().skip(after) {
        let segs = segments(l);
        if segs.len() < 3 {
            continue;
        }
        let codes: Vec<(usize, u8)> = segs[1..]
            .iter()
            .filter_map(|(c, s)| {
                hex_token(s).or_else(|| bare_hex(s).map(|b| vec![b])).and_then(|v| v.last().copied()).map(|b| (*c, b))
            })
            .collect();
        let mut distinct: Vec<u8> = codes.iter().map(|c| c.1).collect();
        distinct.sort_unstable();
        distinct.dedup();
        let label_first = hex_token(&segs[0].1).is_none() && bare_hex(&segs[0].1).is_none();
        if !label_first
            || distinct.len() != codes.len()
            || codes.len() + 1 != segs.len()
            || codes.len() < 2
            || first_word_lower(l) == "value"
            || first_word_lower(l) == "byte"
        {
            continue;
        }
        // Labels: the nearest line above or below with words.
        let neighbour = [i + 1, i.wrapping_sub(1)]
            .into_iter()
            .filter_map(|j| sec.get(j))
            .find(|n| segments(n).len() >= 2 && !n.contains("0x"));
        let words: Vec<(usize, String)> = neighbour.map(|n| segments(n)).unwrap_or_default();
        let mut out = Vec::new();
        for (k, (col, code)) in codes.iter().enumerate() {
            let next_col = codes.get(k + 1).map_or(usize::MAX, |c| c.0);
            let label: Vec<&str> = words
                .iter()
                .filter(|(c, _)| {
                    *c + 2 >= *col && *c < next_col.saturating_sub(2) || (*c < *col && *c + 12 > *col && k == 0)
                })
                .map(|(_, s)| s.as_str())
                .collect();
            out.push((u16::from(*code), label.join(" ")));
        }
        return out;
    }
    Vec::new()
}
