//! File formats and renderings: PLY point clouds, PNG height maps, atomic file writes.

mod heightmap;
mod mesh;
mod plantar;
mod ply;

pub use heightmap::{render_heightmap, HeightMapImage, HeightMapLabel};
pub use mesh::{write_obj, write_ply_mesh, write_stl};
pub use plantar::{render_plantar, PlantarImage};
pub use ply::write_ply_points;

use std::io::Write;
use std::path::Path;

/// What a file a scan writes into its directory (an artifact) may be called, in words for
/// error messages. One rule for the stages that write the files and the archive that lists and
/// serves them, so no stage can write a file the archive would hide.
pub const ARTIFACT_NAME_RULE: &str = "1-64 characters of A-Z a-z 0-9 . _ - not starting with a dot";

/// Whether `name` follows [`ARTIFACT_NAME_RULE`]: a plain file name (no separator, no `..`),
/// not hidden, nothing a URL or a shell would have to quote.
pub fn is_artifact_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'))
}

/// Write `bytes` to `path` so a reader sees the old file or the whole new one, never a part:
/// a temporary file in the same directory, fsync, rename, then fsync of the directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// `image` as a PNG file, written atomically.
pub fn write_png_atomic(path: &Path, image: &image::RgbImage) -> std::io::Result<()> {
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(std::io::Error::other)?;
    write_atomic(path, &png)
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
