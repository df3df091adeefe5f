//! A real serial device (e.g. the STM32F407 board's USART2 behind a USB-UART).

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use serialport::SerialPort;

use super::{ByteLink, LinkError};

pub struct SerialPortLink {
    port: Box<dyn SerialPort>,
    path: String,
}

impl SerialPortLink {
    /// Opens `path` at `baud`, 8N1, no flow control.
    pub fn open(path: &str, baud: u32) -> Result<Self, LinkError> {
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| LinkError::Serial {
                path: path.to_string(),
                detail: e.to_string(),
            })?;
        Ok(SerialPortLink {
            port,
            path: path.to_string(),
        })
    }
}

impl ByteLink for SerialPortLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.port.write_all(bytes).map_err(|source| LinkError::Io {
            what: "writing to the serial device",
            source,
        })
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        self.port
            .set_timeout(timeout.max(Duration::from_millis(1)))
            .map_err(|e| LinkError::Serial {
                path: self.path.clone(),
                detail: e.to_string(),
            })?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => Ok(0),
            Err(e) if e.kind() == ErrorKind::Interrupted => Ok(0),
            Err(source) => Err(LinkError::Io {
                what: "reading from the serial device",
                source,
            }),
        }
    }

    fn describe(&self) -> String {
        format!("serial device {}", self.path)
    }
}
