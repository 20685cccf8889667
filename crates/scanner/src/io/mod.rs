//! File formats and renderings: PLY point clouds, PNG height maps (meshes: `footscan_geom::mesh`); the atomic file writes
//! (from `footscan-util`) re-exported for the modules that write them.

pub(crate) mod heightmap;
mod ply;

pub use heightmap::{render_heightmap, HeightMapImage, HeightMapLabel};
pub use ply::write_ply_points;

pub use footscan_util::{write_atomic, write_atomic_with};

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

/// `image` as a PNG file, written atomically.
pub fn write_png_atomic(path: &Path, image: &image::RgbImage) -> std::io::Result<()> {
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(std::io::Error::other)?;
    write_atomic(path, &png)
}
