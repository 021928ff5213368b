//! The Dynamixel bus on the host-link UART: the board answers Dynamixel packets (as an
//! AX-12A in Protocol 1.0, as an X-series servo in 2.0) and our framed protocol on the same
//! line (`service::line` tells them apart; `service::link` keeps the half-duplex rules).
//!
//! The link task is pended every control tick (besides every received byte), so that an
//! idle line is noticed within a tick of [`IDLE_US`]. Nothing here touches the UART: the
//! bytes come from the receive queue the board's receive path fills, whatever fills it.

use service::dynamixel::Bus;
use service::link::{DynamixelStats, Link};

/// No byte for this long, µs: a partial Dynamixel packet is abandoned and the next byte
/// starts a new packet of either protocol. On the emulated boards bytes trickle in as
/// QEMU's USART model takes them (about 1 ms apart), and a loaded host can hold QEMU's I/O
/// thread back while the emulated core runs on: with 20 ms, 5 of 500 READs lost their
/// packet's tail that way (measured on a 2-core host at a load of 10); on the real line a
/// few character times.
#[cfg(feature = "qemu")]
pub const IDLE_US: u64 = 200_000;
/// See above (the real board: 10 character times at 57 600 Bd, the slowest rate served).
#[cfg(not(feature = "qemu"))]
pub const IDLE_US: u64 = 2_000;

/// The board's µs clock for the link task: [`crate::timing::uptime_us`] read in a
/// critical section (the tick count and the SysTick counter from the same period).
pub fn clock_us() -> u64 {
    cortex_m::interrupt::free(|_| crate::timing::uptime_us())
}

/// `link` serving the Dynamixel bus too, with the stored bus settings (ID, protocol,
/// baud, return delay, …), else the AX-12A's factory settings with `factory_id`.
pub fn serve<'q, W: embedded_io::Write>(link: Link<'q, W>, factory_id: u8) -> Link<'q, W> {
    let settings = link.service().boot_bus_settings(factory_id);
    defmt::info!(
        "Dynamixel bus: ID {=u8}, Protocol {=u8}.0, {=u32} Bd{=str}",
        settings.id,
        settings.protocol_version,
        settings.baud_bps,
        if link.service().bus_settings_stored() {
            " (stored)"
        } else {
            " (factory settings)"
        }
    );
    let link = link.with_dynamixel(Bus::from_settings(&settings), clock_us, IDLE_US);
    // The bus refuses a Baud Rate the UART cannot make within 2.5 %.
    #[cfg(feature = "dynamixel-ttl")]
    let link = {
        let mut link = link;
        link.service_mut().set_uart_rates(|bps| {
            drivers::usart_baud::divider(crate::board::USART2_CLOCK_HZ, bps).is_ok()
        });
        link
    };
    link
}

/// After each run of the link task: on a Dynamixel TTL bus (`dynamixel-ttl`), the bus's
/// Baud Rate goes to the UART (`Link::poll` returns only once no status waits, so the
/// status that changed it has gone out at the old rate). Elsewhere the UART keeps the
/// link's rate: the emulated USART ignores the rate, and the ST-LINK's virtual COM port
/// carries our protocol at 921 600 Bd. `applied` is the rate the UART runs at, bit/s (the
/// link task's own; 0: the link's own rate, before the bus's is applied).
pub fn follow_baud(link: &mut Link<'_, crate::board::SerialTx>, applied: &mut u32) {
    #[cfg(feature = "dynamixel-ttl")]
    {
        let Some(bps) = link.dynamixel().and_then(|b| b.baud_bps()) else {
            return;
        };
        if *applied == bps {
            return;
        }
        match drivers::usart_baud::divider(crate::board::USART2_CLOCK_HZ, bps) {
            Ok(d) => {
                link.tx().set_divider(d.brr, d.over8);
                defmt::info!("Dynamixel bus: {=u32} Bd ({} ppm)", bps, d.error_ppm);
            }
            // Refused by the bus's checks before; a stored one from another board.
            Err(e) => defmt::warn!("Dynamixel bus: {=u32} Bd not made: {}", bps, e),
        }
        *applied = bps;
    }
    #[cfg(not(feature = "dynamixel-ttl"))]
    let _ = (link, applied);
}

/// After each run of the link task: a Dynamixel packet cut short by an idle line or a
/// status dropped is logged with the counts since boot, so that a packet the bus lost
/// (noise on the wire; on the emulated boards, bytes held back by a loaded host) leaves a
/// trace in the board's log. `logged` is the counts as last logged (the link task's own).
pub fn log_losses<W: embedded_io::Write>(link: &Link<'_, W>, logged: &mut DynamixelStats) {
    let Some(stats) = link.dynamixel_stats() else {
        return;
    };
    if (stats.abandoned, stats.dropped) != (logged.abandoned, logged.dropped) {
        defmt::warn!(
            "Dynamixel bus: {=u32} packets cut short by an idle line, {=u32} statuses dropped (since boot)",
            stats.abandoned,
            stats.dropped
        );
        *logged = stats;
    }
}
