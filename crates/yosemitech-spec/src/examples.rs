//! Replays the manual's example frames through the interpreter.
//!
//! An example records what the manual prints and no more: a frame may lack
//! its CRC, carry placeholders for bytes the manual does not give, or be
//! missing altogether (a figure with one side only). What is stated is
//! checked: every complete frame byte for byte (a missing CRC is computed),
//! every partial frame by its header and by each field whose bytes it gives.

use std::collections::{BTreeMap, BTreeSet};

use crate::Spanned;
use yosemitech_rtu::{Function, Hex, crc_ok, crc16};

use crate::check::{check_erratum_id, check_text, crc_text, parse_hex, resolve_figure, resolve_figures, stated_value};
use crate::diag::{Pos, Reporter};
use crate::document::{CrcDoc, ExampleDoc};
use crate::interp::{Value, decode_field};
use crate::model::{Citation, CommandSpec, Example, ExampleErratum, PrintedFrame};

fn hex(text: &Spanned<String>, key: &str, r: &mut Reporter<'_>) -> Option<Vec<u8>> {
    match parse_hex(&text.value) {
        Ok(bytes) => Some(bytes),
        Err(why) => {
            r.error(
                Pos::at(text),
                key,
                format!("invalid hex frame: {why}"),
                Some("write bytes as two hex digits separated by spaces: \"01 03 28 00\"".into()),
            );
            None
        }
    }
}

/// Parses a printed frame: hex bytes, `??`/`XX` placeholders, a final `...`.
pub(crate) fn parse_printed(text: &str) -> Result<(Vec<Option<u8>>, bool), String> {
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let mut bytes = Vec::new();
    let mut open_ended = false;
    for (i, token) in tokens.iter().enumerate() {
        match *token {
            "..." | "…" if i + 1 == tokens.len() => open_ended = true,
            "..." | "…" => return Err("`...` (bytes of unknown number) can only end a frame".into()),
            "??" | "XX" | "xx" => bytes.push(None),
            hexes => bytes.extend(parse_hex(hexes)?.into_iter().map(Some)),
        }
    }
    if bytes.is_empty() {
        return Err("the frame is empty".into());
    }
    if bytes.len() > yosemitech_rtu::frame::MAX_ADU {
        return Err(format!("{} bytes is longer than any RTU frame (256)", bytes.len()));
    }
    Ok((bytes, open_ended))
}

/// One printed side of an example, checked: placeholders only without a
/// CRC, a printed CRC that verifies, a missing CRC computed.
fn printed_frame(
    text: &Spanned<String>,
    crc: Option<&Spanned<CrcDoc>>,
    corrected: bool,
    key: &str,
    r: &mut Reporter<'_>,
) -> Option<PrintedFrame> {
    let (bytes, open_ended) = match parse_printed(&text.value) {
        Ok(parsed) => parsed,
        Err(why) => {
            r.error(
                Pos::at(text),
                key,
                format!("invalid frame: {why}"),
                Some("write bytes as two hex digits separated by spaces: \"01 03 28 00\"; `??` for a byte the manual does not give, a final `...` for bytes of unknown number".into()),
            );
            return None;
        }
    };
    let crc_printed = crc.is_none_or(|c| c.value == CrcDoc::Printed);
    let what = key.rsplit('.').next().unwrap_or("frame");
    let known: Option<Vec<u8>> = if open_ended { None } else { bytes.iter().copied().collect() };
    let complete = match (known, crc_printed) {
        (None, true) => {
            r.error(
                Pos::at(text),
                key,
                "a frame with placeholders cannot carry a known CRC",
                Some(format!("the manual cannot print the CRC of unknown bytes: add `{what}_crc: missing`")),
            );
            return None;
        }
        (None, false) => None,
        (Some(all), true) => {
            if !corrected && !crc_ok(&all) {
                r.error(
                    Pos::at(text),
                    key,
                    match all.len() {
                        0..4 => format!("the printed {what} is too short to carry a CRC ({} bytes)", all.len()),
                        _ => format!("the printed CRC of the {what} is wrong: the bytes before it give {}", crc_text(&all)),
                    },
                    Some(format!("fix the frame; if the manual prints it wrong, add an `erratum` with the corrected frame; if it prints no CRC, write the bytes before it and `{what}_crc: missing`")),
                );
                return None;
            }
            Some(all)
        }
        (Some(mut all), false) => {
            if all.len() >= 4 && crc_ok(&all) {
                r.error(
                    Pos::at(text),
                    key,
                    "the frame already ends in its CRC",
                    Some(format!("remove `{what}_crc: missing`, or remove the CRC bytes the manual does not print")),
                );
                return None;
            }
            all.extend_from_slice(&crc16(&all).to_le_bytes());
            Some(all)
        }
    };
    Some(PrintedFrame { bytes, open_ended, crc_printed, complete })
}

