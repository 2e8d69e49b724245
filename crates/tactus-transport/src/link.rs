//! The [`Link`] trait: one transport (serial, BLE, file, emulator, null) as the sink thread
//! sees it. Each link lives in its own file; [`crate::factory`] opens one by its spec.

use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::Packet;

use crate::LinkError;

/// One link as the sink thread sees it. Implementations block; the thread serialises calls.
pub(crate) trait Link: Send {
    /// Opens (or re-opens) the link.
    fn connect(&mut self) -> Result<(), LinkError>;
    /// Writes one packet (`bytes` is `packet.encode()`).
    fn write(&mut self, packet: &Packet, bytes: &[u8; PACKET_LEN]) -> Result<(), LinkError>;
    /// Closes the link; the next call is `connect`.
    fn disconnect(&mut self);
    /// The MTU, where the link knows one.
    fn mtu(&self) -> Option<u16> {
        None
    }
}
