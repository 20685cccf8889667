//! Process stages: an external program (`command = ["python3", "stage.py"]`) speaking a
//! line protocol on stdin/stdout, with each frame's pixels and output rows in a shared memory
//! file (a memfd) it maps as fd 3.
//!
//! Protocol 1 (docs/plugins.md has the whole contract):
//! * host: `hello 1 detector key=value ...` ; process: `ready 1` (or `error <text>`).
//! * host: `frame <seq> <width> <height> <bytes_per_px> <size>` after writing the pixels at
//!   offset 0 of the shared file (`size` bytes long; re-map when it changes); process: writes
//!   one 24-byte record per row at offset `round_up(width*height*bytes_per_px, 8)`, then
//!   answers `rows <n>` (or `error <text>`).
//! * A per-scan stage is greeted `hello 1 scan ...`; host: `scan <seq> <len> <size>` with the
//!   scan's points (`len` bytes, x y z f64 each) at offset 0; process: writes a report of
//!   `key value` lines at offset `round_up(len, 8)` and answers `report <n>`.
//! * A sink is greeted `hello 1 sink ...`; host: `sink <seq> <len> <size> <scan dir>` with the
//!   scan summary (JSON, `len` bytes) at offset 0; process: a report as above.
//! * Closing stdin ends the process; it must exit within a second.
//!
//! The host maps the same memfd, so a frame is written once, straight into the memory the
//! process reads, and the rows are read where the process wrote them; the answer is read on
//! the calling thread with poll(2), so a frame costs one copy and two wake-ups (docs/method.md
//! 14d.4 has the figures).
//!
//! Why a process and not a library: a crash, a leak or a hang of a researcher's numpy code
//! cannot take the daemon with it; the host kills and restarts the process (a limited number
//! of times per scan) and the scan fails only when the process keeps failing.

use std::fmt::Write as _;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::unix::process::CommandExt;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

use crate::rows::{self, Pixels, RowOut, ROW_BYTES};
use crate::PluginError;

/// The protocol version this host speaks.
pub const PROTOCOL_VERSION: u32 = 1;
/// The descriptor the shared frame file is given as in the process.
pub const FRAME_FD: i32 = 3;

/// Limits of a process stage.
#[derive(Clone, Debug, PartialEq)]
pub struct ExecLimits {
    /// Longest wait for the answer to one frame before the process is killed.
    pub frame_timeout: Duration,
    /// Longest wait for `ready` after the start (an interpreter importing numpy).
    pub start_timeout: Duration,
    /// Restarts allowed per scan after the process died or hung; one more failure fails the
    /// scan.
    pub max_restarts: u32,
}

impl Default for ExecLimits {
    fn default() -> Self {
        Self {
            frame_timeout: Duration::from_secs(2),
            start_timeout: Duration::from_secs(20),
            max_restarts: 2,
        }
    }
}

/// What went wrong in one exchange, and whether a restart may help.
enum Failure {
    /// Exited, was killed or hung (then killed here): restart if allowed.
    Died(String),
    /// Answered, but against the protocol: a bug a restart will not fix.
    Broken(String),
}

struct Proc {
    child: Child,
    stdin: ChildStdin,
    stdout: LineReader,
}

/// Longest line a process may write on stdout; a longer one is garbage, not an answer.
const MAX_LINE: usize = 4096;

/// Lines from the process's stdout, read on the caller's thread with a deadline.
struct LineReader {
    out: ChildStdout,
    buf: Vec<u8>,
}

/// Why no line came.
enum NoLine {
    Timeout,
    /// Closed, unreadable or not a line of text: the reason.
    Gone(String),
}

