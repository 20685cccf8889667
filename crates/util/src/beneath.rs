//! Opening a file beneath a directory so that no path component, however it was swapped,
//! leads out of it: the plugins' WASI grant and every file the daemon serves from its archive
//! go through this one copy.
//!
//! The kernel does the confinement (openat2 with RESOLVE_BENEATH), so `..`, absolute paths
//! and symlinks out of the directory fail in one system call, with no window between a check
//! and the open. Where openat2 is missing (Linux before 5.6, or a seccomp filter that answers
//! ENOSYS or EPERM), a path that must not cross any symlink is walked one component at a time with
//! O_NOFOLLOW, which confines as strictly; a path that may cross symlinks inside the directory
//! is then refused, since no walk by hand can tell where a symlink's target lies without the
//! race openat2 exists to close.

use std::ffi::CString;
use std::fs::File;
use std::io;
use std::os::fd::{AsRawFd, BorrowedFd, FromRawFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::path::{Component, Path};

/// Which symlinks a path beneath the directory may cross.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Links {
    /// Symlinks that stay beneath the directory are followed (a plugin's own layout).
    Inside,
    /// No symlink at all, at any component (what the daemon serves: the archive's own files).
    None,
}

/// Open `path` (relative) beneath the directory `dir` with the open(2) `flags` (O_CLOEXEC is
/// always added) and `mode` for a created file. ENOENT, EXDEV (the path leaves `dir`), ELOOP
/// (a symlink where [`Links::None`] forbids one) come back as the OS error.
pub fn open_beneath(
    dir: BorrowedFd<'_>,
    path: &Path,
    flags: libc::c_int,
    mode: libc::mode_t,
    links: Links,
) -> io::Result<File> {
    let flags = flags | libc::O_CLOEXEC;
    let mut resolve = libc::RESOLVE_BENEATH | libc::RESOLVE_NO_MAGICLINKS;
    if links == Links::None {
        resolve |= libc::RESOLVE_NO_SYMLINKS;
    }
    match openat2(dir, path, flags, mode, resolve) {
        // ENOSYS: a kernel before 5.6; EPERM: a seccomp filter that does not know openat2
        // (a genuine EPERM comes back from the walk as well).
        Err(e)
            if matches!(e.raw_os_error(), Some(libc::ENOSYS) | Some(libc::EPERM))
                && links == Links::None =>
        {
            walk_nofollow(dir, path, flags, mode)
        }
        r => r,
    }
}

fn cstring(name: &[u8]) -> io::Result<CString> {
    CString::new(name).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "a path with a NUL byte cannot name a file",
        )
    })
}

fn openat2(
    dir: BorrowedFd<'_>,
    path: &Path,
    flags: libc::c_int,
    mode: libc::mode_t,
    resolve: u64,
) -> io::Result<File> {
    #[repr(C)]
    struct OpenHow {
        flags: u64,
        mode: u64,
        resolve: u64,
    }
    let how = OpenHow {
        flags: flags as u64,
        mode: mode as u64,
        resolve,
    };
    let c = cstring(path.as_os_str().as_bytes())?;
    // SAFETY: openat2 reads the NUL-terminated path and `how` (of the size given) and
    // returns a new descriptor, owned here at once, or -1.
    let fd = unsafe {
        libc::syscall(
            libc::SYS_openat2,
            dir.as_raw_fd(),
            c.as_ptr(),
            &how as *const OpenHow,
            std::mem::size_of::<OpenHow>(),
        )
    };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: the kernel just returned this descriptor and nothing else owns it.
    Ok(File::from(unsafe { OwnedFd::from_raw_fd(fd as i32) }))
}

