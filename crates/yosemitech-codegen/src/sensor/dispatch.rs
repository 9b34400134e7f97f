//! The module as data: the `COMMANDS` table, and the command set (`CommandId`,
//! `Request`, `Response`) that `rtu::command_set!` declares over it.

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};
use yosemitech_spec::Sensor;

use super::derived::derived_table;
use super::ident;
use crate::naming::Names;
use crate::text::{lit, one_line};

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
    // Each command as `command_set!` declares it: a read names its reply type.
    let declared = s.commands.iter().zip(&variants).map(|(c, v)| {
        let name = lit(&c.name);
        if c.is_read() {
            let reply = format_ident!("{}Response", v);
            quote!(#name => #v(#reply))
        } else {
            quote!(#name => #v)
        }
    });

    quote! {
        /// Every command of this sensor as data, in spec order: name, title,
        /// layout, fields and codecs ([`CommandId`] indexes it). A slice, so
        /// that a command a later manual adds changes no type.
        pub const COMMANDS: &[rtu::CommandEntry] = &[
            #(#entries,)*
        ];

        rtu::command_set! {
            COMMANDS;
            #(#declared,)*
        }

        #derived_table

        /// This module as data, for code that serves every sensor without naming one
        /// (`crate::SENSORS` lists them all).
        pub const MODULE: rtu::SensorModule = rtu::SensorModule { info: SENSOR, commands: COMMANDS, derived: DERIVED };
    }
}