impl LineReader {
    /// The next line (without its newline) into `line`, waiting until `deadline` at most.
    fn read_line(&mut self, line: &mut String, deadline: Instant) -> Result<(), NoLine> {
        loop {
            if let Some(i) = self.buf.iter().position(|&b| b == b'\n') {
                let text = std::str::from_utf8(&self.buf[..i]).map_err(|_| {
                    NoLine::Gone(format!(
                        "wrote a line that is not text: {:?}",
                        preview(&self.buf[..i])
                    ))
                })?;
                line.clear();
                line.push_str(text);
                self.buf.drain(..=i);
                return Ok(());
            }
            if self.buf.len() > MAX_LINE {
                return Err(NoLine::Gone(format!(
                    "wrote {} bytes without a newline: {:?}",
                    self.buf.len(),
                    preview(&self.buf)
                )));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(NoLine::Timeout);
            }
            let mut pfd = libc::pollfd {
                fd: self.out.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            let ms = left.as_millis().clamp(1, i32::MAX as u128) as i32;
            // SAFETY: one valid pollfd for the duration of the call.
            let r = unsafe { libc::poll(&mut pfd, 1, ms) };
            if r < 0 {
                let e = std::io::Error::last_os_error();
                if e.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(NoLine::Gone(format!("stdout could not be polled: {e}")));
            }
            if r == 0 {
                continue;
            }
            let at = self.buf.len();
            self.buf.resize(at + MAX_LINE, 0);
            let got = self.out.read(&mut self.buf[at..]);
            self.buf.truncate(at + *got.as_ref().unwrap_or(&0));
            match got {
                Ok(0) => return Err(NoLine::Gone("closed its stdout (exited)".into())),
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(NoLine::Gone(format!("stdout could not be read: {e}"))),
            }
        }
    }
}

/// The memfd and the host's own shared mapping of it.
struct Shm {
    file: std::fs::File,
    ptr: *mut u8,
    len: usize,
}

// SAFETY: the mapping is owned by this value alone (the process maps its own view of the
// file); moving it between threads moves that ownership.
unsafe impl Send for Shm {}

impl Shm {
    fn new() -> std::io::Result<Self> {
        Ok(Self {
            file: memfd()?,
            ptr: std::ptr::null_mut(),
            len: 0,
        })
    }

    /// Make the file (and the mapping) `len` bytes long.
    fn resize(&mut self, len: usize) -> std::io::Result<()> {
        if len == self.len {
            return Ok(());
        }
        self.unmap();
        self.file.set_len(len as u64)?;
        // SAFETY: a fresh shared mapping of a file we own, `len` > 0 bytes long.
        let p = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                self.file.as_raw_fd(),
                0,
            )
        };
        if p == libc::MAP_FAILED {
            return Err(std::io::Error::last_os_error());
        }
        self.ptr = p.cast();
        self.len = len;
        Ok(())
    }

    fn unmap(&mut self) {
        if !self.ptr.is_null() {
            // SAFETY: `ptr`/`len` are the live mapping made in `resize`.
            unsafe { libc::munmap(self.ptr.cast(), self.len) };
            self.ptr = std::ptr::null_mut();
            self.len = 0;
        }
    }

    /// The first `n` bytes to write into. Only called while the process waits for a
    /// request, so nothing else writes them meanwhile.
    fn head_mut(&mut self, n: usize) -> &mut [u8] {
        assert!(
            n <= self.len,
            "{n} bytes of a {}-byte shared memory",
            self.len
        );
        if n == 0 {
            return &mut [];
        }
        // SAFETY: in bounds of the live mapping; `&mut self` keeps the slice unique here.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, n) }
    }

    /// Copy `dst.len()` bytes from `off` out of the mapping. A copy, not a borrow: a
    /// misbehaving process may still be writing, and what it writes is checked after.
    fn read_at(&self, off: usize, dst: &mut [u8]) {
        assert!(off + dst.len() <= self.len, "read past the shared memory");
        // SAFETY: in bounds of the live mapping; `dst` is ours and does not overlap it.
        unsafe { std::ptr::copy_nonoverlapping(self.ptr.add(off), dst.as_mut_ptr(), dst.len()) }
    }
}

impl Drop for Shm {
    fn drop(&mut self) {
        self.unmap();
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Where a process stage sits, the word its `hello` carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExecRole {
    Detector,
    Scan,
    Sink,
}

impl ExecRole {
    fn word(self) -> &'static str {
        match self {
            Self::Detector => "detector",
            Self::Scan => "scan",
            Self::Sink => "sink",
        }
    }

    /// What one request is called in a message.
    fn request(self) -> &'static str {
        match self {
            Self::Detector => "frame",
            Self::Scan => "scan",
            Self::Sink => "sink call",
        }
    }
}

/// Longest report a per-scan or sink process may write, bytes.
pub const REPORT_CAP: usize = 64 << 10;

/// A stage run by an external process: a per-frame detector, a per-scan stage or a sink.
pub type ExecStage = ExecDetector;

