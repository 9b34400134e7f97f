//! The contract between a generated message type and the runtime: its
//! register data and its fields. The runtime frames the data
//! ([`Command`](crate::Command)'s provided methods); generated code only
//! says where each field sits.

use crate::error::EncodeError;
use crate::value::{FieldInfo, FieldValue};

/// The register data of one message: a write's request, a read's reply.
///
/// Generated for every request and reply type of the spec. Decoding never
/// fails here: the runtime has already checked the frame, and [`Self::Data`]
/// has exactly the length the layout frames, so every field's bytes exist.
pub trait Message: Sized {
    /// The register data on the wire: `[u8; 2 × registers]`, `[u8; 0]` for a
    /// message without data.
    type Data: Copy + AsRef<[u8]> + for<'a> TryFrom<&'a [u8]>;

    /// Name and unit of each field, in wire order.
    const FIELDS: &'static [FieldInfo];

    /// Bytes of register data: two per register.
    const DATA_LEN: usize = core::mem::size_of::<Self::Data>();

    /// Decodes register data; reserved bytes are ignored.
    fn from_data(data: &Self::Data) -> Self;

    /// Encodes register data, reserved bytes with their fill. Does not check
    /// ranges: see [`Self::validate`].
    fn to_data(&self) -> Self::Data;

    /// The value of field `index` of [`Self::FIELDS`].
    fn field(&self, index: usize) -> Option<FieldValue<'_>>;

    /// Checks every field against the range the spec allows
    /// ([`EncodeError::OutOfRange`] names the first that is not). Only
    /// writes have ranges to keep: a read's range is the measuring range,
    /// and a probe may report values outside it.
    fn validate(&self) -> Result<(), EncodeError> {
        Ok(())
    }

    /// Every field with its name and unit, in wire order.
    fn fields(&self) -> impl Iterator<Item = (FieldInfo, FieldValue<'_>)> + '_ {
        Self::FIELDS.iter().enumerate().filter_map(|(i, info)| Some((*info, self.field(i)?)))
    }
}

/// A message that carries no register data: a read's request, a trigger's
/// reply. Saying so is all such a type needs to be a [`Message`].
pub trait NoData: Default {}

impl<T: NoData> Message for T {
    type Data = [u8; 0];
    const FIELDS: &'static [FieldInfo] = &[];

    fn from_data(_: &[u8; 0]) -> Self {
        Self::default()
    }

    fn to_data(&self) -> [u8; 0] {
        []
    }

    fn field(&self, _: usize) -> Option<FieldValue<'_>> {
        None
    }
}

/// A write's reply echoes address and count and carries no data.
impl NoData for () {}
