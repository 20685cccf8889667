//! `lasts.toml`: what the files of a shop's collection of lasts do not say themselves.
//!
//! A last in millimetres or metres is read as it is; one in a modelling tool's units
//! (Last_Flat_RoundTip's longest side is 1.9 units) needs its length, and a collection may
//! hold both. A `lasts.toml` beside the files gives, per file, its units or the length (mm)
//! of its longest side, so every last command that reads the collection (`footscan last
//! choose`, `footscan last customize --stock`, footscand's ranking and last jobs) reads each
//! file the same way:
//!
//! ```toml
//! ["Last_Flat_RoundTip.stl"]
//! length_mm = 265
//!
//! ["LastScan_Default.stl"]
//! units = "m"
//! ```

use footscan_geom::mesh::Units;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The collection file's name, in the stock directory.
pub const COLLECTION_FILE: &str = "lasts.toml";

/// One file's entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    units: Option<String>,
    length_mm: Option<f64>,
}

/// How a collection's file is read: its units, or the length of its longest side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReadAs {
    pub units: Units,
    pub length_mm: Option<f64>,
}

/// A collection file that cannot be used, naming it and what would be valid.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {why}")]
pub struct CollectionError {
    pub path: PathBuf,
    pub why: String,
}

/// The entries of a stock directory's `lasts.toml` (none without one).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Collection {
    files: BTreeMap<String, ReadAs>,
}

impl Collection {
    /// Read `dir/lasts.toml`. Every entry must name a file present in `dir`, and give units
    /// (mm, cm, m, auto) or a length of 100 to 400 mm, not both.
    pub fn load(dir: &Path) -> Result<Collection, CollectionError> {
        let path = dir.join(COLLECTION_FILE);
        let err = |why: String| CollectionError {
            path: path.clone(),
            why,
        };
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Collection::default()),
            Err(e) => return Err(err(e.to_string())),
        };
        let raw: BTreeMap<String, Entry> = toml::from_str(&text).map_err(|e| {
            err(format!(
                "not a collection file: {}; each table is a last's file name with `units` \
                 (mm, cm, m) or `length_mm` (its longest side)",
                e.message()
            ))
        })?;
        let mut files = BTreeMap::new();
        for (name, e) in raw {
            if !dir.join(&name).is_file() {
                return Err(err(format!(
                    "[\"{name}\"]: no such file in {}",
                    dir.display()
                )));
            }
            let read = match (e.units, e.length_mm) {
                (Some(_), Some(_)) => {
                    return Err(err(format!(
                        "[\"{name}\"]: units or length_mm, not both (a length sets the scale)"
                    )))
                }
                (None, None) => {
                    return Err(err(format!(
                        "[\"{name}\"]: give units (mm, cm, m) or length_mm"
                    )))
                }
                (Some(u), None) => ReadAs {
                    units: u.parse().map_err(|e| err(format!("[\"{name}\"]: {e}")))?,
                    length_mm: None,
                },
                (None, Some(l)) if l.is_finite() && (100.0..=400.0).contains(&l) => ReadAs {
                    units: Units::Auto,
                    length_mm: Some(l),
                },
                (None, Some(l)) => {
                    return Err(err(format!(
                        "[\"{name}\"]: length_mm = {l}: a last's longest side is 100 to 400 mm"
                    )))
                }
            };
            files.insert(name, read);
        }
        Ok(Collection { files })
    }

    /// How `name` is read: its entry, else `default` (the command's own options).
    pub fn read_as(&self, name: &str, default: ReadAs) -> ReadAs {
        self.files.get(name).copied().unwrap_or(default)
    }

    /// How the last file at `path` is read: the entry of the `lasts.toml` beside it, else
    /// `default`.
    pub fn for_file(path: &Path, default: ReadAs) -> Result<ReadAs, CollectionError> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(Collection::load(dir)?.read_as(&name, default))
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_are_checked_and_used() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path();
        std::fs::write(dir.join("a.stl"), b"solid").unwrap();
        std::fs::write(dir.join("b.stl"), b"solid").unwrap();
        let default = ReadAs {
            units: Units::Auto,
            length_mm: None,
        };
        assert!(Collection::load(dir).unwrap().is_empty());
        std::fs::write(
            dir.join(COLLECTION_FILE),
            "[\"a.stl\"]\nlength_mm = 265\n[\"b.stl\"]\nunits = \"m\"\n",
        )
        .unwrap();
        let c = Collection::load(dir).unwrap();
        assert_eq!(c.read_as("a.stl", default).length_mm, Some(265.0));
        assert_eq!(c.read_as("b.stl", default).units, Units::M);
        assert_eq!(c.read_as("c.stl", default), default);
        assert_eq!(
            Collection::for_file(&dir.join("a.stl"), default)
                .unwrap()
                .length_mm,
            Some(265.0)
        );
        for (text, words) in [
            ("[\"z.stl\"]\nunits = \"mm\"\n", "no such file"),
            ("[\"a.stl\"]\nunits = \"mm\"\nlength_mm = 250\n", "not both"),
            ("[\"a.stl\"]\nlength_mm = 2.5\n", "100 to 400 mm"),
            ("[\"a.stl\"]\nunits = \"inch\"\n", "valid: mm, cm, m, auto"),
            ("[\"a.stl\"]\nsize = 3\n", "not a collection file"),
        ] {
            std::fs::write(dir.join(COLLECTION_FILE), text).unwrap();
            let e = Collection::load(dir).unwrap_err().to_string();
            assert!(
                e.contains(COLLECTION_FILE) && e.contains(words),
                "{text}: {e}"
            );
        }
    }
}