/// A process stage (named for its first use, the per-frame detector).
pub struct ExecDetector {
    name: String,
    role: ExecRole,
    command: Vec<String>,
    args: Vec<(String, String)>,
    limits: ExecLimits,
    shm: Shm,
    proc: Option<Proc>,
    restarts: u32,
    scratch: Vec<u8>,
    seq: u64,
    /// The request line and the answer, kept so a frame allocates nothing.
    msg: String,
    answer: String,
}

impl std::fmt::Debug for ExecDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExecDetector")
            .field("command", &self.command)
            .field("restarts", &self.restarts)
            .finish()
    }
}

fn memfd() -> std::io::Result<std::fs::File> {
    // SAFETY: memfd_create takes a NUL-terminated name and flags; a valid fd is owned here.
    let fd = unsafe { libc::memfd_create(c"footscan-frame".as_ptr(), libc::MFD_CLOEXEC) };
    if fd < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: `fd` was just created and nothing else owns it.
    Ok(std::fs::File::from(unsafe { OwnedFd::from_raw_fd(fd) }))
}

impl ExecDetector {
    /// Start `command` as a detector and exchange `hello`/`ready`; any failure is a refusal
    /// at start.
    pub fn start(
        command: &[String],
        args: &[(String, f64)],
        limits: ExecLimits,
    ) -> Result<Self, PluginError> {
        let args: Vec<(String, String)> = args
            .iter()
            .map(|(k, v)| (k.clone(), v.to_string()))
            .collect();
        Self::start_as(ExecRole::Detector, command, &args, limits)
    }

    /// Start `command` in `role`; `args` are sent as `key=value` words in `hello`.
    pub fn start_as(
        role: ExecRole,
        command: &[String],
        args: &[(String, String)],
        limits: ExecLimits,
    ) -> Result<Self, PluginError> {
        let name = format!("`{}`", command.join(" "));
        let refuse = |reason: String| PluginError::Load {
            plugin: name.clone(),
            reason,
        };
        if command.is_empty() {
            return Err(refuse(
                "command is empty; give the program and its arguments, e.g. [\"python3\", \"stage.py\"]".into(),
            ));
        }
        if let Some((k, _)) = args
            .iter()
            .find(|(k, _)| k.is_empty() || k.contains(['=', ' ', '\n']))
        {
            return Err(refuse(format!(
                "args key {k:?}: keys must be non-empty and hold no '=', space or newline"
            )));
        }
        if let Some((k, v)) = args
            .iter()
            .find(|(_, v)| v.is_empty() || v.contains(char::is_whitespace))
        {
            return Err(refuse(format!(
                "args.{k} = {v:?}: values must be non-empty and hold no space or newline"
            )));
        }
        let shm =
            Shm::new().map_err(|e| refuse(format!("cannot create its shared memory: {e}")))?;
        let mut d = Self {
            name: name.clone(),
            role,
            command: command.to_vec(),
            args: args.to_vec(),
            limits,
            shm,
            proc: None,
            restarts: 0,
            scratch: Vec::new(),
            seq: 0,
            msg: String::new(),
            answer: String::new(),
        };
        d.spawn().map_err(|e| match e {
            Failure::Died(w) | Failure::Broken(w) => refuse(w),
        })?;
        Ok(d)
    }

