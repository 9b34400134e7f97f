//! Verified address changes on the typed device handles.

use super::address::{AddressChangeError, change_address};
use crate::{Transport, conductivity, ph_orp};

impl<T: Transport> ph_orp::Device<'_, T> {
    /// Changes the probe's slave address to `new` (1..=247, not in use on the
    /// bus), confirmed by the probe's reply and verified by reading its serial
    /// number at `new`; the handle then talks to `new`. On failure the error
    /// says where the probe answers (see [`change_address`]).
    pub fn set_slave_address(&mut self, new: u8) -> Result<(), AddressChangeError> {
        let from = self.address();
        change_address(self.client(), from, new, &ph_orp::SetSlaveId { slave_address: new }, &ph_orp::GetSn)?;
        self.set_address(new);
        Ok(())
    }
}

impl<T: Transport> conductivity::Device<'_, T> {
    /// Changes the probe's slave address to `new`; as
    /// [`ph_orp::Device::set_slave_address`].
    pub fn set_slave_address(&mut self, new: u8) -> Result<(), AddressChangeError> {
        let from = self.address();
        change_address(
            self.client(),
            from,
            new,
            &conductivity::SetSlaveId { slave_address: new },
            &conductivity::GetSn,
        )?;
        self.set_address(new);
        Ok(())
    }
}