/// Checks one example; returns it when every check passed.
pub(crate) fn check_example(
    cmd: &CommandSpec,
    e: &ExampleDoc,
    key: &str,
    ids: &mut BTreeSet<String>,
    r: &mut Reporter<'_>,
) -> Option<Example> {
    let errors_before = r.out.len();
    let no_values = BTreeMap::new();
    let stated = e.values.as_ref().map_or(&no_values, |v| &v.value);
    let values_at = |fallback: Pos| e.values.as_ref().map_or(fallback, Pos::at);
    let at = e.request.as_ref().or(e.response.as_ref()).map_or_else(|| values_at(Pos::default()), Pos::at);
    let figures = resolve_figures(&e.figures, &format!("{key}.figures"), at, r);
    let manual = e.manual.as_ref().map(|m| check_text(m, &format!("{key}.manual"), r));
    let mut also_in: Vec<Citation> = Vec::new();
    for (k, cited) in e.also_in.iter().enumerate() {
        let cited_key = format!("{key}.also_in[{k}]");
        let at = Pos::at(&cited.manual);
        let citation = Citation {
            manual: check_text(&cited.manual, &format!("{cited_key}.manual"), r),
            figures: resolve_figures(&cited.figures, &format!("{cited_key}.figures"), at, r),
        };
        if also_in.iter().any(|c| c.manual == citation.manual) || manual.as_ref() == Some(&citation.manual) {
            r.error(
                at,
                format!("{cited_key}.manual"),
                format!(
                    "the example already cites the manual of software `{}`",
                    crate::names::escape(&citation.manual)
                ),
                Some(
                    "cite each other manual once, with all its figures; the example's own manual is its `manual`"
                        .into(),
                ),
            );
        }
        also_in.push(citation);
    }
    if e.request.is_none() && e.response.is_none() {
        r.error(
            at,
            key,
            "an example prints a request, a reply, or both",
            Some("add `request:` or `response:` as the manual prints it".into()),
        );
        return None;
    }
    for (frame, crc, what) in [(&e.request, &e.request_crc, "request"), (&e.response, &e.response_crc, "response")] {
        if let (None, Some(c)) = (frame, crc) {
            r.error(
                Pos::at(c),
                format!("{key}.{what}_crc"),
                format!("`{what}_crc` without a `{what}`"),
                Some(format!("remove `{what}_crc`, or add the `{what}` the manual prints")),
            );
        }
    }
    let doc = e.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));

    let mut erratum = None;
    if let Some(er) = &e.erratum {
        let ek = format!("{key}.erratum");
        check_erratum_id(&er.id, &format!("{ek}.id"), ids, r);
        let figure = resolve_figure(&er.figure.value, &format!("{ek}.figure"), Pos::at(&er.figure), r);
        if let Some(f) = figure
            && !figures.contains(&f)
        {
            let list: Vec<String> = figures.iter().map(ToString::to_string).collect();
            r.error(
                Pos::at(&er.figure),
                format!("{ek}.figure"),
                format!("figure {f} is not one of the example's figures [{}]", list.join(", ")),
                Some("name the figure that prints the wrong frame".into()),
            );
        }
        let corrected_request =
            er.corrected_request.as_ref().and_then(|t| hex(t, &format!("{ek}.corrected_request"), r));
        let corrected_response =
            er.corrected_response.as_ref().and_then(|t| hex(t, &format!("{ek}.corrected_response"), r));
        if er.corrected_request.is_none() && er.corrected_response.is_none() {
            r.error(
                Pos::at(&er.id),
                &ek,
                "an example erratum gives `corrected_request` or `corrected_response`",
                Some("give the true frame the printed one stands for".into()),
            );
        }
        for (corrected, span, what) in [
            (&corrected_request, &er.corrected_request, "request"),
            (&corrected_response, &er.corrected_response, "response"),
        ] {
            let (Some(c), Some(span)) = (corrected, span) else { continue };
            if !crc_ok(c) {
                r.error(
                    Pos::at(span),
                    format!("{ek}.corrected_{what}"),
                    format!("the CRC of the corrected {what} is wrong: the bytes before it give {}", crc_text(c)),
                    Some("a corrected frame must be the true frame, CRC included".into()),
                );
            }
        }
        erratum = figure.map(|figure| ExampleErratum {
            id: er.id.value.clone(),
            figure,
            printed: check_text(&er.printed, &format!("{ek}.printed"), r),
            corrected_request,
            corrected_response,
            printed_decodes: er.printed_decodes.value,
        });
    }
    let corrects = |what: &str| -> bool {
        e.erratum.as_ref().is_some_and(|x| match what {
            "request" => x.corrected_request.is_some(),
            _ => x.corrected_response.is_some(),
        })
    };
    let request = e
        .request
        .as_ref()
        .and_then(|t| printed_frame(t, e.request_crc.as_ref(), corrects("request"), &format!("{key}.request"), r));
    let response = e
        .response
        .as_ref()
        .and_then(|t| printed_frame(t, e.response_crc.as_ref(), corrects("response"), &format!("{key}.response"), r));
    if r.out.len() > errors_before {
        return None;
    }
    let corrected_spans = e.erratum.as_ref().map(|x| (&x.corrected_request, &x.corrected_response));
    for (corrected, printed, span, what) in [
        (
            erratum.as_ref().and_then(|x| x.corrected_request.as_ref()),
            &request,
            corrected_spans.map_or(&e.request, |c| c.0),
            "request",
        ),
        (
            erratum.as_ref().and_then(|x| x.corrected_response.as_ref()),
            &response,
            corrected_spans.map_or(&e.response, |c| c.1),
            "response",
        ),
    ] {
        let Some(c) = corrected else { continue };
        match printed.as_ref().and_then(|p| p.complete.as_ref()) {
            Some(p) if p == c => r.error(
                span.as_ref().map_or_else(|| values_at(at), Pos::at),
                format!("{key}.erratum.corrected_{what}"),
                format!("the corrected {what} is the printed one: nothing to correct"),
                Some(format!("remove `corrected_{what}`, or give the frame the device really sends")),
            ),
            Some(_) => {}
            // A partial frame (placeholders, no CRC) may be completed by an
            // erratum, as long as the correction keeps every byte it prints.
            None => {
                if let Some(problem) =
                    printed.as_ref().map_or(Some(format!("no {what} is printed")), |p| contradiction(p, c))
                {
                    r.error(
                        span.as_ref().map_or_else(|| values_at(at), Pos::at),
                        format!("{key}.erratum.corrected_{what}"),
                        format!("the corrected {what} cannot stand for the printed one: {problem}"),
                        Some("a correction keeps every byte the manual prints and fills the rest".into()),
                    );
                }
            }
        }
    }

    // Which frame carries the values, and which of its bytes are known.
    let (value_frame, data_start) = if cmd.is_read() { (&response, 3usize) } else { (&request, 7usize) };
    let value_span = if cmd.is_read() { &e.response } else { &e.request };
    let true_value_frame: Option<Vec<u8>> = if cmd.is_read() {
        erratum.as_ref().and_then(|x| x.corrected_response.clone()).or_else(|| response.as_ref()?.complete.clone())
    } else {
        erratum.as_ref().and_then(|x| x.corrected_request.clone()).or_else(|| request.as_ref()?.complete.clone())
    };
    let complete_values = true_value_frame.is_some();

    // Stated values, by field.
    let mut values = BTreeMap::new();
    for (name, v) in stated {
        let vk = format!("{key}.values.{name}");
        match cmd.field(name) {
            Some(field) if !field.is_reserved() => {
                let bytes_known = value_frame.as_ref().is_some_and(|f| {
                    (data_start + field.offset..data_start + field.offset + field.size()).all(|i| f.byte(i).is_some())
                });
                if !complete_values && !bytes_known {
                    r.error(
                        Pos::at(v),
                        vk,
                        format!("the example's frame does not give the bytes of `{name}`"),
                        Some("state only values whose bytes the manual prints; a value printed alone goes in the field's `examples`".into()),
                    );
                    continue;
                }
                match stated_value(field, &v.value) {
                    Ok(value) => {
                        values.insert(name.clone(), value);
                    }
                    Err(why) => r.error(Pos::at(v), vk, why, None),
                }
            }
            _ => r.error(
                Pos::at(v),
                vk,
                format!("`{}` has no field called `{}`", cmd.name, crate::names::escape(name)),
                Some(format!(
                    "fields: {}",
                    cmd.named_fields().map(|f| f.display_name()).collect::<Vec<_>>().join(", ")
                )),
            ),
        }
    }
    if complete_values {
        let missing: Vec<String> = cmd
            .named_fields()
            .map(|f| f.display_name())
            .filter(|n| !stated.contains_key(*n))
            .map(|n| format!("`{n}`"))
            .collect();
        if !missing.is_empty() {
            let pos = value_span.as_ref().map_or(values_at(at), |s| values_at(at).max(Pos::at(s)));
            r.error(
                pos,
                format!("{key}.values"),
                format!("the example states no value for {}", missing.join(", ")),
                Some("state every field's value as the manual gives it".into()),
            );
        }
    }
    if r.out.len() > errors_before {
        return None;
    }

    let true_req =
        erratum.as_ref().and_then(|x| x.corrected_request.clone()).or_else(|| request.as_ref()?.complete.clone());
    let true_resp =
        erratum.as_ref().and_then(|x| x.corrected_response.clone()).or_else(|| response.as_ref()?.complete.clone());
    let request_at = e.request.as_ref().map_or(at, Pos::at);
    let response_at = e.response.as_ref().map_or(at, Pos::at);

    // The slave the exchange is addressed to.
    let mut slave =
        request.as_ref().and_then(|f| f.byte(0)).or_else(|| response.as_ref().and_then(|f| f.byte(0))).unwrap_or(1);

    // The request: exactly what the spec encodes, or its stated header.
    if let Some(true_req) = &true_req {
        match cmd.decode_request(true_req) {
            Ok((s, _)) => slave = s,
            Err(err) => {
                let why = header_mismatch(cmd, true_req).unwrap_or_else(|| err.to_string());
                r.error(
                    request_at,
                    format!("{key}.request"),
                    format!("the request is not a `{}` frame: {why}", cmd.name),
                    Some(format!(
                        "`{}` sends function 0x{:02X}, register 0x{:04X}, count {}",
                        cmd.name,
                        cmd.function.code(),
                        cmd.address,
                        cmd.count
                    )),
                );
                return None;
            }
        }
        let request_values = if cmd.is_read() { BTreeMap::new() } else { values.clone() };
        match cmd.encode_request(slave, &request_values) {
            Ok(encoded) if &encoded == true_req => {}
            Ok(encoded) => r.error(
                request_at,
                format!("{key}.request"),
                format!("the printed request does not carry the stated values; they encode as {}", Hex(&encoded)),
                Some("check `values` against the request's data bytes".into()),
            ),
            Err(err) => r.error(
                values_at(at),
                format!("{key}.values"),
                format!("the stated values do not encode: {err}"),
                Some("state values the command can send (see the fields' types and `range`)".into()),
            ),
        }
    } else if let Some(partial) = &request {
        let mut head = vec![slave, cmd.function.code()];
        head.extend_from_slice(&cmd.address.to_be_bytes());
        head.extend_from_slice(&cmd.count.to_be_bytes());
        if cmd.function == Function::Write {
            head.push((2 * cmd.count) as u8);
        }
        if let Some(fixed) = cmd.fixed_slave {
            head[0] = fixed;
        }
        check_stated_bytes(partial, &head, "request", key, request_at, cmd, r);
        // A request has one length; placeholders stand for bytes, one each,
        // so a partial request without a closing `...` must have it too.
        let printed_len = partial.bytes.len() + if partial.crc_printed { 0 } else { 2 };
        let want = cmd.layout().request_len();
        if !partial.open_ended && printed_len != want {
            r.error(
                request_at,
                format!("{key}.request"),
                format!("the request is {printed_len} bytes with its CRC, but a `{}` request is {want}", cmd.name),
                Some("write one `??` per byte the manual does not give, or end the frame with `...`".into()),
            );
        }
    }

    // The reply: decodes to the stated values and re-encodes to itself, or
    // matches its stated header and fields.
    if let Some(true_resp) = &true_resp {
        match cmd.decode_response(slave, true_resp) {
            Ok(decoded) => {
                if cmd.is_read() {
                    compare_values(&decoded, &values, e, key, "", r);
                }
                let map: BTreeMap<String, Value> =
                    if cmd.is_read() { decoded.into_iter().collect() } else { BTreeMap::new() };
                match cmd.encode_response(slave, &map) {
                    Ok(again) if &again == true_resp || cmd.trigger => {}
                    Ok(again) => r.error(
                        response_at,
                        format!("{key}.response"),
                        format!("the decoded reply re-encodes as {}", Hex(&again)),
                        Some("reserved bytes may need a `fill` value".into()),
                    ),
                    Err(err) => r.error(
                        response_at,
                        format!("{key}.response"),
                        format!("the decoded reply does not re-encode: {err}"),
                        Some("a field's `range` may exclude the value the manual prints".into()),
                    ),
                }
            }
            Err(err) => r.error(
                response_at,
                format!("{key}.response"),
                format!("the reply does not decode: {err}"),
                Some("check the reply against the command; if the manual prints it wrong, add an `erratum`".into()),
            ),
        }
    } else if let Some(partial) = &response {
        let reply_slave = cmd.fixed_slave.unwrap_or(slave);
        let mut head = vec![reply_slave, cmd.function.code()];
        match cmd.function {
            Function::Read => {
                // A printed byte count the decoder accepts stands; any other is compared
                // with (and reported against) the Modbus one.
                let modbus = u8::try_from(2 * usize::from(cmd.count)).unwrap_or(u8::MAX);
                head.push(partial.byte(2).filter(|&b| cmd.layout().accepts_byte_count(b)).unwrap_or(modbus));
            }
            Function::Write => {
                head.extend_from_slice(&cmd.address.to_be_bytes());
                head.extend_from_slice(&cmd.count.to_be_bytes());
            }
        }
        check_stated_bytes(partial, &head, "response", key, response_at, cmd, r);
    }
    // Fields whose bytes a partial frame gives decode to the stated values.
    if !complete_values && let Some(frame) = value_frame {
        for field in cmd.named_fields() {
            let range = data_start + field.offset..data_start + field.offset + field.size();
            let bytes: Option<Vec<u8>> = range.clone().map(|i| frame.byte(i)).collect();
            let (Some(bytes), Some(want)) = (bytes, values.get(field.display_name())) else { continue };
            let got = decode_field(field, &bytes);
            if !got.same_as(want) {
                let pos = stated.get(field.display_name()).map(Pos::at).unwrap_or_default();
                r.error(
                    pos,
                    format!("{key}.values.{}", field.display_name()),
                    format!(
                        "bytes {} give {} = {got}, but the example states {want}",
                        Hex(&bytes),
                        field.display_name()
                    ),
                    Some("check the stated value against the printed bytes".into()),
                );
            }
        }
    }

    // The printed form of a corrected frame behaves as the erratum says.
    if let (Some(x), Some(er)) = (&erratum, &e.erratum) {
        let printed_req = request.as_ref().and_then(|f| f.complete.clone()).unwrap_or_default();
        let printed_resp = response.as_ref().and_then(|f| f.complete.clone()).unwrap_or_default();
        let outcome = if x.corrected_response.is_some() {
            cmd.decode_response(slave, &printed_resp).map(Some)
        } else {
            cmd.decode_request(&printed_req).map(|_| None)
        };
        let decodes = outcome.is_ok();
        if decodes != x.printed_decodes {
            let detail = match &outcome {
                Ok(_) => "is accepted by the decoder".to_string(),
                Err(err) => format!("is rejected ({err})"),
            };
            r.error(
                Pos::at(&er.printed_decodes),
                format!("{key}.erratum.printed_decodes"),
                format!("the printed frame {detail}, but `printed_decodes` is {}", x.printed_decodes),
                Some(format!("set `printed_decodes: {decodes}`")),
            );
        }
        if let Ok(Some(decoded)) = outcome {
            compare_values(&decoded, &values, e, key, " (printed frame)", r);
        }
    }
    (r.out.len() == errors_before).then_some(Example {
        figures,
        manual,
        request,
        response,
        values,
        doc,
        erratum,
        also_in,
    })
}

