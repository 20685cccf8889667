//! Small general helpers that the scanner library, the last stages and the daemon share: one
//! copy of each, below every footscan crate, so no crate depends on another for a helper.

use std::io::Write;
use std::path::Path;

pub mod beneath;
pub mod priority;

/// The current UTC time as RFC 3339 (seconds precision), for records in files.
pub fn now_rfc3339() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()
}

/// Write `bytes` to `path` so a reader sees the old file or the whole new one, never a part:
/// a temporary file in the same directory, fsync, rename, then fsync of the directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Like [`write_atomic`], with the content produced by `fill` into a buffered writer.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| std::io::Error::other(format!("{}: not a file path", path.display())))?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)?;
        std::fs::File::open(dir)?.sync_all()
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// The names of the files a scan leaves in its directory. They are written here, below every
/// crate that reads a scan directory, because the fleet crate (which depends on no other
/// footscan crate) stores them too; the scanner's `ScanDir` takes its names from here.
pub mod scan_files {
    /// The run's summary, written for failed scans too.
    pub const SUMMARY: &str = "scan.json";
    /// The foot's measurements.
    pub const MEASUREMENTS: &str = "measurements.json";
    /// The plantar picture beside the measurements.
    pub const PLANTAR: &str = "plantar.png";
    /// The scan grid.
    pub const GRID: &str = "grid.bin";
    /// The point cloud.
    pub const POINTS: &str = "points.ply";
    /// The height-map picture.
    pub const HEIGHTMAP: &str = "heightmap.png";
    /// The simulator's ground truth of the foot, when the scan was simulated.
    pub const TRUTH: &str = "truth.json";
    /// The daemon archive's record of the scan.
    pub const RECORD: &str = "record.json";
    /// The calibration the scan was made with, copied beside it.
    pub const CALIBRATION: &str = "calibration.toml";
    /// The plantar model as a closed mesh (STL), from the `model.bezier` stage.
    pub const MODEL_STL: &str = "model.stl";
    /// The plantar model as a B-spline solid (STEP AP214).
    pub const MODEL_STEP: &str = "model.step";
    /// The plantar model as a B-spline solid (IGES 5.3), `footscan model --format iges`.
    pub const MODEL_IGES: &str = "model.igs";
    /// The plantar model for the 3D view (glTF binary).
    pub const MODEL_GLB: &str = "model.glb";
    /// The plantar model as PLY and OBJ meshes, `footscan model --format ply|obj`.
    pub const MODEL_PLY: &str = "model.ply";
    pub const MODEL_OBJ: &str = "model.obj";
}

/// An error and its causes on one line, `outer: cause: root`, for the edges that turn an
/// error into text (an API answer, a record's reason, a log line). Library errors name what
/// failed and leave the cause to their `source()`, so each cause is printed here exactly once.
pub struct Chain<'a>(pub &'a (dyn std::error::Error + 'static));

impl std::fmt::Display for Chain<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)?;
        let mut cause = self.0.source();
        while let Some(c) = cause {
            write!(f, ": {c}")?;
            cause = c.source();
        }
        Ok(())
    }
}

/// [`Chain`] as a String.
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    Chain(e).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_prints_each_cause_once() {
        #[derive(Debug)]
        struct Outer(std::io::Error);
        impl std::fmt::Display for Outer {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("reading scan.json")
            }
        }
        impl std::error::Error for Outer {
            fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
                Some(&self.0)
            }
        }
        let e = Outer(std::io::Error::other("disk full"));
        assert_eq!(chain(&e), "reading scan.json: disk full");
        assert_eq!(chain(&std::io::Error::other("alone")), "alone");
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let e = write_atomic(&dir.path().join("missing/x"), b"").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
    }

    #[test]
    fn now_is_rfc3339_utc_seconds() {
        let t = now_rfc3339();
        assert_eq!(t.len(), "2026-01-01T00:00:00Z".len(), "{t}");
        assert!(t.ends_with('Z') && t.as_bytes()[10] == b'T', "{t}");
        assert!(humantime::parse_rfc3339(&t).is_ok(), "{t}");
    }
}
