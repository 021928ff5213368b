//! The board's settings store from the host: save, load, factory reset, the fault log.

use protocol::{LoggedFault, Reply, Request};

use crate::{Client, Error, Result};

impl Client {
    /// [`Request::Save`]: the running configuration into the board's flash (refused with
    /// `not-allowed` while the motor is enabled).
    ///
    /// # Errors
    /// As [`Client::ping`]; the board's refusal as [`Error::Refused`].
    pub fn save(&mut self) -> Result<()> {
        self.request_ok(Request::Save)
    }

    /// [`Request::Load`]: the board re-reads its store and applies it.
    ///
    /// # Errors
    /// As [`Client::save`].
    pub fn load(&mut self) -> Result<()> {
        self.request_ok(Request::Load)
    }

    /// [`Request::FactoryReset`]: the board forgets its stored settings and fault log.
    ///
    /// # Errors
    /// As [`Client::save`].
    pub fn factory_reset(&mut self) -> Result<()> {
        self.request_ok(Request::FactoryReset)
    }

    /// The stored fault log, most recent first ([`Request::FaultsLog`], one request per
    /// entry).
    ///
    /// # Errors
    /// As [`Client::save`].
    pub fn fault_log(&mut self) -> Result<Vec<LoggedFault>> {
        let mut entries = Vec::new();
        for index in 0..=u8::MAX {
            match self.request(Request::FaultsLog { index })? {
                Reply::FaultsLog {
                    count,
                    entry: Some(e),
                } if index < count => entries.push(e),
                Reply::FaultsLog { .. } => return Ok(entries),
                reply => {
                    return Err(Error::UnexpectedReply {
                        request: "faults-log",
                        reply,
                    })
                }
            }
        }
        Ok(entries)
    }
}