/// Why `corrected` cannot be the frame a partial `printed` frame stands for:
/// a printed byte it changes, or a length the printed frame rules out.
fn contradiction(printed: &PrintedFrame, corrected: &[u8]) -> Option<String> {
    if let Some((at, want)) =
        printed.bytes.iter().enumerate().find_map(|(i, b)| b.filter(|b| corrected.get(i) != Some(b)).map(|b| (i, b)))
    {
        return Some(format!("byte {at} is printed as {want:02X}"));
    }
    let printed_len = printed.bytes.len() + if printed.crc_printed { 0 } else { 2 };
    let length_fits = if printed.open_ended { corrected.len() >= printed_len } else { corrected.len() == printed_len };
    (!length_fits).then(|| format!("it is {} bytes where the printed frame has {printed_len}", corrected.len()))
}

/// Every byte a partial frame states in its header matches what the command sends.
fn check_stated_bytes(
    frame: &PrintedFrame,
    head: &[u8],
    what: &str,
    key: &str,
    at: Pos,
    cmd: &CommandSpec,
    r: &mut Reporter<'_>,
) {
    let names = match (what, cmd.function) {
        ("request", _) => ["slave", "function", "address", "address", "count", "count", "byte count"],
        (_, Function::Read) => ["slave", "function", "byte count", "", "", "", ""],
        (_, Function::Write) => ["slave", "function", "address", "address", "count", "count", ""],
    };
    for (i, want) in head.iter().enumerate() {
        if let Some(got) = frame.byte(i)
            && got != *want
        {
            r.error(
                at,
                format!("{key}.{what}"),
                format!(
                    "byte {i} ({}) is 0x{got:02X}, but `{}` sends 0x{want:02X}",
                    names.get(i).copied().unwrap_or("header"),
                    cmd.name
                ),
                Some("check the frame against the command's function, address and count".into()),
            );
            return;
        }
    }
}

