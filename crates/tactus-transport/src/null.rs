//! The null link: accepts every packet and sends it nowhere (`--glove null`).

use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::Packet;

use crate::link::Link;
use crate::LinkError;

/// The `null` sink's link.
pub(crate) struct NullLink;

impl Link for NullLink {
    fn connect(&mut self) -> Result<(), LinkError> {
        Ok(())
    }
    fn write(&mut self, _: &Packet, _: &[u8; PACKET_LEN]) -> Result<(), LinkError> {
        Ok(())
    }
    fn disconnect(&mut self) {}
}