/// The fallback for [`Links::None`]: each component opened with O_NOFOLLOW relative to the
/// directory opened before it; only plain names (no `..`, no root) are accepted.
fn walk_nofollow(
    dir: BorrowedFd<'_>,
    path: &Path,
    flags: libc::c_int,
    mode: libc::mode_t,
) -> io::Result<File> {
    let parts: Vec<&std::ffi::OsStr> = path
        .components()
        .filter(|c| *c != Component::CurDir)
        .map(|c| match c {
            Component::Normal(n) => Ok(n),
            _ => Err(io::Error::from_raw_os_error(libc::EXDEV)),
        })
        .collect::<io::Result<_>>()?;
    let Some((last, dirs)) = parts.split_last() else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "an empty path names no file",
        ));
    };
    let at = |d: BorrowedFd<'_>, name: &std::ffi::OsStr, flags: libc::c_int| {
        let c = cstring(name.as_bytes())?;
        // SAFETY: a valid directory descriptor and a NUL-terminated name; the new descriptor
        // is owned at once.
        let fd = unsafe {
            libc::openat(
                d.as_raw_fd(),
                c.as_ptr(),
                flags | libc::O_NOFOLLOW | libc::O_CLOEXEC,
                mode as libc::c_uint,
            )
        };
        if fd < 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: `fd` was just opened and is owned by nobody else.
        Ok(unsafe { OwnedFd::from_raw_fd(fd) })
    };
    let mut held: Option<OwnedFd> = None;
    for d in dirs {
        let from = held.as_ref().map_or(dir, |h| {
            use std::os::fd::AsFd;
            h.as_fd()
        });
        held = Some(at(from, d, libc::O_RDONLY | libc::O_DIRECTORY)?);
    }
    let from = held.as_ref().map_or(dir, |h| {
        use std::os::fd::AsFd;
        h.as_fd()
    });
    Ok(File::from(at(from, last, flags)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::fd::AsFd;

    fn setup() -> (tempfile::TempDir, File) {
        let t = tempfile::tempdir().unwrap();
        let root = t.path().join("root");
        std::fs::create_dir_all(root.join("a/b")).unwrap();
        std::fs::write(root.join("a/b/f.txt"), b"inside").unwrap();
        std::fs::write(t.path().join("secret.txt"), b"outside").unwrap();
        std::os::unix::fs::symlink(t.path(), root.join("out")).unwrap();
        std::os::unix::fs::symlink("b", root.join("a/inner")).unwrap();
        std::os::unix::fs::symlink("../../../secret.txt", root.join("a/b/leak.txt")).unwrap();
        let dir = File::open(&root).unwrap();
        (t, dir)
    }

    fn read(dir: &File, p: &str, links: Links, nofollow_walk: bool) -> io::Result<String> {
        use std::io::Read;
        let mut f = if nofollow_walk {
            walk_nofollow(dir.as_fd(), Path::new(p), libc::O_RDONLY, 0)?
        } else {
            open_beneath(dir.as_fd(), Path::new(p), libc::O_RDONLY, 0, links)?
        };
        let mut s = String::new();
        f.read_to_string(&mut s)?;
        Ok(s)
    }

    #[test]
    fn nothing_outside_the_directory_opens() {
        let (_t, dir) = setup();
        for walk in [false, true] {
            assert_eq!(
                read(&dir, "a/b/f.txt", Links::None, walk).unwrap(),
                "inside"
            );
            for escape in [
                "out/secret.txt",
                "a/b/leak.txt",
                "../secret.txt",
                "a/../../secret.txt",
                "/etc/hostname",
                "a/inner/f.txt",
            ] {
                assert!(
                    read(&dir, escape, Links::None, walk).is_err(),
                    "{escape} opened (walk {walk})"
                );
            }
        }
        // Symlinks that stay inside are followed when allowed, and only those.
        assert_eq!(
            read(&dir, "a/inner/f.txt", Links::Inside, false).unwrap(),
            "inside"
        );
        for escape in ["out/secret.txt", "a/b/leak.txt", "../secret.txt"] {
            let e = read(&dir, escape, Links::Inside, false).unwrap_err();
            assert_eq!(e.raw_os_error(), Some(libc::EXDEV), "{escape}: {e}");
        }
    }
}
