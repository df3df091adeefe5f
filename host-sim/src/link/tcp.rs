//! The emulated board's UART0 over TCP (QEMU `-chardev socket,...,nodelay=on`).

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use super::{ByteLink, LinkError};

pub struct TcpLink {
    stream: TcpStream,
    peer: String,
}

impl TcpLink {
    /// Connects to `addr`, retrying until `connect_timeout` passes (QEMU may
    /// still be opening its socket).
    pub fn connect(addr: &str, connect_timeout: Duration) -> Result<Self, LinkError> {
        let deadline = Instant::now() + connect_timeout;
        let target = addr
            .to_socket_addrs()
            .map_err(|source| LinkError::Io {
                what: "resolving the emulator address",
                source,
            })?
            .next()
            .ok_or_else(|| LinkError::Io {
                what: "resolving the emulator address",
                source: std::io::Error::new(ErrorKind::NotFound, format!("{addr} has no address")),
            })?;
        loop {
            match TcpStream::connect_timeout(&target, Duration::from_millis(500)) {
                Ok(stream) => {
                    // Nagle would hold each small frame for ~40 ms.
                    stream.set_nodelay(true).map_err(|source| LinkError::Io {
                        what: "setting TCP_NODELAY",
                        source,
                    })?;
                    return Ok(TcpLink {
                        stream,
                        peer: addr.to_string(),
                    });
                }
                Err(e) if Instant::now() < deadline => {
                    let _ = e;
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(source) => {
                    return Err(LinkError::Io {
                        what: "connecting to the emulator's UART socket",
                        source,
                    })
                }
            }
        }
    }
}

impl ByteLink for TcpLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.stream
            .write_all(bytes)
            .map_err(|source| LinkError::Io {
                what: "sending to the emulator",
                source,
            })
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        // A zero timeout would mean "block forever" to set_read_timeout.
        let timeout = timeout.max(Duration::from_micros(1));
        self.stream
            .set_read_timeout(Some(timeout))
            .map_err(|source| LinkError::Io {
                what: "setting the read timeout",
                source,
            })?;
        match self.stream.read(buf) {
            Ok(0) => Err(LinkError::Closed),
            Ok(n) => Ok(n),
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => Ok(0),
            Err(e) if e.kind() == ErrorKind::Interrupted => Ok(0),
            Err(source) => Err(LinkError::Io {
                what: "receiving from the emulator",
                source,
            }),
        }
    }

    fn describe(&self) -> String {
        format!("emulator UART over tcp://{}", self.peer)
    }
}
