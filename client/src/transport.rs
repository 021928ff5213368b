//! Byte transports to a board: a serial port (the real board's ST-LINK virtual COM port) or
//! a TCP stream (an emulated board, a relay, or the in-process [`crate::fake`] board).

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// Default baud rate of the real board's UART (USART2 via the ST-LINK VCP), 8N1.
pub const DEFAULT_BAUD: u32 = 921_600;

/// Shortest read timeout handed to the OS (a zero timeout means "block forever" to some
/// APIs), 1 ms.
const MIN_WAIT: Duration = Duration::from_millis(1);

/// A bidirectional byte stream to a board.
pub trait Transport: Send {
    /// Reads whatever bytes are available into `buf`, waiting at most `wait` for the first
    /// one. Returns the number of bytes read: 0 when nothing arrived in time.
    ///
    /// # Errors
    /// An I/O error, or [`io::ErrorKind::UnexpectedEof`] when the peer closed the stream.
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> io::Result<usize>;

    /// Writes all of `bytes` (and flushes them).
    ///
    /// # Errors
    /// An I/O error.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// A short description for messages, e.g. `tcp 127.0.0.1:4000`.
    fn describe(&self) -> String;
}

fn timed_out(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// A TCP stream to a board (emulated board, relay, fake board).
#[derive(Debug)]
pub struct TcpTransport {
    stream: TcpStream,
    peer: String,
    wait: Option<Duration>,
}

impl TcpTransport {
    /// Connects to `addr` (e.g. `127.0.0.1:4000`), giving up after `timeout`.
    ///
    /// # Errors
    /// The address does not resolve, or no connection within `timeout`.
    pub fn connect(addr: &str, timeout: Duration) -> io::Result<TcpTransport> {
        let mut last = io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{addr}: no address to connect to"),
        );
        for a in addr.to_socket_addrs()? {
            match TcpStream::connect_timeout(&a, timeout) {
                Ok(s) => return TcpTransport::from_stream(s),
                Err(e) => last = e,
            }
        }
        Err(last)
    }

    /// Wraps a connected stream (e.g. one accepted from QEMU's serial chardev).
    ///
    /// # Errors
    /// Setting the socket options failed.
    pub fn from_stream(stream: TcpStream) -> io::Result<TcpTransport> {
        stream.set_nodelay(true)?;
        stream.set_nonblocking(false)?;
        let peer = stream
            .peer_addr()
            .map_or_else(|_| "?".to_string(), |a| a.to_string());
        Ok(TcpTransport {
            stream,
            peer,
            wait: None,
        })
    }

    /// The underlying stream.
    #[must_use]
    pub fn stream(&self) -> &TcpStream {
        &self.stream
    }
}

impl Transport for TcpTransport {
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> io::Result<usize> {
        let wait = wait.max(MIN_WAIT);
        if self.wait != Some(wait) {
            self.stream.set_read_timeout(Some(wait))?;
            self.wait = Some(wait);
        }
        match self.stream.read(buf) {
            Ok(0) if !buf.is_empty() => Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "the other end closed the connection",
            )),
            Ok(n) => Ok(n),
            Err(e) if timed_out(&e) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.stream.write_all(bytes)?;
        self.stream.flush()
    }

    fn describe(&self) -> String {
        format!("tcp {}", self.peer)
    }
}

/// A serial port (the real board: `/dev/ttyACM0`, 921 600 baud 8N1 by default).
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
    path: String,
    wait: Option<Duration>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

impl SerialTransport {
    /// Opens `path` at `baud` baud, 8N1, no flow control.
    ///
    /// # Errors
    /// The port does not exist, is busy, or refuses the settings.
    pub fn open(path: &str, baud: u32) -> io::Result<SerialTransport> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(io::Error::from)?;
        Ok(SerialTransport {
            port,
            path: path.to_string(),
            wait: Some(Duration::from_millis(10)),
        })
    }
}

impl Transport for SerialTransport {
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> io::Result<usize> {
        let wait = wait.max(MIN_WAIT);
        if self.wait != Some(wait) {
            self.port.set_timeout(wait).map_err(io::Error::from)?;
            self.wait = Some(wait);
        }
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if timed_out(&e) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn describe(&self) -> String {
        format!("serial {}", self.path)
    }
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> io::Result<usize> {
        (**self).read(buf, wait)
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).write_all(bytes)
    }

    fn describe(&self) -> String {
        (**self).describe()
    }
}
