//! Pseudo-terminal plumbing: an openpty pair in raw mode and a self-pipe to wake the server.

use std::ffi::CStr;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::path::PathBuf;

/// The emulator's side of a pty pair.
///
/// The emulator keeps its own descriptor of the slave open for its whole life: without it the
/// master would see a hangup (and `read` would fail with EIO) every time the client closes its
/// port, and data written while no client is attached would be lost. Clients open `path`.
pub(crate) struct Pty {
    pub master: OwnedFd,
    /// Held open for the emulator's life (see above); never read.
    pub _slave: OwnedFd,
    pub path: PathBuf,
}

fn cvt(rc: libc::c_int) -> io::Result<libc::c_int> {
    if rc < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(rc)
    }
}

fn raw_termios() -> libc::termios {
    // SAFETY: termios is plain old data; all-zero is a valid starting point for cfmakeraw.
    let mut tio: libc::termios = unsafe { std::mem::zeroed() };
    // SAFETY: cfmakeraw/cfsetspeed only write into the struct we own.
    unsafe {
        libc::cfmakeraw(&mut tio);
        libc::cfsetspeed(&mut tio, libc::B115200);
    }
    tio.c_cflag |= libc::CREAD | libc::CLOCAL | libc::CS8;
    tio.c_cc[libc::VMIN] = 1;
    tio.c_cc[libc::VTIME] = 0;
    tio
}

fn set_flags(fd: RawFd, nonblocking: bool) -> io::Result<()> {
    // SAFETY: fcntl on a descriptor we own, with integer arguments.
    unsafe {
        let fl = cvt(libc::fcntl(fd, libc::F_GETFL))?;
        let fl = if nonblocking {
            fl | libc::O_NONBLOCK
        } else {
            fl
        };
        cvt(libc::fcntl(fd, libc::F_SETFL, fl))?;
        let fd_fl = cvt(libc::fcntl(fd, libc::F_GETFD))?;
        cvt(libc::fcntl(fd, libc::F_SETFD, fd_fl | libc::FD_CLOEXEC))?;
    }
    Ok(())
}

impl Pty {
    /// Open a pty pair in raw mode (no echo, no line discipline, 8N1), master non-blocking.
    pub fn open() -> io::Result<Pty> {
        let mut m: libc::c_int = -1;
        let mut s: libc::c_int = -1;
        let tio = raw_termios();
        // SAFETY: openpty writes two descriptors into m and s; we pass no name buffer (it has no
        // length bound) and read the name with ptsname_r instead.
        cvt(unsafe {
            libc::openpty(&mut m, &mut s, std::ptr::null_mut(), &tio, std::ptr::null())
        })?;
        // SAFETY: openpty succeeded, so both are fresh descriptors we now own.
        let (master, slave) = unsafe { (OwnedFd::from_raw_fd(m), OwnedFd::from_raw_fd(s)) };
        set_flags(master.as_raw_fd(), true)?;
        set_flags(slave.as_raw_fd(), false)?;
        // Some libcs ignore termp for part of the flags; apply raw mode explicitly too. The
        // attributes live on the slave's line discipline, which the master shares.
        // SAFETY: tcsetattr reads the termios we own.
        cvt(unsafe { libc::tcsetattr(slave.as_raw_fd(), libc::TCSANOW, &tio) })?;
        let mut buf = [0 as libc::c_char; 128];
        // SAFETY: buf is writable for its full length, which we pass.
        let rc = unsafe { libc::ptsname_r(master.as_raw_fd(), buf.as_mut_ptr(), buf.len()) };
        if rc != 0 {
            return Err(io::Error::from_raw_os_error(rc));
        }
        // SAFETY: ptsname_r NUL-terminated the buffer on success.
        let name = unsafe { CStr::from_ptr(buf.as_ptr()) };
        let path = PathBuf::from(name.to_string_lossy().into_owned());
        Ok(Pty {
            master,
            _slave: slave,
            path,
        })
    }
}

/// A non-blocking pipe used to wake the server's poll from other threads.
pub(crate) fn wake_pipe() -> io::Result<(OwnedFd, OwnedFd)> {
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: pipe2 writes two descriptors into the array we own.
    cvt(unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_NONBLOCK | libc::O_CLOEXEC) })?;
    // SAFETY: both descriptors are fresh and owned by us from here on.
    Ok(unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) })
}

/// Write one byte to the wake pipe (a full pipe already means "wake up", so errors are moot).
pub(crate) fn wake(fd: &OwnedFd) {
    let b = 1u8;
    // SAFETY: writes one byte from a live stack variable to a descriptor we own.
    let _ = unsafe { libc::write(fd.as_raw_fd(), (&b as *const u8).cast(), 1) };
}

/// Drain the wake pipe.
pub(crate) fn drain(fd: &OwnedFd) {
    let mut buf = [0u8; 64];
    loop {
        // SAFETY: reads into a stack buffer of the given length.
        let n = unsafe { libc::read(fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
        if n <= 0 {
            break;
        }
    }
}

/// `read(2)` into `buf`; `Ok(None)` when nothing is available (EAGAIN).
pub(crate) fn read_nb(fd: &OwnedFd, buf: &mut [u8]) -> io::Result<Option<usize>> {
    // SAFETY: reads at most buf.len() bytes into buf.
    let n = unsafe { libc::read(fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
    if n < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted {
            return Ok(None);
        }
        return Err(e);
    }
    Ok(Some(n as usize))
}

/// `write(2)` of `buf`; `Ok(0)` when the pty buffer is full (EAGAIN).
pub(crate) fn write_nb(fd: &OwnedFd, buf: &[u8]) -> io::Result<usize> {
    // SAFETY: writes at most buf.len() bytes from buf.
    let n = unsafe { libc::write(fd.as_raw_fd(), buf.as_ptr().cast(), buf.len()) };
    if n < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted {
            return Ok(0);
        }
        return Err(e);
    }
    Ok(n as usize)
}

/// Poll the master (for `events`) and the wake pipe for up to `timeout_s` seconds.
/// Returns (master revents, wake readable).
pub(crate) fn poll2(
    master: Option<&OwnedFd>,
    events: libc::c_short,
    wake: &OwnedFd,
    timeout_s: f64,
) -> (libc::c_short, bool) {
    let mut fds = [
        libc::pollfd {
            fd: master.map(|m| m.as_raw_fd()).unwrap_or(-1),
            events,
            revents: 0,
        },
        libc::pollfd {
            fd: wake.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        },
    ];
    let t = timeout_s.clamp(0.0, 1.0);
    let ts = libc::timespec {
        tv_sec: t.trunc() as libc::time_t,
        tv_nsec: ((t - t.trunc()) * 1e9) as libc::c_long,
    };
    // SAFETY: fds is a live array of two pollfd structs; ts lives for the call.
    let rc = unsafe { libc::ppoll(fds.as_mut_ptr(), 2, &ts, std::ptr::null()) };
    if rc <= 0 {
        return (0, false);
    }
    (fds[0].revents, fds[1].revents & libc::POLLIN != 0)
}
