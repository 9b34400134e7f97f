//! Replays the manual's example frames through the interpreter.

use std::collections::{BTreeMap, BTreeSet};

use serde_saphyr::Spanned;
use yosemitech_rtu::{Hex, crc_ok};

use crate::diag::{Pos, Reporter};
use crate::document::ExampleDoc;
use crate::interp::Value;
use crate::model::{Command, Example, ExampleErratum};
use crate::resolve::{check_erratum_id, crc_text, parse_hex, stated_value};

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
    let doc = e.doc.as_ref().map(|d| d.value.trim().to_string());

    let mut erratum = None;
    if let Some(er) = &e.erratum {
        let ek = format!("{key}.erratum");
        check_erratum_id(&er.id, &format!("{ek}.id"), ids, r);
        if !e.figures.contains(&er.figure.value) {
            r.error(
                Pos::at(&er.figure),
                format!("{ek}.figure"),
                format!("figure {} is not one of the example's figures {:?}", er.figure.value, e.figures),
                None,
            );
        }
        let corrected_request =
            er.corrected_request.as_ref().and_then(|t| hex(t, &format!("{ek}.corrected_request"), r));
        let corrected_response =
            er.corrected_response.as_ref().and_then(|t| hex(t, &format!("{ek}.corrected_response"), r));
        if er.corrected_request.is_none() && er.corrected_response.is_none() {
            r.error(Pos::at(&er.id), &ek, "an example erratum gives `corrected_request` or `corrected_response`", None);
        }
        erratum = Some(ExampleErratum {
            id: er.id.value.clone(),
            figure: er.figure.value,
            printed: er.printed.value.trim().to_string(),
            corrected_request,
            corrected_response,
            printed_decodes: er.printed_decodes.value,
        });
    }
    let (request, response) = (request?, response?);

    // CRCs: a printed frame must verify unless an erratum corrects it.
    let frames = [
        ("request", &request, erratum.as_ref().and_then(|x| x.corrected_request.as_ref()), &e.request),
        ("response", &response, erratum.as_ref().and_then(|x| x.corrected_response.as_ref()), &e.response),
    ];
    for (what, printed, corrected, span) in frames {
        match corrected {
            None if !crc_ok(printed) => r.error(
                Pos::at(span),
                format!("{key}.{what}"),
                format!("the printed CRC of the {what} is wrong: the bytes give {}", crc_text(printed)),
                Some("fix the frame; if the manual prints it wrong, add an `erratum` with the corrected frame".into()),
            ),
            Some(c) if !crc_ok(c) => r.error(
                Pos::at(span),
                format!("{key}.erratum.corrected_{what}"),
                format!("the corrected {what}'s CRC is wrong: the bytes give {}", crc_text(c)),
                None,
            ),
            Some(c) if c == printed => r.error(
                Pos::at(span),
                format!("{key}.erratum.corrected_{what}"),
                format!("the corrected {what} is the printed one: nothing to correct"),
                None,
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
    let missing: Vec<&str> =
        cmd.named_fields().map(|f| f.display_name()).filter(|n| !e.values.value.contains_key(*n)).collect();
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
            r.error(
                Pos::at(&e.request),
                format!("{key}.request"),
                format!("the request is not a `{}` frame: {err}", cmd.name),
                None,
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
            format!("the spec encodes this request as {}", Hex(&encoded)),
            Some("the printed frame, the command and the stated values disagree".into()),
        ),
        Err(err) => r.error(
            Pos::at(&e.values),
            format!("{key}.values"),
            format!("the stated values do not encode: {err}"),
            None,
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
                    None,
                ),
            }
        }
        Err(err) => {
            r.error(Pos::at(&e.response), format!("{key}.response"), format!("the reply does not decode: {err}"), None)
        }
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
                None,
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
