//! The file-system part of WASI preview 1 a granted module may use, over exactly one
//! directory: the module sees it as its one preopened descriptor (fd 3) and can open files
//! beneath it, read them, and (for per-scan stages, whose grant is writable) write them.
//!
//! Why by hand and not the wasmtime-wasi crate: that crate brings the component model, tokio
//! and cap-std (minutes of CI build for eight functions), and grants the rest of WASI (clocks,
//! randomness, sockets) by default. Confinement is the kernel's: every path is opened with
//! openat2(RESOLVE_BENEATH) from the granted directory's descriptor (footscan_util::beneath,
//! the copy the daemon's archive uses too), so `..`, absolute paths
//! and symlinks out of the directory fail in the kernel, not in a check here that could miss
//! a case.

use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::os::fd::{AsFd, OwnedFd};

use footscan_util::beneath::{open_beneath, Links};
use std::path::PathBuf;

use wasmtime::{Caller, Extern, Linker};

/// The WASI module name the functions are imported from.
pub const MODULE: &str = "wasi_snapshot_preview1";

/// What a granted module may import from [`MODULE`]; anything else is refused at load.
pub const PROVIDED: [&str; 8] = [
    "fd_prestat_get",
    "fd_prestat_dir_name",
    "path_open",
    "fd_read",
    "fd_write",
    "fd_seek",
    "fd_filestat_get",
    "fd_close",
];

/// The descriptor the granted directory has in the module.
pub const DIR_FD: u32 = 3;
/// Files a module may hold open at once.
const MAX_OPEN: usize = 64;

// WASI errno values (preview 1).
const SUCCESS: i32 = 0;
const E_BADF: i32 = 8;
const E_FAULT: i32 = 21;
const E_INVAL: i32 = 28;
const E_IO: i32 = 29;
const E_MFILE: i32 = 33;
const E_NOTCAPABLE: i32 = 76;

/// A directory a stage's config grants its module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Grant {
    pub dir: PathBuf,
    /// Sinks read the scan directory and never write it; per-scan stages may write files.
    pub writable: bool,
}

/// A module's view of its grant: the directory's descriptor and the files it opened.
pub struct Fs {
    root: OwnedFd,
    name: String,
    writable: bool,
    files: HashMap<u32, File>,
    next: u32,
}

impl Fs {
    /// Open the granted directory (it must exist and be a directory).
    pub fn open(g: &Grant) -> Result<Self, String> {
        let dir = File::open(&g.dir).map_err(|e| {
            format!(
                "the granted directory {} cannot be opened ({e})",
                g.dir.display()
            )
        })?;
        if !dir.metadata().map(|m| m.is_dir()).unwrap_or(false) {
            return Err(format!("the grant {} is not a directory", g.dir.display()));
        }
        Ok(Self {
            root: OwnedFd::from(dir),
            name: ".".into(),
            writable: g.writable,
            files: HashMap::new(),
            next: DIR_FD + 1,
        })
    }

    /// Open `path` beneath the granted directory; the kernel refuses any way out of it.
    fn open_beneath(
        &self,
        path: &str,
        write: bool,
        create: bool,
        trunc: bool,
    ) -> Result<File, i32> {
        if write && !self.writable {
            return Err(E_NOTCAPABLE);
        }
        let mut flags = libc::O_NOCTTY;
        flags |= if write { libc::O_RDWR } else { libc::O_RDONLY };
        if create {
            flags |= libc::O_CREAT;
        }
        if trunc {
            flags |= libc::O_TRUNC;
        }
        if path.as_bytes().contains(&0) {
            return Err(E_INVAL);
        }
        let file = open_beneath(
            self.root.as_fd(),
            std::path::Path::new(path),
            flags,
            if create { 0o644 } else { 0 },
            Links::Inside,
        )
        .map_err(errno)?;
        if file.metadata().map(|m| m.is_dir()).unwrap_or(false) {
            return Err(31); // EISDIR: only files are opened
        }
        Ok(file)
    }
}

/// WASI's errno for an OS error.
fn errno(e: std::io::Error) -> i32 {
    match e.raw_os_error() {
        Some(libc::ENOENT) => 44,
        Some(libc::EACCES) | Some(libc::EPERM) => 2,
        Some(libc::EXDEV) => E_NOTCAPABLE, // RESOLVE_BENEATH: the path leaves the grant
        Some(libc::ELOOP) => 32,
        Some(libc::EISDIR) => 31,
        Some(libc::ENOTDIR) => 54,
        Some(libc::EEXIST) => 20,
        Some(libc::ENAMETOOLONG) => 37,
        Some(libc::EROFS) => 69,
        _ => E_IO,
    }
}

/// The host state a granted module's functions reach.
pub trait HasFs {
    fn fs(&mut self) -> Option<&mut Fs>;
    /// Where a line the module writes to stdout or stderr goes (the log).
    fn plugin_name(&self) -> &str;
}

