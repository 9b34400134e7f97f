//! What a generated sensor module declares, written out once.
//!
//! Every generated module has the same run-time dispatch over its commands
//! (`CommandId`, `Request`, `Response`) and the same device handles; only
//! the list of commands and the per-command methods differ. The module
//! declares that list ([`command_set!`](crate::command_set)) and its handles
//! ([`device_handle!`](crate::device_handle),
//! [`async_device_handle!`](crate::async_device_handle)); the items they stand for
//! are spelled here, once, as prost's derives spell what its generated
//! structs declare. They are `macro_rules!`, so a crate that depends on the
//! generated code compiles no macro crate for them.
//!
//! The `#[doc(hidden)]` helpers below choose between a write's reply (a
//! unit variant of `Response`) and a read's (a variant holding the reply
//! struct); they are not API.

/// Declares a sensor's commands for run-time dispatch.
///
/// Given the module's command table (a `const` slice of
/// [`CommandEntry`](crate::CommandEntry), one row per command in the same
/// order) and each command as `"spec_name" => Type` (a write, whose reply
/// carries no data) or `"spec_name" => Type(ReplyType)` (a read), it
/// declares:
///
/// - `CommandId`, one variant per command, viewing the table (`name`,
///   `title`, `layout`, fields) and decoding a command's frames;
/// - `Request` and `Response`, any request or reply of the sensor, with
///   their encoders, field views and `From` conversions;
/// - `decode_response(id, slave, frame)` and `identify_request(frame)`.
///
/// ```
/// use yosemitech_rtu as rtu;
///
/// /// Reads the level.
/// #[derive(Debug, Clone, Copy, PartialEq, Default)]
/// pub struct GetLevel;
/// # impl rtu::NoData for GetLevel {}
/// /// The level.
/// #[derive(Debug, Clone, Copy, PartialEq)]
/// pub struct GetLevelResponse {
///     pub level_mm: u16,
/// }
/// # impl rtu::Message for GetLevelResponse {
/// #     type Data = [u8; 2];
/// #     const FIELDS: &'static [rtu::FieldInfo] = &[rtu::FieldInfo::new("level_mm", Some("mm"))];
/// #     fn from_data(data: &[u8; 2]) -> Self {
/// #         Self { level_mm: u16::from_be_bytes(*data) }
/// #     }
/// #     fn to_data(&self) -> [u8; 2] {
/// #         self.level_mm.to_be_bytes()
/// #     }
/// #     fn field(&self, index: usize) -> Option<rtu::FieldValue<'_>> {
/// #         (index == 0).then_some(rtu::FieldValue::Int(i64::from(self.level_mm)))
/// #     }
/// # }
/// impl rtu::Command for GetLevel {
///     type Response = GetLevelResponse;
///     const NAME: &'static str = "get_level";
///     const LAYOUT: rtu::Layout<'static> = rtu::Layout::read(0x1000, 1);
/// }
///
/// pub const COMMANDS: &[rtu::CommandEntry] = &[rtu::CommandEntry::of::<GetLevel>("Get level")];
///
/// rtu::command_set! {
///     COMMANDS;
///     "get_level" => GetLevel(GetLevelResponse),
/// }
///
/// let id = CommandId::from_name("get_level").ok_or("no such command")?;
/// let mut frame = [0; 16];
/// let len = Request::from(GetLevel).encode(1, &mut frame)?;
/// assert_eq!(identify_request(&frame[..len]), Some(id));
/// let len = Response::from(GetLevelResponse { level_mm: 1250 }).encode(1, &mut frame)?;
/// assert_eq!(
///     decode_response(id, 1, &frame[..len])?,
///     Response::GetLevel(GetLevelResponse { level_mm: 1250 })
/// );
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[macro_export]
macro_rules! command_set {
    (
        $table:ident;
        $( $name:literal => $variant:ident $( ( $reply:ty ) )? ),+ $(,)?
    ) => {
        /// Every command of this sensor, for code that picks commands at run
        /// time (CLIs, simulators, tests). Non-exhaustive: a later manual may
        /// add a command, so a `match` outside this crate needs a `_` arm.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[non_exhaustive]
        pub enum CommandId {
            $(
                #[doc = concat!("`", $name, "`: [`", stringify!($variant), "`].")]
                $variant,
            )+
        }

        impl CommandId {
            /// Every command, in spec order.
            pub const ALL: &[Self] = &[$(Self::$variant),+];

            #[doc = concat!("The command's row of [`", stringify!($table), "`].")]
            // Variants are declared in table order, so every discriminant is an index.
            #[allow(clippy::indexing_slicing)]
            pub const fn entry(self) -> &'static $crate::CommandEntry {
                &$table[self as usize]
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
            pub const fn layout(self) -> $crate::Layout<'static> {
                self.entry().layout
            }

            /// Name and unit of each field of the request (empty for reads).
            pub const fn request_fields(self) -> &'static [$crate::FieldInfo] {
                self.entry().request_fields
            }

            /// Name and unit of each field of the reply (empty for writes).
            pub const fn response_fields(self) -> &'static [$crate::FieldInfo] {
                self.entry().response_fields
            }

            /// Checks a request frame for this command and decodes it.
            pub fn decode_request(self, frame: &[u8]) -> Result<(u8, Request), $crate::FrameError> {
                match self {
                    $(
                        Self::$variant => $crate::dispatch::decode_request::<$variant>(frame)
                            .map(|(slave, request)| (slave, Request::$variant(request))),
                    )+
                }
            }

            /// Checks a reply to this command, sent to `slave`, and decodes it.
            pub fn decode_response(self, slave: u8, frame: &[u8]) -> Result<Response, $crate::FrameError> {
                match self {
                    $(
                        Self::$variant => $crate::dispatch::decode_response::<$variant>(slave, frame)
                            .map($crate::__reply_constructor!(Response::$variant $(, $reply)?)),
                    )+
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
            $(
                #[doc = concat!("A [`", stringify!($variant), "`] request.")]
                $variant($variant),
            )+
        }

        impl Request {
            /// Which command this is.
            pub const fn command(&self) -> CommandId {
                match self {
                    $(Self::$variant(_) => CommandId::$variant,)+
                }
            }

            /// Writes the request frame for `slave` into `out` and returns its length.
            pub fn encode(&self, slave: u8, out: &mut [u8]) -> Result<usize, $crate::EncodeError> {
                match self {
                    $(Self::$variant(request) => $crate::dispatch::encode_request(request, slave, out),)+
                }
            }

            /// The value of field `index` of [`CommandId::request_fields`].
            pub fn field(&self, index: usize) -> Option<$crate::FieldValue<'_>> {
                match self {
                    $(Self::$variant(request) => $crate::Message::field(request, index),)+
                }
            }

            /// Every field with its name and unit, in wire order.
            pub fn fields(&self) -> impl Iterator<Item = ($crate::FieldInfo, $crate::FieldValue<'_>)> + '_ {
                self.command()
                    .request_fields()
                    .iter()
                    .enumerate()
                    .filter_map(|(i, info)| Some((*info, self.field(i)?)))
            }
        }

        /// A reply to any command of this sensor (writes reply with no data).
        /// Non-exhaustive, as [`CommandId`] is.
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[non_exhaustive]
        pub enum Response {
            $(
                #[doc = concat!("The reply to [`", stringify!($variant), "`].")]
                $variant $(($reply))?,
            )+
        }

        impl Response {
            /// Which command this answers.
            pub const fn command(&self) -> CommandId {
                match self {
                    $(Self::$variant { .. } => CommandId::$variant,)+
                }
            }

            /// Writes this reply from `slave` into `out` and returns its length.
            pub fn encode(&self, slave: u8, out: &mut [u8]) -> Result<usize, $crate::EncodeError> {
                match self {
                    $(
                        $crate::__reply_pattern!(Self::$variant, reply $(, $reply)?) => {
                            $crate::dispatch::encode_response::<$variant>(
                                $crate::__reply_data!(reply $(, $reply)?),
                                slave,
                                out,
                            )
                        }
                    )+
                }
            }

            /// The value of field `index` of [`CommandId::response_fields`].
            pub fn field(&self, index: usize) -> Option<$crate::FieldValue<'_>> {
                match self {
                    $(
                        $crate::__reply_pattern!(Self::$variant, reply $(, $reply)?) => {
                            $crate::Message::field($crate::__reply_data!(reply $(, $reply)?), index)
                        }
                    )+
                }
            }

            /// Every field with its name and unit, in wire order.
            pub fn fields(&self) -> impl Iterator<Item = ($crate::FieldInfo, $crate::FieldValue<'_>)> + '_ {
                self.command()
                    .response_fields()
                    .iter()
                    .enumerate()
                    .filter_map(|(i, info)| Some((*info, self.field(i)?)))
            }
        }

        $(
            impl From<$variant> for Request {
                fn from(request: $variant) -> Self {
                    Self::$variant(request)
                }
            }

            $(
                impl From<$reply> for Response {
                    fn from(response: $reply) -> Self {
                        Self::$variant(response)
                    }
                }
            )?
        )+

        /// Checks a reply to command `id`, sent to `slave`, and decodes it.
        pub fn decode_response(id: CommandId, slave: u8, frame: &[u8]) -> Result<Response, $crate::FrameError> {
            id.decode_response(slave, frame)
        }

        /// The command a request frame is for, by its function, start address
        /// and register count (the first in spec order if several match). Does
        /// not check the frame: decode it with [`CommandId::decode_request`].
        pub fn identify_request(frame: &[u8]) -> Option<CommandId> {
            $crate::identify_request($table, frame).and_then(|i| CommandId::ALL.get(i).copied())
        }
    };
}

