//! The module as data: the `COMMANDS` table and the `CommandId` that views it.

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};
use yosemitech_spec::Sensor;

use super::derived::derived_table;
use super::ident;
use crate::naming::Names;
use crate::text::{doc, lit, one_line};

pub(super) fn dispatch(s: &Sensor, names: &Names) -> TokenStream {
    let derived_table = derived_table(s);
    let variants: Vec<Ident> = names.commands.iter().map(|c| ident(&c.ty)).collect();
    let titles: Vec<Literal> = s.commands.iter().map(|c| lit(&one_line(&c.title))).collect();
    let coefficient_writes: Vec<&str> = s.coefficient_blocks().iter().map(|(write, _)| write.name.as_str()).collect();
    let entries = s.commands.iter().zip(&variants).zip(&titles).map(|((c, v), title)| {
        if coefficient_writes.contains(&c.name.as_str()) {
            quote!(rtu::CommandEntry::of::<#v>(#title).restoring_coefficients())
        } else {
            quote!(rtu::CommandEntry::of::<#v>(#title))
        }
    });
    let id_docs: Vec<TokenStream> =
        s.commands.iter().zip(&variants).map(|(c, v)| doc(&format!("`{}`: [`{v}`].", c.name))).collect();

    let mut response_variants = Vec::new();
    let mut decode_response_arms = Vec::new();
    let mut response_command_arms = Vec::new();
    let mut response_encode_arms = Vec::new();
    let mut response_field_arms = Vec::new();
    let mut froms = Vec::new();
    for (c, v) in s.commands.iter().zip(&variants) {
        let d = doc(&format!("The reply to [`{v}`]."));
        if c.is_read() {
            let resp = format_ident!("{}Response", v);
            response_variants.push(quote!(#d #v(#resp)));
            decode_response_arms
                .push(quote!(Self::#v => rtu::dispatch::decode_response::<#v>(slave, frame).map(Response::#v)));
            response_command_arms.push(quote!(Self::#v(_) => CommandId::#v));
            response_encode_arms.push(quote!(Self::#v(r) => rtu::dispatch::encode_response::<#v>(r, slave, out)));
            response_field_arms.push(quote!(Self::#v(r) => r.field(index)));
            froms.push(quote! {
                impl From<#resp> for Response {
                    fn from(response: #resp) -> Self {
                        Self::#v(response)
                    }
                }
            });
        } else {
            response_variants.push(quote!(#d #v));
            decode_response_arms
                .push(quote!(Self::#v => rtu::dispatch::decode_response::<#v>(slave, frame).map(|()| Response::#v)));
            response_command_arms.push(quote!(Self::#v => CommandId::#v));
            response_encode_arms.push(quote!(Self::#v => rtu::dispatch::encode_response::<#v>(&(), slave, out)));
            response_field_arms.push(quote!(Self::#v => None));
        }
        froms.push(quote! {
            impl From<#v> for Request {
                fn from(request: #v) -> Self {
                    Self::#v(request)
                }
            }
        });
    }
    let request_variants = variants.iter().map(|v| {
        let d = doc(&format!("A [`{v}`] request."));
        quote!(#d #v(#v))
    });

    quote! {
        /// Every command of this sensor as data, in spec order: name, title,
        /// layout, fields and codecs ([`CommandId`] indexes it). A slice, so
        /// that a command a later manual adds changes no type.
        pub const COMMANDS: &[rtu::CommandEntry] = &[
            #(#entries,)*
        ];

        /// Every command of this sensor, for code that picks commands at run
        /// time (CLIs, simulators, tests). Non-exhaustive: a later manual may
        /// add a command, so a `match` outside this crate needs a `_` arm.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[non_exhaustive]
        pub enum CommandId {
            #(#id_docs #variants,)*
        }

        impl CommandId {
            /// Every command, in spec order.
            pub const ALL: &[Self] = &[#(Self::#variants),*];

            /// The command's row of [`COMMANDS`].
            // Variants are declared in table order, so every discriminant is an index.
            #[allow(clippy::indexing_slicing)]
            pub const fn entry(self) -> &'static rtu::CommandEntry {
                &COMMANDS[self as usize]
            }

            /// The command's snake_case name in the spec.
            pub const fn name(self) -> &'static str {
                self.entry().name
            }

            /// The command called `name` in the spec.
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL.iter().copied().find(|id| id.name() == name)
            }

            /// The command's title in the manual.
            pub const fn title(self) -> &'static str {
                self.entry().title
            }

            /// Function, start address, register count and addressing quirks.
            pub const fn layout(self) -> rtu::Layout<'static> {
                self.entry().layout
            }

            /// Name and unit of each field of the request (empty for reads).
            pub const fn request_fields(self) -> &'static [rtu::FieldInfo] {
                self.entry().request_fields
            }

            /// Name and unit of each field of the reply (empty for writes).
            pub const fn response_fields(self) -> &'static [rtu::FieldInfo] {
                self.entry().response_fields
            }

            /// Checks a request frame for this command and decodes it.
            pub fn decode_request(self, frame: &[u8]) -> Result<(u8, Request), rtu::FrameError> {
                match self {
                    #(Self::#variants => {
                        rtu::dispatch::decode_request::<#variants>(frame).map(|(slave, r)| (slave, Request::#variants(r)))
                    })*
                }
            }

            /// Checks a reply to this command, sent to `slave`, and decodes it.
            pub fn decode_response(self, slave: u8, frame: &[u8]) -> Result<Response, rtu::FrameError> {
                match self {
                    #(#decode_response_arms,)*
                }
            }
        }

        impl ::core::fmt::Display for CommandId {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                f.write_str(self.name())
            }
        }

        /// A request of any command of this sensor. Non-exhaustive, as
        /// [`CommandId`] is.
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[non_exhaustive]
        pub enum Request {
            #(#request_variants,)*
        }

        impl Request {
            /// Which command this is.
            pub const fn command(&self) -> CommandId {
                match self {
                    #(Self::#variants(_) => CommandId::#variants,)*
                }
            }

            /// Writes the request frame for `slave` into `out` and returns its length.
            pub fn encode(&self, slave: u8, out: &mut [u8]) -> Result<usize, rtu::EncodeError> {
                match self {
                    #(Self::#variants(r) => rtu::dispatch::encode_request(r, slave, out),)*
                }
            }

            /// The value of field `index` of [`CommandId::request_fields`].
            pub fn field(&self, index: usize) -> Option<rtu::FieldValue<'_>> {
                match self {
                    #(Self::#variants(r) => rtu::Message::field(r, index),)*
                }
            }

            /// Every field with its name and unit, in wire order.
            pub fn fields(&self) -> impl Iterator<Item = (rtu::FieldInfo, rtu::FieldValue<'_>)> + '_ {
                self.command().request_fields().iter().enumerate().filter_map(|(i, info)| Some((*info, self.field(i)?)))
            }
        }

        /// A reply to any command of this sensor (writes reply with no data).
        /// Non-exhaustive, as [`CommandId`] is.
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[non_exhaustive]
        pub enum Response {
            #(#response_variants,)*
        }

        impl Response {
            /// Which command this answers.
            pub const fn command(&self) -> CommandId {
                match self {
                    #(#response_command_arms,)*
                }
            }

            /// Writes this reply from `slave` into `out` and returns its length.
            pub fn encode(&self, slave: u8, out: &mut [u8]) -> Result<usize, rtu::EncodeError> {
                match self {
                    #(#response_encode_arms,)*
                }
            }

            /// The value of field `index` of [`CommandId::response_fields`].
            pub fn field(&self, index: usize) -> Option<rtu::FieldValue<'_>> {
                use rtu::Message as _;
                match self {
                    #(#response_field_arms,)*
                }
            }

            /// Every field with its name and unit, in wire order.
            pub fn fields(&self) -> impl Iterator<Item = (rtu::FieldInfo, rtu::FieldValue<'_>)> + '_ {
                self.command().response_fields().iter().enumerate().filter_map(|(i, info)| Some((*info, self.field(i)?)))
            }
        }

        #(#froms)*

        /// Checks a reply to command `id`, sent to `slave`, and decodes it.
        pub fn decode_response(id: CommandId, slave: u8, frame: &[u8]) -> Result<Response, rtu::FrameError> {
            id.decode_response(slave, frame)
        }

        /// The command a request frame is for, by its function, start address
        /// and register count (the first in spec order if several match). Does
        /// not check the frame: decode it with [`CommandId::decode_request`].
        pub fn identify_request(frame: &[u8]) -> Option<CommandId> {
            rtu::identify_request(COMMANDS, frame).and_then(|i| CommandId::ALL.get(i).copied())
        }

        #derived_table

        /// This module as data, for code that serves every sensor without naming one
        /// (`crate::SENSORS` lists them all).
        pub const MODULE: rtu::SensorModule = rtu::SensorModule { info: SENSOR, commands: COMMANDS, derived: DERIVED };
    }
}