fn memory<T>(caller: &mut Caller<'_, T>) -> Option<wasmtime::Memory> {
    match caller.get_export("memory") {
        Some(Extern::Memory(m)) => Some(m),
        _ => None,
    }
}

fn range(mem: &[u8], ptr: i32, len: usize) -> Option<std::ops::Range<usize>> {
    let start = ptr as u32 as usize;
    let end = start.checked_add(len)?;
    (end <= mem.len()).then_some(start..end)
}

fn u32_at(mem: &[u8], ptr: usize) -> u32 {
    u32::from_le_bytes(mem[ptr..ptr + 4].try_into().unwrap())
}

/// The (ptr, len) pairs of an iovec array, checked to lie in memory.
fn iovecs(mem: &[u8], iovs: i32, n: i32) -> Option<Vec<std::ops::Range<usize>>> {
    let list = range(mem, iovs, (n as u32 as usize).checked_mul(8)?)?;
    (0..n as usize)
        .map(|i| {
            let at = list.start + 8 * i;
            range(mem, u32_at(mem, at) as i32, u32_at(mem, at + 4) as usize)
        })
        .collect()
}

/// Every host call starts the same way: the module's memory and the host state, borrowed
/// together (wasmtime's `data_and_store_mut`); `f` gets both, or the call answers EFAULT
/// when the module exports no memory.
fn with_mem<T: HasFs>(c: &mut Caller<'_, T>, f: impl FnOnce(&mut [u8], &mut T) -> i32) -> i32 {
    let Some(m) = memory(c) else {
        return E_FAULT;
    };
    let (mem, host) = m.data_and_store_mut(c);
    f(mem, host)
}

/// [`with_mem`] with the grant: `no_grant` is the answer for a module given none.
fn with_fs<T: HasFs>(
    c: &mut Caller<'_, T>,
    no_grant: i32,
    f: impl FnOnce(&mut [u8], &mut Fs) -> i32,
) -> i32 {
    with_mem(c, |mem, host| match host.fs() {
        Some(fs) => f(mem, fs),
        None => no_grant,
    })
}

/// [`with_fs`] with the file `fd` names (EBADF for no grant or no such file).
fn with_file<T: HasFs>(
    c: &mut Caller<'_, T>,
    fd: i32,
    f: impl FnOnce(&mut [u8], &mut File) -> i32,
) -> i32 {
    with_fs(c, E_BADF, |mem, fs| match fs.files.get_mut(&(fd as u32)) {
        Some(file) => f(mem, file),
        None => E_BADF,
    })
}

