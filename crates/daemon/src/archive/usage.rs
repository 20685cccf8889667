//! Where an archive's disk goes (`footscand archive du`): by kind of file across the scans,
//! by year of the scans, and the rest (index, visits, calibrations). Read-only and without
//! the archive lock, so it runs beside a running daemon; sizes are the blocks allocated
//! (what the disk loses), with the files' lengths beside them.

use super::{io_at, ArchiveError, ScanId, INDEX, TMP_PREFIX};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Bytes on disk (allocated blocks) and the files' lengths.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct Size {
    pub files: u64,
    pub disk: u64,
    pub bytes: u64,
}

impl Size {
    fn add_file(&mut self, m: &std::fs::Metadata) {
        use std::os::unix::fs::MetadataExt;
        self.files += 1;
        self.disk += m.blocks() * 512;
        self.bytes += m.len();
    }
    fn add(&mut self, o: &Size) {
        self.files += o.files;
        self.disk += o.disk;
        self.bytes += o.bytes;
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Usage {
    /// Finished scan directories.
    pub scans: u64,
    pub total: Size,
    /// By file name within the scans (grid.bin, model.stl, ...); a file in a subdirectory
    /// (a last, an insole) counts under its directory's name with a trailing `/`.
    pub by_kind: BTreeMap<String, Size>,
    /// By the year the scan started (the id's), with the scan count.
    pub by_year: BTreeMap<String, (u64, Size)>,
    /// Everything outside the scan directories: the index, visits, calibrations, scans
    /// still being written.
    pub other: BTreeMap<String, Size>,
}

/// Add every file under `p` (not following symlinks) into `size`.
fn walk(p: &Path, size: &mut Size) -> std::io::Result<()> {
    let m = p.symlink_metadata()?;
    if m.is_dir() {
        for e in std::fs::read_dir(p)? {
            walk(&e?.path(), size)?;
        }
    } else {
        size.add_file(&m);
    }
    Ok(())
}

/// What the archive at `root` holds, read from its directories.
pub fn usage(root: &Path) -> Result<Usage, ArchiveError> {
    let mut u = Usage::default();
    for e in std::fs::read_dir(root).map_err(io_at(root))? {
        let e = e.map_err(io_at(root))?;
        let name = e.file_name().to_string_lossy().into_owned();
        let path = e.path();
        let is_dir = e.file_type().is_ok_and(|t| t.is_dir());
        match ScanId::parse(&name) {
            Ok(_) if is_dir => {
                u.scans += 1;
                let mut scan = Size::default();
                for f in std::fs::read_dir(&path).map_err(io_at(&path))? {
                    let f = f.map_err(io_at(&path))?;
                    let fname = f.file_name().to_string_lossy().into_owned();
                    let mut s = Size::default();
                    walk(&f.path(), &mut s).map_err(io_at(&f.path()))?;
                    let kind = if f.file_type().is_ok_and(|t| t.is_dir()) {
                        format!("{fname}/")
                    } else {
                        fname
                    };
                    u.by_kind.entry(kind).or_default().add(&s);
                    scan.add(&s);
                }
                let year = u.by_year.entry(name[..4].to_string()).or_default();
                year.0 += 1;
                year.1.add(&scan);
                u.total.add(&scan);
            }
            _ => {
                let key = if name.starts_with(TMP_PREFIX) {
                    "scans being written (.tmp-*)".to_string()
                } else if name.starts_with(INDEX) {
                    INDEX.to_string()
                } else {
                    name
                };
                let mut s = Size::default();
                walk(&path, &mut s).map_err(io_at(&path))?;
                u.other.entry(key).or_default().add(&s);
                u.total.add(&s);
            }
        }
    }
    Ok(u)
}

fn mb(b: u64) -> String {
    format!("{:.1}", b as f64 / 1e6)
}

impl Usage {
    /// The report as a table for a terminal.
    pub fn table(&self, root: &Path) -> String {
        let mut out = format!(
            "{}: {} scans, {} MB on disk ({} MB in files), {} MB a scan on average\n",
            root.display(),
            self.scans,
            mb(self.total.disk),
            mb(self.total.bytes),
            mb(self
                .by_kind
                .values()
                .map(|s| s.disk)
                .sum::<u64>()
                .checked_div(self.scans)
                .unwrap_or(0))
        );
        let mut kinds: Vec<_> = self.by_kind.iter().collect();
        kinds.sort_by(|a, b| b.1.disk.cmp(&a.1.disk).then(a.0.cmp(b.0)));
        out += "\nby file (across the scans)      files      MB on disk   share\n";
        for (k, s) in kinds {
            out += &format!(
                "  {k:<28} {:>8} {:>15} {:>6.1} %\n",
                s.files,
                mb(s.disk),
                100.0 * s.disk as f64 / self.total.disk.max(1) as f64
            );
        }
        out += "\nby year of the scan             scans      MB on disk\n";
        for (y, (n, s)) in &self.by_year {
            out += &format!("  {y:<28} {n:>8} {:>15}\n", mb(s.disk));
        }
        if !self.other.is_empty() {
            out += "\noutside the scans               files      MB on disk\n";
            for (k, s) in &self.other {
                out += &format!("  {k:<28} {:>8} {:>15}\n", s.files, mb(s.disk));
            }
        }
        out
    }
}