    /// How many times the process was restarted in this scan.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    fn fault(&self, what: String) -> PluginError {
        PluginError::Fault {
            plugin: self.name.clone(),
            what,
        }
    }

    fn spawn(&mut self) -> Result<(), Failure> {
        self.proc = None;
        let shm_fd = self.shm.file.as_raw_fd();
        let mut cmd = Command::new(&self.command[0]);
        cmd.args(&self.command[1..])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        // SAFETY: only async-signal-safe calls between fork and exec: dup2 gives the child the
        // shared file as fd 3 and clears close-on-exec on the copy; when the file already is
        // fd 3 dup2 does nothing, so close-on-exec is cleared by hand.
        unsafe {
            cmd.pre_exec(move || {
                let ok = if shm_fd == FRAME_FD {
                    libc::fcntl(FRAME_FD, libc::F_SETFD, 0) >= 0
                } else {
                    libc::dup2(shm_fd, FRAME_FD) >= 0
                };
                if !ok {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let mut child = cmd
            .spawn()
            .map_err(|e| Failure::Broken(format!("cannot start {}: {e}", self.command[0])))?;
        let stdin = child.stdin.take().expect("piped");
        let stdout = child.stdout.take().expect("piped");
        let stderr = child.stderr.take().expect("piped");
        let who = self.name.clone();
        std::thread::Builder::new()
            .name("plugin-stderr".into())
            .spawn(move || {
                for line in BufReader::new(stderr).lines() {
                    let Ok(line) = line else { return };
                    tracing::warn!(plugin = %who, "{line}");
                }
            })
            .expect("thread spawns");
        self.proc = Some(Proc {
            child,
            stdin,
            stdout: LineReader {
                out: stdout,
                buf: Vec::with_capacity(2 * MAX_LINE),
            },
        });
        let mut hello = format!("hello {PROTOCOL_VERSION} {}", self.role.word());
        for (k, v) in &self.args {
            hello += &format!(" {k}={v}");
        }
        self.msg = hello;
        self.exchange(self.limits.start_timeout)?;
        let answer = self.answer.as_str();
        let words: Vec<&str> = answer.split_whitespace().collect();
        match words.as_slice() {
            ["ready", v] if *v == PROTOCOL_VERSION.to_string() => Ok(()),
            ["error", ..] => Err(Failure::Broken(format!(
                "refused to start: {}",
                answer.trim_start_matches("error").trim()
            ))),
            _ => Err(Failure::Broken(format!(
                "answered hello with {:?}, not \"ready {PROTOCOL_VERSION}\"",
                preview(answer.as_bytes())
            ))),
        }
    }

    /// Send `self.msg` as one line, wait for one line into `self.answer`.
    fn exchange(&mut self, timeout: Duration) -> Result<(), Failure> {
        let Some(p) = self.proc.as_mut() else {
            return Err(Failure::Died("is not running".into()));
        };
        self.msg.push('\n');
        let sent = p
            .stdin
            .write_all(self.msg.as_bytes())
            .and_then(|()| p.stdin.flush());
        self.msg.pop();
        if let Err(e) = sent {
            return Err(Failure::Died(format!("{} ({e})", exit_text(&mut p.child))));
        }
        match p
            .stdout
            .read_line(&mut self.answer, Instant::now() + timeout)
        {
            Ok(()) => {
                let n = self.answer.trim_end().len();
                self.answer.truncate(n);
                Ok(())
            }
            Err(NoLine::Gone(why)) => {
                // Wait briefly so the exit status tells how it ended.
                let status = wait_briefly(&mut p.child);
                Err(Failure::Died(format!("{why}: {status}")))
            }
            Err(NoLine::Timeout) => {
                let _ = p.child.kill();
                let _ = p.child.wait();
                Err(Failure::Died(format!(
                    "did not answer within {} ms (frame_timeout_ms); killed",
                    timeout.as_millis()
                )))
            }
        }
    }

    /// Detect the line in every row of a `width` x `height` frame into `out` (one per row).
    pub fn detect(
        &mut self,
        width: u32,
        height: u32,
        px: Pixels<'_>,
        out: &mut [RowOut],
    ) -> Result<(), PluginError> {
        let (w, h, bpp) = (width as usize, height as usize, px.bytes_per_px());
        assert_eq!(px.len(), w * h, "pixels of a {width}x{height} frame");
        assert_eq!(out.len(), h, "one result per row");
        let out_off = (w * h * bpp).div_ceil(8) * 8;
        let size = out_off + h * ROW_BYTES;
        self.shm
            .resize(size)
            .map_err(|e| self.fault(format!("could not size its shared memory: {e}")))?;
        px.write_le(self.shm.head_mut(w * h * bpp));
        self.seq += 1;
        self.msg.clear();
        let _ = write!(self.msg, "frame {} {width} {height} {bpp} {size}", self.seq);
        let n = self.request("rows")?;
        if n != h {
            return Err(self.fault(format!(
                "answered {n} rows for a frame of {h} rows (it must write one per row) on frame {}",
                self.seq
            )));
        }
        self.scratch.resize(h * ROW_BYTES, 0);
        self.shm.read_at(out_off, &mut self.scratch);
        rows::parse(&self.scratch, width, out)
            .map_err(|what| self.fault(format!("{what} on frame {}", self.seq)))
    }
}

impl ExecDetector {
    /// Send `self.msg` and wait for `<word> <n>`, restarting a process that died or hung
    /// (the shared file keeps its contents, so the request is simply sent again).
    fn request(&mut self, word: &str) -> Result<usize, PluginError> {
        loop {
            let failure = match self.exchange(self.limits.frame_timeout) {
                Ok(()) => match parse_count_answer(&self.answer, word) {
                    Ok(n) => return Ok(n),
                    Err(e) => Failure::Broken(e),
                },
                Err(f) => f,
            };
            match failure {
                Failure::Died(why) if self.restarts < self.limits.max_restarts => {
                    self.restarts += 1;
                    tracing::warn!(
                        plugin = %self.name,
                        restart = self.restarts,
                        "{why} on {} {}; restarting it",
                        self.role.request(),
                        self.seq
                    );
                    let msg = std::mem::take(&mut self.msg);
                    let spawned = self.spawn();
                    self.msg = msg;
                    if let Err(Failure::Died(w) | Failure::Broken(w)) = spawned {
                        return Err(self.fault(format!("could not be restarted: {w}")));
                    }
                }
                Failure::Died(why) => {
                    return Err(self.fault(format!(
                        "{why} on {} {} after {} restarts (max_restarts)",
                        self.role.request(),
                        self.seq,
                        self.restarts
                    )))
                }
                Failure::Broken(why) => {
                    return Err(self.fault(format!(
                        "{why} on {} {}",
                        self.role.request(),
                        self.seq
                    )))
                }
            }
        }
    }

    /// A per-scan stage's or sink's one call: `input` in, its report out. `dir` (sinks) is
    /// the scan directory, sent at the end of the request line.
    pub fn run(
        &mut self,
        input: &[u8],
        dir: Option<&std::path::Path>,
    ) -> Result<Vec<u8>, PluginError> {
        let word = match self.role {
            ExecRole::Scan => "scan",
            ExecRole::Sink => "sink",
            ExecRole::Detector => {
                return Err(self.fault("is a detector: it takes frames, not a scan".into()))
            }
        };
        let out_off = input.len().div_ceil(8) * 8;
        let size = out_off + REPORT_CAP;
        self.shm
            .resize(size)
            .map_err(|e| self.fault(format!("could not size its shared memory: {e}")))?;
        self.shm.head_mut(input.len()).copy_from_slice(input);
        self.seq += 1;
        self.msg.clear();
        let _ = write!(self.msg, "{word} {} {} {size}", self.seq, input.len());
        if let Some(d) = dir {
            let d = d.display().to_string();
            if d.contains('\n') {
                return Err(self.fault(format!("cannot be sent the directory {d:?} (a newline)")));
            }
            let _ = write!(self.msg, " {d}");
        }
        let n = self.request("report")?;
        if n > REPORT_CAP {
            return Err(self.fault(format!(
                "answered a report of {n} bytes, more than the {REPORT_CAP} it has"
            )));
        }
        let mut report = vec![0; n];
        self.shm.read_at(out_off, &mut report);
        Ok(report)
    }
}

fn parse_count_answer(answer: &str, word: &str) -> Result<usize, String> {
    let words: Vec<&str> = answer.split_whitespace().collect();
    match words.as_slice() {
        [w, n] if *w == word => n.parse().map_err(|_| {
            format!(
                "answered {:?}: the count is not a number",
                preview(answer.as_bytes())
            )
        }),
        ["error", ..] => Err(format!(
            "reported an error: {}",
            answer.trim_start_matches("error").trim()
        )),
        _ => Err(format!(
            "answered {:?}, not \"{word} <n>\" (protocol {PROTOCOL_VERSION}, docs/plugins.md)",
            preview(answer.as_bytes())
        )),
    }
}

/// The first 80 bytes of what a process wrote, for a message.
fn preview(b: &[u8]) -> String {
    let s = String::from_utf8_lossy(&b[..b.len().min(80)]).into_owned();
    if b.len() > 80 {
        s + "..."
    } else {
        s
    }
}

fn exit_text(child: &mut Child) -> String {
    match child.try_wait() {
        Ok(Some(s)) => describe_status(s),
        _ => "its stdin is closed".into(),
    }
}

fn wait_briefly(child: &mut Child) -> String {
    for _ in 0..100 {
        if let Ok(Some(s)) = child.try_wait() {
            return describe_status(s);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.kill();
    let _ = child.wait();
    "still running; killed".into()
}

fn describe_status(s: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exited with status {c}"),
        (None, Some(sig)) => format!("killed by signal {sig}"),
        _ => format!("ended ({s})"),
    }
}