/// Declares a blocking device handle: a borrowed [`Client`](crate::Client)
/// and a slave address, with the methods every handle shares (`new`,
/// `address`, `set_address`, `client`, `call`). The module adds one method
/// per command in its own `impl` block.
#[macro_export]
macro_rules! device_handle {
    ($(#[$meta:meta])* $vis:vis struct $name:ident;) => {
        $(#[$meta])*
        $vis struct $name<'c, T> {
            client: &'c mut $crate::Client<T>,
            address: u8,
        }

        impl<'c, T: $crate::Transport> $name<'c, T> {
            /// The probe at `address` on `client`'s bus.
            pub fn new(client: &'c mut $crate::Client<T>, address: u8) -> Self {
                Self { client, address }
            }

            /// The probe's slave address.
            pub fn address(&self) -> u8 {
                self.address
            }

            /// Points the handle at another address, after the probe's
            /// address was changed and verified (see `rtu::address`).
            pub fn set_address(&mut self, address: u8) {
                self.address = address;
            }

            /// The client, for requests to other devices on the bus.
            pub fn client(&mut self) -> &mut $crate::Client<T> {
                self.client
            }

            /// Sends any command to this probe (or to the command's fixed
            /// slave address) and returns the decoded reply.
            pub fn call<C: $crate::Command>(&mut self, command: &C) -> Result<C::Response, $crate::Error> {
                self.client.call(C::LAYOUT.request_slave(self.address), command)
            }
        }
    };
}

/// Declares an async device handle: [`device_handle!`]'s over a borrowed
/// [`AsyncClient`](crate::AsyncClient) (tokio), `call` an `async fn`.
#[macro_export]
macro_rules! async_device_handle {
    ($(#[$meta:meta])* $vis:vis struct $name:ident;) => {
        $(#[$meta])*
        $vis struct $name<'c, L> {
            client: &'c mut $crate::AsyncClient<L>,
            address: u8,
        }

        impl<'c, L: $crate::transport::AsyncLink> $name<'c, L> {
            /// The probe at `address` on `client`'s bus.
            pub fn new(client: &'c mut $crate::AsyncClient<L>, address: u8) -> Self {
                Self { client, address }
            }

            /// The probe's slave address.
            pub fn address(&self) -> u8 {
                self.address
            }

            /// Points the handle at another address, after the probe's
            /// address was changed and verified.
            pub fn set_address(&mut self, address: u8) {
                self.address = address;
            }

            /// The client, for requests to other devices on the bus.
            pub fn client(&mut self) -> &mut $crate::AsyncClient<L> {
                self.client
            }

            /// Sends any command to this probe (or to the command's fixed
            /// slave address) and returns the decoded reply.
            pub async fn call<C: $crate::Command>(&mut self, command: &C) -> Result<C::Response, $crate::Error> {
                self.client.call(C::LAYOUT.request_slave(self.address), command).await
            }
        }
    };
}

/// A `Response` variant as a pattern: a write's unit variant, or a read's
/// with its reply bound to `$bind`.
#[doc(hidden)]
#[macro_export]
macro_rules! __reply_pattern {
    ($variant:path, $bind:ident) => {
        $variant
    };
    ($variant:path, $bind:ident, $reply:ty) => {
        $variant($bind)
    };
}

/// The reply data a `Response` variant holds: a write's `()`, or the read's
/// reply bound by [`__reply_pattern!`].
#[doc(hidden)]
#[macro_export]
macro_rules! __reply_data {
    ($bind:ident) => {
        &()
    };
    ($bind:ident, $reply:ty) => {
        $bind
    };
}

/// The function from a command's decoded reply to its `Response` variant.
#[doc(hidden)]
#[macro_export]
macro_rules! __reply_constructor {
    ($variant:path) => {
        |()| $variant
    };
    ($variant:path, $reply:ty) => {
        $variant
    };
}
