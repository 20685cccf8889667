//! The link: the serial port, its receive buffer split into lines, and arrival times.
//!
//! Everything that touches the port is here, so the layers above see lines with the
//! CLOCK_MONOTONIC time their bytes arrived, and a port that failed in any way as
//! [`HalError::Disconnected`] (the port is then dropped, so later calls fail fast until it is
//! opened again) or [`HalError::Timeout`]. Line splitting is kept in [`LineBuffer`], apart
//! from the port, so it can be tested on byte strings.

use footscan_hal::{HalError, HalResult, Timestamp};
use serialport::{ClearBuffer, SerialPort};
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

/// Bytes without a line end after which the receive buffer is thrown away as noise (GRBL's
/// longest line, a `$N=` startup line echo, is well under 100).
const MAX_PENDING: usize = 512;

/// Received bytes, handed out as trimmed non-empty lines (`\r\n` or `\n` terminated).
#[derive(Clone, Debug, Default)]
pub(crate) struct LineBuffer {
    rx: Vec<u8>,
}

impl LineBuffer {
    pub fn push(&mut self, bytes: &[u8]) {
        self.rx.extend_from_slice(bytes);
    }

    pub fn clear(&mut self) {
        self.rx.clear();
    }

    /// The next complete line, if any. Bytes that are not UTF-8 become U+FFFD, so noise
    /// still reaches the tracker as a (garbage) line. More than [`MAX_PENDING`] bytes without
    /// a line end are dropped and described in the error.
    pub fn next_line(&mut self) -> Result<Option<String>, String> {
        while let Some(i) = self.rx.iter().position(|&b| b == b'\n') {
            let raw: Vec<u8> = self.rx.drain(..=i).collect();
            let s = String::from_utf8_lossy(&raw).trim().to_string();
            if !s.is_empty() {
                return Ok(Some(s));
            }
        }
        if self.rx.len() > MAX_PENDING {
            let junk = std::mem::take(&mut self.rx);
            return Err(format!(
                "{} bytes without a line end: {:?}",
                junk.len(),
                String::from_utf8_lossy(&junk[..64])
            ));
        }
        Ok(None)
    }
}

/// The serial port of one controller.
pub(crate) struct Link {
    device: String,
    port: Option<Box<dyn SerialPort>>,
    lines: LineBuffer,
    /// When the bytes now at the end of the buffer arrived.
    rx_time: Timestamp,
    /// Longest a write may block (a controller that stopped reading).
    write_timeout: Duration,
}

impl Link {
    pub fn new(device: String, write_timeout: Duration) -> Self {
        Link {
            device,
            port: None,
            lines: LineBuffer::default(),
            rx_time: Timestamp::default(),
            write_timeout,
        }
    }

    pub fn device(&self) -> &str {
        &self.device
    }

    pub fn is_open(&self) -> bool {
        self.port.is_some()
    }

    /// Open the port and discard whatever the OS buffered before. A port that does not exist
    /// (unplugged) is `Disconnected`, so a reconnect loop can wait for it.
    pub fn open(&mut self, baud: u32) -> HalResult<()> {
        self.close();
        let port = serialport::new(&self.device, baud)
            .timeout(self.write_timeout)
            .open()
            .map_err(|e| {
                let absent = matches!(e.kind, serialport::ErrorKind::NoDevice)
                    || matches!(e.kind, serialport::ErrorKind::Io(ErrorKind::NotFound));
                if absent {
                    HalError::Disconnected {
                        device: self.device.clone(),
                        reason: format!("cannot open: {e}"),
                    }
                } else {
                    HalError::Io {
                        device: self.device.clone(),
                        source: e.into(),
                    }
                }
            })?;
        let _ = port.clear(ClearBuffer::All);
        self.port = Some(port);
        Ok(())
    }

    pub fn close(&mut self) {
        self.port = None;
        self.lines.clear();
    }

