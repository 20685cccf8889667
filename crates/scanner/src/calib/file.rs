use super::bezier_depth::BezierDepth;
use super::{CameraModel, ModelError, Triangulator};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A calibration as saved on disk: the model, how it was obtained, and how good it is.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// `simulator-truth`, `insystem`, `bezier`, `opencv`, ...
    pub method: String,
    /// RFC 3339 UTC time the calibration was made.
    pub date: String,
    pub model: CameraModel,
    /// One standard deviation per fitted parameter, same names as in `model`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub stddev: BTreeMap<String, f64>,
    /// Fit residuals by target (RMS, px or mm as the key says).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub residuals: BTreeMap<String, f64>,
    /// Heights from a Bezier depth network instead of the laser plane (method `bezier`); x and
    /// y still come from `model`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bezier: Option<BezierDepth>,
}

/// Why a calibration's text is refused.
#[derive(Debug, thiserror::Error)]
pub enum ParseError {
    #[error(transparent)]
    Toml(#[from] toml::de::Error),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("bezier: {rows} reference rows and {blocks} blocks for a {height}-row camera")]
    Bezier {
        rows: usize,
        blocks: usize,
        height: u32,
    },
}

#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    #[error("cannot read calibration {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Boxed: TOML's error is large, and this one is rare.
    #[error("calibration {path} is not valid")]
    Parse {
        path: PathBuf,
        source: Box<ParseError>,
    },
    #[error("cannot write calibration {path}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl Calibration {
    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|source| CalibrationError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text).map_err(|e| CalibrationError::Parse {
            path: path.to_owned(),
            source: Box::new(e),
        })
    }

    pub fn parse(text: &str) -> Result<Self, ParseError> {
        let c: Calibration = toml::from_str(text)?;
        c.model.validate()?;
        if let Some(b) = &c.bezier {
            if b.reference_col.len() != c.model.height as usize || b.blocks.is_empty() {
                return Err(ParseError::Bezier {
                    rows: b.reference_col.len(),
                    blocks: b.blocks.len(),
                    height: c.model.height,
                });
            }
        }
        Ok(c)
    }

    /// The triangulator this calibration defines (with its depth network, if any).
    pub fn triangulator(&self) -> Triangulator {
        let t = self.model.triangulator();
        match &self.bezier {
            Some(b) => t.with_depth(b.clone()),
            None => t,
        }
    }

    /// Written atomically; an invalid model is refused rather than saved.
    pub fn save(&self, path: &Path) -> Result<(), CalibrationError> {
        self.model.validate().map_err(|e| CalibrationError::Parse {
            path: path.to_owned(),
            source: Box::new(e.into()),
        })?;
        let text = toml::to_string_pretty(self).expect("calibration serialises");
        footscan_util::write_atomic(path, text.as_bytes()).map_err(|source| {
            CalibrationError::Write {
                path: path.to_owned(),
                source,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::model::tests::default_model;

    #[test]
    fn round_trips_through_toml() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calib.toml");
        let c = Calibration {
            method: "simulator-truth".into(),
            date: "2026-11-21T00:00:00Z".into(),
            model: default_model(),
            stddev: BTreeMap::new(),
            residuals: [("plate_rms_px".to_string(), 0.01)].into(),
            bezier: None,
        };
        c.save(&path).unwrap();
        assert_eq!(Calibration::load(&path).unwrap(), c);
    }

    /// An invalid model is a typed cause under the file's error, not text inside it.
    #[test]
    fn an_invalid_model_is_the_cause() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calib.toml");
        let mut c = Calibration {
            method: "simulator-truth".into(),
            date: "2026-11-21T00:00:00Z".into(),
            model: default_model(),
            stddev: BTreeMap::new(),
            residuals: BTreeMap::new(),
            bezier: None,
        };
        c.model.d_mm = -1.0;
        let e = c.save(&path).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("calibration {} is not valid", path.display())
        );
        let cause = std::error::Error::source(&e).unwrap();
        let parse = cause
            .downcast_ref::<Box<ParseError>>()
            .map(|b| &**b)
            .or_else(|| cause.downcast_ref::<ParseError>());
        assert!(
            matches!(
                parse,
                Some(ParseError::Model(ModelError::NotPositive {
                    key: "d_mm",
                    ..
                }))
            ),
            "{cause:?}"
        );
        assert!(!path.exists());
    }

    #[test]
    fn bad_file_names_path_and_key() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, "method = \"x\"\ndate = \"d\"\n[model]\nf_px = 1\n").unwrap();
        let e = footscan_util::chain(&Calibration::load(&path).unwrap_err());
        assert!(e.contains("bad.toml") && e.contains("missing field"), "{e}");
    }
}
