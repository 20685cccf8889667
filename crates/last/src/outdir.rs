//! An output directory written whole or not at all.

use std::path::{Path, PathBuf};

/// Writes an output directory through `write` into a fresh sibling (`.NAME.tmpPID`), then puts
/// it in `out`'s place: an earlier `out` is moved aside and removed only once the new one is
/// there, so `out` holds either every new file or what it held before. An error names the
/// path it is about and why; nothing is left behind.
pub fn write_dir_atomic<T>(
    out: &Path,
    write: impl FnOnce(&Path) -> Result<T, (PathBuf, String)>,
) -> Result<T, (PathBuf, String)> {
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = out
        .file_name()
        .ok_or_else(|| (out.to_path_buf(), "not a directory path".to_string()))?
        .to_string_lossy()
        .to_string();
    let pid = std::process::id();
    let tmp = parent.join(format!(".{name}.tmp{pid}"));
    let _ = std::fs::remove_dir_all(&tmp);
    let result = write(&tmp).and_then(|v| {
        let old = parent.join(format!(".{name}.old{pid}"));
        let had = out.exists();
        if had {
            std::fs::rename(out, &old).map_err(|e| (out.to_path_buf(), e.to_string()))?;
        }
        if let Err(e) = std::fs::rename(&tmp, out) {
            if had {
                let _ = std::fs::rename(&old, out);
            }
            return Err((out.to_path_buf(), e.to_string()));
        }
        if had {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(v)
    });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}