    fn not_open(&self) -> HalError {
        HalError::Disconnected {
            device: self.device.clone(),
            reason: "port not open (call connect)".into(),
        }
    }

    /// The port failed: drop it.
    fn lost(&mut self, reason: String) -> HalError {
        self.close();
        HalError::Disconnected {
            device: self.device.clone(),
            reason,
        }
    }

    pub fn write(&mut self, bytes: &[u8]) -> HalResult<()> {
        let timeout = self.write_timeout;
        let Some(port) = self.port.as_mut() else {
            return Err(self.not_open());
        };
        let _ = port.set_timeout(timeout);
        // No flush: tcdrain has no timeout and would hang on a controller that stopped reading.
        match port.write_all(bytes) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == ErrorKind::TimedOut => Err(HalError::Timeout {
                device: self.device.clone(),
                what: "the port to accept written bytes".into(),
                after: timeout,
            }),
            Err(e) => Err(self.lost(format!("write failed: {e}"))),
        }
    }

    /// One read of whatever is available, waiting until `deadline` at most.
    /// Returns whether anything arrived.
    pub fn read_some(&mut self, deadline: Instant) -> HalResult<bool> {
        let left = deadline.saturating_duration_since(Instant::now());
        let Some(port) = self.port.as_mut() else {
            return Err(self.not_open());
        };
        let _ = port.set_timeout(left);
        let mut buf = [0u8; 1024];
        match port.read(&mut buf) {
            Ok(0) => Err(self.lost("end of file on the port (hung up)".into())),
            Ok(n) => {
                self.rx_time = Timestamp::now();
                self.lines.push(&buf[..n]);
                Ok(true)
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                Ok(false)
            }
            Err(e) => Err(self.lost(format!("read failed: {e}"))),
        }
    }

    /// The next complete line already received, with the time its last bytes arrived.
    /// A receive buffer full of bytes without a line end is `BadData`.
    pub fn next_line(&mut self) -> HalResult<Option<(String, Timestamp)>> {
        match self.lines.next_line() {
            Ok(l) => Ok(l.map(|l| (l, self.rx_time))),
            Err(detail) => Err(HalError::BadData {
                device: self.device.clone(),
                detail,
            }),
        }
    }

    /// The next line, reading until one is complete or `deadline` passes (then `None`).
    pub fn read_line(&mut self, deadline: Instant) -> HalResult<Option<(String, Timestamp)>> {
        loop {
            if let Some(l) = self.next_line()? {
                return Ok(Some(l));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            self.read_some(deadline)?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_split_across_reads_and_terminators() {
        let mut b = LineBuffer::default();
        b.push(b"o");
        assert_eq!(b.next_line(), Ok(None));
        b.push(b"k\r");
        assert_eq!(b.next_line(), Ok(None), "no line before its \\n");
        b.push(b"\n\r\n\nerror:2");
        assert_eq!(b.next_line(), Ok(Some("ok".into())));
        assert_eq!(b.next_line(), Ok(None), "empty lines skipped");
        b.push(b"0\nok\n");
        assert_eq!(b.next_line(), Ok(Some("error:20".into())));
        assert_eq!(b.next_line(), Ok(Some("ok".into())));
        assert_eq!(b.next_line(), Ok(None));
    }

    #[test]
    fn noise_becomes_lines_or_is_dropped() {
        let mut b = LineBuffer::default();
        b.push(b"\xff\xfeok\r\n");
        assert_eq!(b.next_line(), Ok(Some("\u{fffd}\u{fffd}ok".into())));
        b.push(&[b'x'; MAX_PENDING]);
        assert_eq!(b.next_line(), Ok(None), "at the limit: still waiting");
        b.push(b"y");
        let e = b.next_line().unwrap_err();
        assert!(e.starts_with("513 bytes without a line end"), "{e}");
        b.push(b"ok\n");
        assert_eq!(b.next_line(), Ok(Some("ok".into())), "recovers");
    }
}
