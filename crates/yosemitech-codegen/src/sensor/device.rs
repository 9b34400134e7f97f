//! `Device` and `AsyncDevice`: one method per command over a client (the
//! handles themselves are `rtu::device_handle!`'s and `rtu::async_device_handle!`'s).

use proc_macro2::TokenStream;
use quote::quote;
use yosemitech_rtu::Function;
use yosemitech_spec::{Role, Sensor};

use super::fields::field_gens;
use super::{Options, ident};
use crate::naming::Names;
use crate::text::{doc, one_line};

const RANGE_NOTE: &str = " Values outside the spec's range are refused before sending.";

/// `Device::set_slave_address` for a sensor with a write of role
/// `set_slave_address` and a read of role `serial_number`, both sent to the
/// device's own address: the verified change of `rtu::address`.
fn set_slave_address(s: &Sensor, names: &Names) -> Option<TokenStream> {
    let own = |role| {
        s.commands.iter().position(|c| c.role == Some(role) && c.fixed_slave.is_none()).map(|i| (i, &s.commands[i]))
    };
    let ((wi, write), (pi, _)) = (own(Role::SetSlaveAddress)?, own(Role::SerialNumber)?);
    // Validation gives the write exactly one named field, a `u8`.
    let [field] = field_gens(names, wi, write).try_into().ok()?;
    let field = field.name;
    let write_ty = ident(&names.commands[wi].ty);
    let probe_ty = ident(&names.commands[pi].ty);
    let d = doc(&format!(
        "Changes the probe's slave address to `new` (1..=247, not in use on the bus) with [`{}`], confirmed by the \
         probe's reply and verified by reading [`{}`] at `new`; the handle then talks to `new`. On failure the error \
         says where the probe answers (see `rtu::address::change_address`).",
        names.commands[wi].ty, names.commands[pi].ty
    ));
    Some(quote! {
        #d
        pub fn set_slave_address(&mut self, new: u8) -> Result<(), rtu::address::AddressChangeError> {
            rtu::address::change_address(self.client, self.address, new, &#write_ty { #field: new }, &#probe_ty)?;
            self.address = new;
            Ok(())
        }
    })
}

pub(super) fn device(s: &Sensor, names: &Names, o: &Options) -> TokenStream {
    let cfg = match &o.std_feature {
        Some(feature) => quote!(#[cfg(feature = #feature)]),
        None => TokenStream::new(),
    };
    // One method per command, emitted twice from the same parts: blocking
    // (`Device`) and, when asked for, async (`AsyncDevice`).
    let mut methods = Vec::new();
    let mut async_methods = Vec::new();
    for (ci, c) in s.commands.iter().enumerate() {
        let n = &names.commands[ci];
        let ty = ident(&n.ty);
        let method = ident(&n.method);
        let gens = field_gens(names, ci, c);
        let title = one_line(&c.title);
        let title = title.trim_end_matches('.');
        // (doc, parameters, return type, request expression)
        let (d, params, ret, request) = match c.function {
            Function::Read => {
                // The whole reply, even of one field: a field a later manual
                // adds to it then changes no method's type.
                let resp = ident(&n.response);
                let d = doc(&format!("{title}: sends [`{}`] and returns the reply.", n.ty));
                (d, quote!(), quote!(#resp), quote!(&#ty))
            }
            Function::Write => match gens.as_slice() {
                [] => {
                    let d = doc(&format!("{title}: sends [`{}`].", n.ty));
                    (d, quote!(), quote!(()), quote!(&#ty))
                }
                [only] => {
                    let field = &only.name;
                    let fty = &only.ty;
                    let d = doc(&format!(
                        "{title}: sends [`{}`] with `{}`.{}",
                        n.ty,
                        only.field.display_name(),
                        if only.field.range.is_some() { RANGE_NOTE } else { "" }
                    ));
                    (d, quote!(, #field: #fty), quote!(()), quote!(&#ty { #field }))
                }
                _ => {
                    let ranged = gens.iter().any(|g| g.field.range.is_some());
                    let d = doc(&format!(
                        "{title}: sends `request` ([`{}`]).{}",
                        n.ty,
                        if ranged { RANGE_NOTE } else { "" }
                    ));
                    (d, quote!(, request: #ty), quote!(()), quote!(&request))
                }
            },
        };
        methods.push(quote! {
            #d
            pub fn #method(&mut self #params) -> Result<#ret, rtu::Error> {
                self.call(#request)
            }
        });
        async_methods.push(quote! {
            #d
            pub async fn #method(&mut self #params) -> Result<#ret, rtu::Error> {
                self.call(#request).await
            }
        });
    }
    methods.extend(set_slave_address(s, names));
    let title = one_line(&s.title);
    let async_device = match &o.async_feature {
        Some(feature) => {
            let d = doc(&format!(
                "One {title} on a bus, from async code: [`Device`]'s methods as `async fn`s over a borrowed \
                 [`rtu::AsyncClient`] (tokio), with the same requests, checks and replies."
            ));
            quote! {
                #[cfg(feature = #feature)]
                rtu::async_device_handle! {
                    #d
                    pub struct AsyncDevice;
                }

                #[cfg(feature = #feature)]
                impl<'c, L: rtu::transport::AsyncLink> AsyncDevice<'c, L> {
                    #(#async_methods)*
                }
            }
        }
        None => TokenStream::new(),
    };
    let d = doc(&format!(
        "One {title} on a bus: a borrowed [`rtu::Client`] and the probe's slave address, with one method per command.\n\n\
         Reads are named after the command without its `get_` prefix and return the reply (a struct that later fields may join); writes \
         keep the command's name and take the field (one field) or the request (several). Commands with a fixed slave \
         address (a read at the wildcard address 0xFF) use it instead of the device's."
    ));
    quote! {
        #cfg
        rtu::device_handle! {
            #d
            pub struct Device;
        }

        #cfg
        impl<'c, T: rtu::Transport> Device<'c, T> {
            #(#methods)*
        }

        #async_device
    }
}
