//! A scan's directory as one type: the names of the files a scan leaves there, written once,
//! and their loaders. The CLI, the stages, the report, the last stages and the daemon's
//! archive all reach a scan's files through it, so a file's name is a constant, not a literal
//! repeated in every reader.

use super::ScanGrid;
use footscan_util::scan_files;
use std::path::{Path, PathBuf};

/// A directory a scan was written to (by `footscan scan` or footscand's archive).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScanDir {
    path: PathBuf,
}

/// Why a file of a scan directory could not be loaded. A missing optional file is not an
/// error: the loaders of optional files return `Ok(None)`.
#[derive(Debug, thiserror::Error)]
pub enum ScanDirError {
    #[error("reading {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: not {what}", path.display())]
    Parse {
        path: PathBuf,
        /// What the file should have held, in words ("valid JSON", "the scanner's measurements").
        what: &'static str,
        #[source]
        source: serde_json::Error,
    },
}

impl ScanDir {
    /// The run's summary (`ScanSummary`), written for failed scans too.
    pub const SUMMARY: &'static str = scan_files::SUMMARY;
    /// The foot's measurements (`measure::Measurements`), from the `measure.foot` stage or
    /// `footscan measure`.
    pub const MEASUREMENTS: &'static str = scan_files::MEASUREMENTS;
    /// The plantar picture beside the measurements.
    pub const PLANTAR: &'static str = scan_files::PLANTAR;
    /// The scan grid ([`ScanGrid`]), from the `sink.grid` stage.
    pub const GRID: &'static str = scan_files::GRID;
    /// The point cloud, from the `sink.ply` stage.
    pub const POINTS: &'static str = scan_files::POINTS;
    /// The height-map picture, from the `sink.heightmap` stage.
    pub const HEIGHTMAP: &'static str = scan_files::HEIGHTMAP;
    /// The simulator's ground truth of the foot, when the scan was simulated.
    pub const TRUTH: &'static str = scan_files::TRUTH;
    /// The daemon archive's record of the scan (subject, side, status, times).
    pub const RECORD: &'static str = scan_files::RECORD;
    /// The calibration the scan was made with, copied beside it.
    pub const CALIBRATION: &'static str = scan_files::CALIBRATION;
    /// The plantar model's files (`model.bezier`, `footscan model`).
    pub const MODEL_STL: &'static str = scan_files::MODEL_STL;
    pub const MODEL_STEP: &'static str = scan_files::MODEL_STEP;
    pub const MODEL_IGES: &'static str = scan_files::MODEL_IGES;
    pub const MODEL_GLB: &'static str = scan_files::MODEL_GLB;
    pub const MODEL_PLY: &'static str = scan_files::MODEL_PLY;
    pub const MODEL_OBJ: &'static str = scan_files::MODEL_OBJ;

    pub fn new(path: impl Into<PathBuf>) -> ScanDir {
        ScanDir { path: path.into() }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The path of the file `name` (one of the constants above, or a stage's own output).
    pub fn file(&self, name: &str) -> PathBuf {
        self.path.join(name)
    }

    pub fn summary_path(&self) -> PathBuf {
        self.file(Self::SUMMARY)
    }

    pub fn measurements_path(&self) -> PathBuf {
        self.file(Self::MEASUREMENTS)
    }

    pub fn plantar_path(&self) -> PathBuf {
        self.file(Self::PLANTAR)
    }

    pub fn grid_path(&self) -> PathBuf {
        self.file(Self::GRID)
    }

    pub fn truth_path(&self) -> PathBuf {
        self.file(Self::TRUTH)
    }

    pub fn record_path(&self) -> PathBuf {
        self.file(Self::RECORD)
    }

    /// The scan grid (grid.bin, or its compact form); its absence is an error, as every
    /// reader needs it.
    pub fn load_grid(&self) -> std::io::Result<ScanGrid> {
        let path = self.grid_path();
        ScanGrid::parse(&self.read_stored(Self::GRID)?, &path)
    }

    /// The original bytes of the file `name`: the file itself when it is there, else, in a
    /// compacted scan (`compact.json`, [`super::stored`]), its stored form decoded and
    /// checked against the manifest's length and SHA-256. NotFound when neither is there;
    /// Unsupported for a file the compaction left to be rebuilt from the grid (points.ply,
    /// model.stl, model.glb), which `crate::compact`'s `ScanDir::read_file` rebuilds.
    pub fn read_stored(&self, name: &str) -> std::io::Result<Vec<u8>> {
        let path = self.file(name);
        match std::fs::read(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let entry = super::stored::Manifest::load(&self.path)?
                    .and_then(|m| m.files.get(name).cloned());
                match entry {
                    Some(entry) => {
                        super::stored::decode(&self.path, name, &entry)?.ok_or_else(|| {
                            std::io::Error::new(
                                std::io::ErrorKind::Unsupported,
                                format!(
                                    "{}: kept to be rebuilt from the grid; read it with \
                                     ScanDir::read_file",
                                    path.display()
                                ),
                            )
                        })
                    }
                    None => Err(e),
                }
            }
            r => r,
        }
    }

    /// The bytes of `name` (or of its stored form, as [`Self::read_stored`]), or None when
    /// the file is not there.
    pub fn read_optional(&self, name: &str) -> Result<Option<Vec<u8>>, ScanDirError> {
        let path = self.file(name);
        match self.read_stored(name) {
            Ok(b) => Ok(Some(b)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(source) => Err(ScanDirError::Read { path, source }),
        }
    }

    /// `name` parsed as `T`, or None when the file is not there; `what` says what the file
    /// should hold, for the error when it does not.
    pub fn load_json<T: serde::de::DeserializeOwned>(
        &self,
        name: &str,
        what: &'static str,
    ) -> Result<Option<T>, ScanDirError> {
        let Some(bytes) = self.read_optional(name)? else {
            return Ok(None);
        };
        serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|source| ScanDirError::Parse {
                path: self.file(name),
                what,
                source,
            })
    }

    /// scan.json, untyped (the report reads a few fields of summaries of any age), or None.
    pub fn load_summary(&self) -> Result<Option<serde_json::Value>, ScanDirError> {
        self.load_json(Self::SUMMARY, "valid JSON")
    }

    /// record.json of the daemon's archive, untyped (it is the daemon's type), or None.
    pub fn load_record(&self) -> Result<Option<serde_json::Value>, ScanDirError> {
        self.load_json(Self::RECORD, "valid JSON")
    }
}

impl From<&Path> for ScanDir {
    fn from(p: &Path) -> ScanDir {
        ScanDir::new(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn optional_files_are_none_and_bad_json_names_the_file() {
        let d = tempfile::tempdir().unwrap();
        let s = ScanDir::new(d.path());
        assert!(s.load_summary().unwrap().is_none());
        std::fs::write(s.summary_path(), b"{ not json").unwrap();
        let e = s.load_summary().unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("scan.json") && text.contains("not valid JSON"),
            "{text}"
        );
        std::fs::write(s.summary_path(), br#"{"status": "ok"}"#).unwrap();
        assert_eq!(s.load_summary().unwrap().unwrap()["status"], "ok");
        let e = s.load_grid().unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
    }
}