/// Define the [`PROVIDED`] functions in `linker`.
pub fn define<T: HasFs + 'static>(linker: &mut Linker<T>) -> wasmtime::Result<()> {
    linker.func_wrap(
        MODULE,
        "fd_prestat_get",
        |mut c: Caller<'_, T>, fd: i32, buf: i32| -> i32 {
            with_fs(&mut c, E_BADF, |mem, fs| {
                if fd as u32 != DIR_FD {
                    return E_BADF;
                }
                let Some(r) = range(mem, buf, 8) else {
                    return E_FAULT;
                };
                mem[r.start..r.start + 4].copy_from_slice(&0u32.to_le_bytes());
                mem[r.start + 4..r.end].copy_from_slice(&(fs.name.len() as u32).to_le_bytes());
                SUCCESS
            })
        },
    )?;
    linker.func_wrap(
        MODULE,
        "fd_prestat_dir_name",
        |mut c: Caller<'_, T>, fd: i32, ptr: i32, len: i32| -> i32 {
            with_fs(&mut c, E_BADF, |mem, fs| {
                if fd as u32 != DIR_FD {
                    return E_BADF;
                }
                let name = fs.name.as_bytes();
                if (len as u32 as usize) < name.len() {
                    return E_INVAL;
                }
                let Some(r) = range(mem, ptr, name.len()) else {
                    return E_FAULT;
                };
                mem[r].copy_from_slice(name);
                SUCCESS
            })
        },
    )?;
    linker.func_wrap(
        MODULE,
        "path_open",
        |mut c: Caller<'_, T>,
         fd: i32,
         _dirflags: i32,
         path: i32,
         path_len: i32,
         oflags: i32,
         rights: i64,
         _inheriting: i64,
         fdflags: i32,
         opened: i32|
         -> i32 {
            with_fs(&mut c, E_NOTCAPABLE, |mem, fs| {
                if fd as u32 != DIR_FD {
                    return E_BADF;
                }
                let Some(r) = range(mem, path, path_len as u32 as usize) else {
                    return E_FAULT;
                };
                let Ok(p) = std::str::from_utf8(&mem[r]) else {
                    return E_INVAL;
                };
                let (create, directory, trunc) =
                    (oflags & 1 != 0, oflags & 2 != 0, oflags & 8 != 0);
                if directory {
                    return E_NOTCAPABLE; // files only: the grant is one flat directory to read
                }
                // fd_write right (bit 6), or an open that creates, truncates or appends.
                let write = rights & (1 << 6) != 0 || create || trunc || fdflags & 1 != 0;
                if fs.files.len() >= MAX_OPEN {
                    return E_MFILE;
                }
                let file = match fs.open_beneath(p, write, create, trunc) {
                    Ok(f) => f,
                    Err(e) => return e,
                };
                let Some(out) = range(mem, opened, 4) else {
                    return E_FAULT;
                };
                let n = fs.next;
                fs.next += 1;
                fs.files.insert(n, file);
                mem[out].copy_from_slice(&n.to_le_bytes());
                SUCCESS
            })
        },
    )?;
    linker.func_wrap(
        MODULE,
        "fd_read",
        |mut c: Caller<'_, T>, fd: i32, iovs: i32, n: i32, nread: i32| -> i32 {
            with_file(&mut c, fd, |mem, file| {
                let Some(bufs) = iovecs(mem, iovs, n) else {
                    return E_FAULT;
                };
                let Some(out) = range(mem, nread, 4) else {
                    return E_FAULT;
                };
                let mut total = 0u32;
                for b in bufs {
                    let want = b.len();
                    match file.read(&mut mem[b]) {
                        Ok(got) => {
                            total += got as u32;
                            if got < want {
                                break;
                            }
                        }
                        Err(e) => return errno(e),
                    }
                }
                mem[out].copy_from_slice(&total.to_le_bytes());
                SUCCESS
            })
        },
    )?;
    linker.func_wrap(
        MODULE,
        "fd_write",
        |mut c: Caller<'_, T>, fd: i32, iovs: i32, n: i32, nwritten: i32| -> i32 {
            with_mem(&mut c, |mem, host| {
                let Some(bufs) = iovecs(mem, iovs, n) else {
                    return E_FAULT;
                };
                let Some(out) = range(mem, nwritten, 4) else {
                    return E_FAULT;
                };
                let mut total = 0u32;
                if fd == 1 || fd == 2 {
                    // stdout and stderr: the module's diagnostics, to the log.
                    let text: Vec<u8> = bufs.iter().flat_map(|b| mem[b.clone()].to_vec()).collect();
                    for line in String::from_utf8_lossy(&text).lines() {
                        tracing::warn!(plugin = %host.plugin_name(), "{line}");
                    }
                    total = text.len() as u32;
                } else {
                    let Some(fs) = host.fs() else { return E_BADF };
                    let Some(file) = fs.files.get_mut(&(fd as u32)) else {
                        return E_BADF;
                    };
                    for b in bufs {
                        if let Err(e) = file.write_all(&mem[b.clone()]) {
                            return errno(e);
                        }
                        total += b.len() as u32;
                    }
                }
                mem[out].copy_from_slice(&total.to_le_bytes());
                SUCCESS
            })
        },
    )?;
    linker.func_wrap(
        MODULE,
        "fd_seek",
        |mut c: Caller<'_, T>, fd: i32, offset: i64, whence: i32, newoffset: i32| -> i32 {
            with_file(&mut c, fd, |mem, file| {
                let to = match whence {
                    0 if offset >= 0 => SeekFrom::Start(offset as u64),
                    1 => SeekFrom::Current(offset),
                    2 => SeekFrom::End(offset),
                    _ => return E_INVAL,
                };
                let Some(out) = range(mem, newoffset, 8) else {
                    return E_FAULT;
                };
                match file.seek(to) {
                    Ok(p) => {
                        mem[out].copy_from_slice(&p.to_le_bytes());
                        SUCCESS
                    }
                    Err(e) => errno(e),
                }
            })
        },
    )?;
    linker.func_wrap(
        MODULE,
        "fd_filestat_get",
        |mut c: Caller<'_, T>, fd: i32, buf: i32| -> i32 {
            with_file(&mut c, fd, |mem, file| {
                let Some(r) = range(mem, buf, 64) else {
                    return E_FAULT;
                };
                let meta = match file.metadata() {
                    Ok(m) => m,
                    Err(e) => return errno(e),
                };
                let b = &mut mem[r];
                b.fill(0);
                b[16] = 4; // filetype: regular file
                b[24..32].copy_from_slice(&1u64.to_le_bytes()); // nlink
                b[32..40].copy_from_slice(&meta.len().to_le_bytes());
                SUCCESS
            })
        },
    )?;
    linker.func_wrap(MODULE, "fd_close", |mut c: Caller<'_, T>, fd: i32| -> i32 {
        let Some(fs) = c.data_mut().fs() else {
            return E_BADF;
        };
        match fs.files.remove(&(fd as u32)) {
            Some(_) => SUCCESS,
            None => E_BADF,
        }
    })?;
    Ok(())
}
