//! The async flash traits sequential-storage drives, over a blocking flash.
//!
//! The STM32F4's flash (and the RAM flash) works synchronously: the CPU stalls until a
//! program or erase is done, so an async driver would gain nothing. [`Blocking`] completes
//! every operation in its first poll, which is why the store can run the map's futures with
//! `embassy_futures::block_on` (one poll, no executor). It is embassy-embedded-hal's
//! `BlockingAsync`, plus access to the wrapped flash (the emulated boards snapshot it after
//! every operation; the tests read its wear counters), which `BlockingAsync` does not give.

use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};
use embedded_storage_async::nor_flash as nor_async;

/// A blocking [`NorFlash`] seen through the async traits.
#[derive(Debug)]
pub(crate) struct Blocking<F>(pub(crate) F);

impl<F: NorFlash> nor_async::ErrorType for Blocking<F> {
    type Error = F::Error;
}

impl<F: NorFlash> nor_async::ReadNorFlash for Blocking<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }

    fn capacity(&self) -> usize {
        ReadNorFlash::capacity(&self.0)
    }
}

impl<F: NorFlash> nor_async::NorFlash for Blocking<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.0.erase(from, to)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write(offset, bytes)
    }
}
