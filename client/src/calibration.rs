//! The board's calibration sequence from the host: start, stop, progress and result.

use protocol::{CalibrationReport, Reply, Request};

use crate::{Client, Error, Result};

impl Client {
    /// [`Request::Calibrate`]: start the calibration sequence (`start`) or stop it. The
    /// board refuses to start unless disabled with no fault latched.
    ///
    /// # Errors
    /// As [`Client::ping`]; the board's refusal as [`Error::Refused`].
    pub fn calibrate(&mut self, start: bool) -> Result<()> {
        self.request_ok(Request::Calibrate { start })
    }

    /// [`Request::GetCalibration`]: the sequence's progress and the calibration in force.
    ///
    /// # Errors
    /// As [`Client::calibrate`].
    pub fn calibration(&mut self) -> Result<CalibrationReport> {
        match self.request(Request::GetCalibration)? {
            Reply::Calibration(report) => Ok(report),
            reply => Err(Error::UnexpectedReply {
                request: "get-calibration",
                reply,
            }),
        }
    }
}
