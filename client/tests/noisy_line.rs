//! A noisy line between the client and a board: the line corrupts the first frames the
//! client sends (one byte flipped: the board answers a line error) and eats the board's
//! first reply. The client sends the request again with the same `seq`; the board answers
//! the repeat from its reply cache, so each request is carried out once.

use std::io;
use std::time::Duration;

use client::fake::FakeBoard;
use client::Client;
use client::{TcpTransport, Transport};
use protocol::State;

/// A line that flips one byte in each of the first `corrupt` writes and drops what the
/// board sends until `swallow` whole frames have gone by.
struct NoisyLine {
    inner: TcpTransport,
    corrupt: u32,
    swallow: u32,
}

impl Transport for NoisyLine {
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> io::Result<usize> {
        let n = self.inner.read(buf, wait)?;
        if self.swallow == 0 {
            return Ok(n);
        }
        let mut kept = 0;
        for i in 0..n {
            let b = buf[i];
            if self.swallow > 0 {
                if b == 0 {
                    self.swallow -= 1;
                }
            } else {
                buf[kept] = b;
                kept += 1;
            }
        }
        Ok(kept)
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.corrupt > 0 && bytes.len() > 4 {
            self.corrupt -= 1;
            let mut noisy = bytes.to_vec();
            let i = noisy.len() / 2;
            noisy[i] ^= 0x5A;
            if noisy[i] == 0 {
                noisy[i] = 0x33; // keep the frame in one piece
            }
            return self.inner.write_all(&noisy);
        }
        self.inner.write_all(bytes)
    }

    fn describe(&self) -> String {
        format!("noisy {}", self.inner.describe())
    }
}

fn client(board: &FakeBoard, corrupt: u32, swallow: u32) -> Client {
    let inner = TcpTransport::connect(&board.addr().to_string(), Duration::from_secs(5)).unwrap();
    Client::new(NoisyLine {
        inner,
        corrupt,
        swallow,
    })
    .with_timeout(Duration::from_millis(300))
}

#[test]
fn a_corrupted_request_is_sent_again_and_succeeds() {
    let board = FakeBoard::start().unwrap();
    let mut c = client(&board, 1, 0);
    c.enable().expect("enabled at the second attempt");
    assert_eq!(board.shared().device.state, State::Enabled);
    let stats = c.stats();
    assert_eq!(stats.retries, 1);
    assert_eq!(stats.line_errors, 1);
}

#[test]
fn a_lost_reply_is_replayed_not_carried_out_twice() {
    let board = FakeBoard::start().unwrap();
    let mut c = client(&board, 0, 1);
    // The reply to the first attempt is lost; the retry gets the cached reply.
    let k = c.set_stiffness(200_000).expect("the retry's reply");
    assert!(k > 0);
    let stats = c.stats();
    assert_eq!(stats.retries, 1);
    assert_eq!(board.shared().protocol_errors, 0);
    // Without retries the same loss is a timeout.
    let mut c = client(&board, 0, 1);
    c.set_retries(0);
    assert!(c.ping().is_err());
}
