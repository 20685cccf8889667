//! A bare serial client for talking to the emulator in tests (no driver logic).
#![allow(dead_code)]

use footscan_hal::Timestamp;
use serialport::{ClearBuffer, SerialPort, TTYPort};
use std::io::{Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

pub struct Client {
    pub port: TTYPort,
    buf: Vec<u8>,
}

/// A status report with the monotonic times of its query and of its arrival.
#[derive(Clone, Debug)]
pub struct Report {
    pub line: String,
    pub sent: Timestamp,
    pub received: Timestamp,
}

impl Report {
    pub fn state(&self) -> &str {
        self.line[1..].split(['|', '>']).next().unwrap()
    }
    pub fn x(&self) -> f64 {
        let f = self
            .line
            .split(['|', '>', '<'])
            .find_map(|f| f.strip_prefix("MPos:"))
            .expect("MPos");
        f.split(',').next().unwrap().parse().unwrap()
    }
}

impl Client {
    pub fn open(path: &Path) -> Client {
        let port = serialport::new(path.to_string_lossy(), 115200)
            .timeout(Duration::from_millis(20))
            .open_native()
            .expect("open pty");
        port.clear(ClearBuffer::Input).unwrap();
        Client {
            port,
            buf: Vec::new(),
        }
    }

    pub fn send(&mut self, bytes: &[u8]) {
        self.port.write_all(bytes).unwrap();
    }

    /// Next non-empty line, or None after `timeout`.
    pub fn line(&mut self, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(i) = self.buf.iter().position(|&b| b == b'\n') {
                let l: Vec<u8> = self.buf.drain(..=i).collect();
                let s = String::from_utf8_lossy(&l).trim().to_string();
                if s.is_empty() {
                    continue;
                }
                return Some(s);
            }
            if Instant::now() >= deadline {
                return None;
            }
            let mut b = [0u8; 256];
            match self.port.read(&mut b) {
                Ok(n) => self.buf.extend_from_slice(&b[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("read: {e}"),
            }
        }
    }

    /// Send a line and collect everything up to and including its `ok`/`error:N`.
    pub fn cmd(&mut self, line: &str) -> Vec<String> {
        self.send(format!("{line}\n").as_bytes());
        self.until_response(Duration::from_secs(5))
    }

    pub fn until_response(&mut self, timeout: Duration) -> Vec<String> {
        let mut out = Vec::new();
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let l = self
                .line(left)
                .unwrap_or_else(|| panic!("no response; got {out:?}"));
            let done = l == "ok" || l.starts_with("error:");
            out.push(l);
            if done {
                return out;
            }
        }
    }

    /// Expect exactly `ok` (after any feedback lines).
    pub fn ok(&mut self, line: &str) {
        let r = self.cmd(line);
        assert_eq!(r.last().map(String::as_str), Some("ok"), "{line}: {r:?}");
    }

    pub fn status(&mut self) -> Report {
        let sent = Timestamp::now();
        self.send(b"?");
        let deadline = Instant::now() + Duration::from_secs(5);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let l = self.line(left).expect("status report");
            if l.starts_with('<') {
                return Report {
                    line: l,
                    sent,
                    received: Timestamp::now(),
                };
            }
        }
    }

    /// Soft reset; returns the lines up to the banner plus any that follow within 100 ms.
    pub fn reset(&mut self) -> Vec<String> {
        self.send(&[0x18]);
        let mut out = Vec::new();
        loop {
            let l = self.line(Duration::from_secs(5)).expect("banner");
            let banner = l.starts_with("Grbl ");
            out.push(l);
            if banner {
                break;
            }
        }
        while let Some(l) = self.line(Duration::from_millis(100)) {
            out.push(l);
        }
        out
    }

    /// Reset, unlock and home: an idle machine at 0.
    pub fn ready(&mut self) {
        self.reset();
        self.ok("$H");
    }

    pub fn wait_state(&mut self, state: &str, timeout: Duration) -> Report {
        let deadline = Instant::now() + timeout;
        loop {
            let r = self.status();
            if r.state() == state {
                return r;
            }
            assert!(Instant::now() < deadline, "never reached {state}: {r:?}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}
