//! The frames a manual prints, and the printed frames that are wrong.

use std::collections::BTreeMap;

use serde::Serialize;

use super::Figure;

/// A frame as a manual prints it.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct PrintedFrame {
    /// The bytes printed, CRC included when printed; `None` for a placeholder
    /// ("Value", "Time") the manual prints instead of a byte.
    pub bytes: Vec<Option<u8>>,
    /// The manual prints bytes of unknown number after `bytes` ("meaningless").
    pub open_ended: bool,
    /// Whether the manual prints the CRC.
    pub crc_printed: bool,
    /// The whole frame, CRC included (computed when not printed), when every
    /// byte is known; validation checked the printed CRC against it.
    pub complete: Option<Vec<u8>>,
}

impl PrintedFrame {
    /// True when every byte is known (the CRC may still be computed).
    pub fn is_complete(&self) -> bool {
        self.complete.is_some()
    }

    /// The byte at `at`, when printed.
    pub fn byte(&self, at: usize) -> Option<u8> {
        self.bytes.get(at).copied().flatten()
    }
}

/// A frame pair (or one side of it) printed in the manual.
#[derive(Debug, Clone, Serialize)]
pub struct Example {
    /// Figures and tables that print the frame.
    pub figures: Vec<Figure>,
    /// The manual's software revision when not the sensor's `manual`.
    pub manual: Option<String>,
    /// The request as printed; `None` when the manual prints none.
    pub request: Option<PrintedFrame>,
    /// The reply as printed; `None` when the manual prints none.
    pub response: Option<PrintedFrame>,
    /// Values the manual states, by field name.
    pub values: BTreeMap<String, crate::Value>,
    /// Remarks on the example, in prose.
    pub doc: Option<String>,
    /// Where the printed frame is wrong.
    pub erratum: Option<ExampleErratum>,
    /// Other manuals that print the same frames, with their figures.
    pub also_in: Vec<Citation>,
}

/// Another manual's figures that print an example's frames byte for byte.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Citation {
    /// The manual's software revision.
    pub manual: String,
    /// Its figures and tables.
    pub figures: Vec<Figure>,
}

impl Example {
    /// The true request, complete with its CRC: the correction if the
    /// printed one is wrong; `None` when not every byte is known.
    pub fn true_request(&self) -> Option<&[u8]> {
        self.erratum
            .as_ref()
            .and_then(|e| e.corrected_request.as_deref())
            .or_else(|| self.request.as_ref()?.complete.as_deref())
    }

    /// The true reply, complete with its CRC: the correction if the printed
    /// one is wrong; `None` when not every byte is known.
    pub fn true_response(&self) -> Option<&[u8]> {
        self.erratum
            .as_ref()
            .and_then(|e| e.corrected_response.as_deref())
            .or_else(|| self.response.as_ref()?.complete.as_deref())
    }

    /// Both true frames, when both are complete: what a golden test replays.
    pub fn true_pair(&self) -> Option<(&[u8], &[u8])> {
        Some((self.true_request()?, self.true_response()?))
    }

    /// The slave address the request is sent to (from the reply when no
    /// request is printed).
    pub fn slave(&self) -> u8 {
        let from = |f: &Option<PrintedFrame>| f.as_ref().and_then(|f| f.byte(0));
        self.true_request()
            .and_then(|r| r.first().copied())
            .or_else(|| from(&self.request))
            .or_else(|| from(&self.response))
            .unwrap_or(0)
    }

    /// Frames printed in this example (one or two).
    pub fn frames_printed(&self) -> usize {
        usize::from(self.request.is_some()) + usize::from(self.response.is_some())
    }

    /// Printed frames whose every byte and CRC the manual gives.
    pub fn frames_printed_complete(&self) -> usize {
        [&self.request, &self.response]
            .into_iter()
            .flatten()
            .filter(|f| f.crc_printed && f.complete.as_deref().is_some_and(yosemitech_rtu::crc_ok))
            .count()
    }
}

/// A printed frame that is wrong.
#[derive(Debug, Clone, Serialize)]
pub struct ExampleErratum {
    /// Identifier, unique within the sensor.
    pub id: String,
    /// The figure that prints the wrong frame.
    pub figure: Figure,
    /// What is wrong with the printed frame, in prose.
    pub printed: String,
    /// The true request with its CRC, when the printed one is wrong.
    pub corrected_request: Option<Vec<u8>>,
    /// The true reply with its CRC, when the printed one is wrong.
    pub corrected_response: Option<Vec<u8>>,
    /// Whether our decoder accepts the printed frame.
    pub printed_decodes: bool,
}