fn compare_values(
    decoded: &[(String, Value)],
    stated: &BTreeMap<String, Value>,
    e: &ExampleDoc,
    key: &str,
    note: &str,
    r: &mut Reporter<'_>,
) {
    for (name, got) in decoded {
        let Some(want) = stated.get(name) else { continue };
        if !got.same_as(want) {
            let pos = e.values.as_ref().and_then(|v| v.value.get(name)).map(Pos::at).unwrap_or_default();
            r.error(
                pos,
                format!("{key}.values.{name}"),
                format!("the frame{note} gives {name} = {got}, but the example states {want}"),
                Some("check the stated value against the printed bytes".into()),
            );
        }
    }
}

/// What in a request's header differs from the command, in the spec's terms.
fn header_mismatch(cmd: &CommandSpec, frame: &[u8]) -> Option<String> {
    let function = *frame.get(1)?;
    if function != cmd.function.code() {
        return Some(format!(
            "it has function 0x{function:02X}, but `{}` is a {} (0x{:02X})",
            cmd.name,
            if cmd.is_read() { "read" } else { "write" },
            cmd.function.code()
        ));
    }
    let address = u16::from_be_bytes([*frame.get(2)?, *frame.get(3)?]);
    if address != cmd.address {
        return Some(format!("it addresses register 0x{address:04X}, but `{}` uses 0x{:04X}", cmd.name, cmd.address));
    }
    let count = u16::from_be_bytes([*frame.get(4)?, *frame.get(5)?]);
    if count != cmd.count {
        return Some(format!("it asks for {count} registers, but `{}` covers {}", cmd.name, cmd.count));
    }
    if let Some(slave) = cmd.fixed_slave
        && frame.first() != Some(&slave)
    {
        return Some(format!(
            "it is sent to slave {}, but `{}` always uses 0x{slave:02X}",
            frame.first().copied().unwrap_or(0),
            cmd.name
        ));
    }
    None
}
