//! Replays the manual's example frames through the interpreter.

use std::collections::{BTreeMap, BTreeSet};

use serde_saphyr::Spanned;
use yosemitech_rtu::{Hex, crc_ok};

use crate::diag::{Pos, Reporter};
use crate::document::ExampleDoc;
use crate::interp::Value;
use crate::model::{Command, Example, ExampleErratum};
use crate::resolve::{check_erratum_id, check_text, crc_text, parse_hex, stated_value};

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

/// Checks one example; returns it when every check passed.
pub(crate) fn check_example(
    cmd: &Command,
    e: &ExampleDoc,
    key: &str,
    ids: &mut BTreeSet<String>,
    r: &mut Reporter<'_>,
) -> Option<Example> {
    let errors_before = r.out.len();
    let request = hex(&e.request, &format!("{key}.request"), r);
    let response = hex(&e.response, &format!("{key}.response"), r);
    let doc = e.doc.as_ref().map(|d| check_text(d, &format!("{key}.doc"), r));

    let mut erratum = None;
    if let Some(er) = &e.erratum {
        let ek = format!("{key}.erratum");
        check_erratum_id(&er.id, &format!("{ek}.id"), ids, r);
        if !e.figures.contains(&er.figure.value) {
            r.error(
                Pos::at(&er.figure),
                format!("{ek}.figure"),
                format!("figure {} is not one of the example's figures {:?}", er.figure.value, e.figures),
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
        erratum = Some(ExampleErratum {
            id: er.id.value.clone(),
            figure: er.figure.value,
            printed: check_text(&er.printed, &format!("{ek}.printed"), r),
            corrected_request,
            corrected_response,
            printed_decodes: er.printed_decodes.value,
        });
    }
    let (request, response) = (request?, response?);

    // CRCs: a printed frame must verify unless an erratum corrects it.
    let corrections = e.erratum.as_ref().map(|x| (&x.corrected_request, &x.corrected_response));
    let frames = [
        (
            "request",
            &request,
            erratum.as_ref().and_then(|x| x.corrected_request.as_ref()),
            &e.request,
            corrections.and_then(|c| c.0.as_ref()),
        ),
        (
            "response",
            &response,
            erratum.as_ref().and_then(|x| x.corrected_response.as_ref()),
            &e.response,
            corrections.and_then(|c| c.1.as_ref()),
        ),
    ];
    for (what, printed, corrected, span, corrected_span) in frames {
        let corrected_at = corrected_span.map_or_else(|| Pos::at(span), Pos::at);
        match corrected {
            None if !crc_ok(printed) => r.error(
                Pos::at(span),
                format!("{key}.{what}"),
                match printed.len() {
                    0..4 => format!("the printed {what} is too short to carry a CRC ({} bytes)", printed.len()),
                    _ => format!(
                        "the printed CRC of the {what} is wrong: the bytes before it give {}",
                        crc_text(printed)
                    ),
                },
                Some("fix the frame; if the manual prints it wrong, add an `erratum` with the corrected frame".into()),
            ),
            Some(c) if !crc_ok(c) => r.error(
                corrected_at,
                format!("{key}.erratum.corrected_{what}"),
                format!("the CRC of the corrected {what} is wrong: the bytes before it give {}", crc_text(c)),
                Some("a corrected frame must be the true frame, CRC included".into()),
            ),
            Some(c) if c == printed => r.error(
                corrected_at,
                format!("{key}.erratum.corrected_{what}"),
                format!("the corrected {what} is the printed one: nothing to correct"),
                Some(format!("remove `corrected_{what}`, or give the frame the device really sends")),
            ),
            _ => {}
        }
    }

    // Stated values, by field.
    let mut values = BTreeMap::new();
    for (name, v) in &e.values.value {
        let vk = format!("{key}.values.{name}");
        match cmd.field(name) {
            Some(field) if !field.is_reserved() => match stated_value(field, &v.value) {
                Ok(value) => {
                    values.insert(name.clone(), value);
                }
                Err(why) => r.error(Pos::at(v), vk, why, None),
            },
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
    let missing: Vec<String> = cmd
        .named_fields()
        .map(|f| f.display_name())
        .filter(|n| !e.values.value.contains_key(*n))
        .map(|n| format!("`{n}`"))
        .collect();
    if !missing.is_empty() {
        r.error(
            Pos::at(&e.values).max(Pos::at(&e.response)),
            format!("{key}.values"),
            format!("the example states no value for {}", missing.join(", ")),
            Some("state every field's value as the manual gives it".into()),
        );
    }
    if r.out.len() > errors_before {
        return None;
    }

    let true_req = erratum.as_ref().and_then(|x| x.corrected_request.clone()).unwrap_or_else(|| request.clone());
    let true_resp = erratum.as_ref().and_then(|x| x.corrected_response.clone()).unwrap_or_else(|| response.clone());

    // The request must be exactly what the spec encodes.
    let slave = match cmd.decode_request(&true_req) {
        Ok((slave, _)) => slave,
        Err(err) => {
            let why = header_mismatch(cmd, &true_req).unwrap_or_else(|| err.to_string());
            r.error(
                Pos::at(&e.request),
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
    };
    let request_values = if cmd.is_read() { BTreeMap::new() } else { values.clone() };
    match cmd.encode_request(slave, &request_values) {
        Ok(encoded) if encoded == true_req => {}
        Ok(encoded) => r.error(
            Pos::at(&e.request),
            format!("{key}.request"),
            format!("the printed request does not carry the stated values; they encode as {}", Hex(&encoded)),
            Some("check `values` against the request's data bytes".into()),
        ),
        Err(err) => r.error(
            Pos::at(&e.values),
            format!("{key}.values"),
            format!("the stated values do not encode: {err}"),
            Some("state values the command can send (see the fields' types and `range`)".into()),
        ),
    }

    // The reply must decode to the stated values and re-encode to itself.
    match cmd.decode_response(slave, &true_resp) {
        Ok(decoded) => {
            if cmd.is_read() {
                compare_values(&decoded, &values, e, key, "", r);
            }
            let map: BTreeMap<String, Value> =
                if cmd.is_read() { decoded.into_iter().collect() } else { BTreeMap::new() };
            match cmd.encode_response(slave, &map) {
                Ok(again) if again == true_resp => {}
                Ok(again) => r.error(
                    Pos::at(&e.response),
                    format!("{key}.response"),
                    format!("the decoded reply re-encodes as {}", Hex(&again)),
                    Some("reserved bytes may need a `fill` value".into()),
                ),
                Err(err) => r.error(
                    Pos::at(&e.response),
                    format!("{key}.response"),
                    format!("the decoded reply does not re-encode: {err}"),
                    Some("a field's `range` may exclude the value the manual prints".into()),
                ),
            }
        }
        Err(err) => r.error(
            Pos::at(&e.response),
            format!("{key}.response"),
            format!("the reply does not decode: {err}"),
            Some("check the reply against the command; if the manual prints it wrong, add an `erratum`".into()),
        ),
    }

    // The printed form of a corrected frame behaves as the erratum says.
    if let (Some(x), Some(er)) = (&erratum, &e.erratum) {
        let outcome = if x.corrected_response.is_some() {
            cmd.decode_response(slave, &response).map(Some)
        } else {
            cmd.decode_request(&request).map(|_| None)
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
    (r.out.len() == errors_before).then(|| Example {
        figures: e.figures.clone(),
        request,
        response,
        values,
        doc,
        erratum,
    })
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
            let pos = e.values.value.get(name).map(Pos::at).unwrap_or_default();
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
fn header_mismatch(cmd: &Command, frame: &[u8]) -> Option<String> {
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
