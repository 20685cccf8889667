//! Units of a last or foot mesh: millimetres, metres, or unscaled model units.
//!
//! Mesh files carry no unit. A shoe last or a foot is 50 mm to 1 m long, so the longest side
//! of the bounding box tells the unit: under 1 it is metres, between 1 and 50 the model was
//! saved in arbitrary units and needs its real length, from 50 on it is millimetres.

use super::{MeshError, MeshReport, TriMesh};
use crate::V3;
use std::path::Path;

/// The smallest plausible length of a last or foot (mm).
pub const MIN_PLAUSIBLE_MM: f64 = 50.0;

/// The unit the caller says a mesh is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Units {
    Mm,
    /// Centimetres (some scanners and modelling tools write them).
    Cm,
    M,
    /// Decide from the size (see the module documentation).
    #[default]
    Auto,
}

/// A units name that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown units {0:?}; valid: mm, cm, m, auto")]
pub struct UnknownUnits(pub String);

impl std::str::FromStr for Units {
    type Err = UnknownUnits;
    fn from_str(s: &str) -> Result<Units, UnknownUnits> {
        match s {
            "mm" => Ok(Units::Mm),
            "cm" => Ok(Units::Cm),
            "m" => Ok(Units::M),
            "auto" => Ok(Units::Auto),
            _ => Err(UnknownUnits(s.to_string())),
        }
    }
}

/// How a mesh was brought to millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UnitsDecision {
    /// Already millimetres (scale 1).
    Millimetres,
    /// Metres, given (`Units::M`) or detected from the size (`detected`); scale 1000.
    Metres { detected: bool },
    /// Centimetres (given); scale 10.
    Centimetres,
    /// Scaled so the longest side is the given length.
    Length { length_mm: f64 },
}

/// What loading a last or foot did, for reporting.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadReport {
    pub decision: UnitsDecision,
    /// Factor applied to the file's coordinates.
    pub scale: f64,
    /// Bounding-box size in the file's own units.
    pub file_size: V3,
    /// Validation of the scaled mesh.
    pub mesh: MeshReport,
    /// A point cloud read as a last: how far its points lie from the mesh made through them
    /// (scaled).
    pub cloud: Option<super::cloud::CloudFit>,
}

impl LoadReport {
    /// One line for logs: what the size said and what was done.
    pub fn describe(&self) -> String {
        let s = self.file_size;
        let how = match self.decision {
            UnitsDecision::Millimetres => "millimetres".to_string(),
            UnitsDecision::Metres { detected: true } => {
                "metres (detected from the size), scaled by 1000".into()
            }
            UnitsDecision::Metres { detected: false } => "metres, scaled by 1000".into(),
            UnitsDecision::Centimetres => "centimetres, scaled by 10".into(),
            UnitsDecision::Length { length_mm } => {
                format!("scaled by {:.6} to a length of {length_mm} mm", self.scale)
            }
        };
        let made = self.cloud.map_or(String::new(), |c| {
            format!(
                " (a point cloud of {} points made a closed mesh round their outside: points \
                 off it {:.2} mm rms, {:.2} mm at the 99th percentile, none more than {:.2} \
                 mm outside; {} points on inner walls left inside)",
                c.points, c.rms_mm, c.p99_mm, c.outside_max_mm, c.inner_points
            )
        });
        format!(
            "{:.4} x {:.4} x {:.4} in the file: {how}; {} triangles, volume {:.0} mm^3{made}",
            s.x, s.y, s.z, self.mesh.triangles, self.mesh.volume
        )
    }
}

impl Units {
    /// The scale to millimetres for a mesh of bounding-box size `size` (file units) with an
    /// optional target length (the longest side after scaling; it overrides the units).
    pub fn resolve(
        self,
        size: V3,
        length_mm: Option<f64>,
        path: &Path,
    ) -> Result<(f64, UnitsDecision), MeshError> {
        let longest = size.max();
        if let Some(l) = length_mm {
            let valid = l.is_finite() && l > 0.0 && longest.is_finite() && longest > 0.0;
            if !valid {
                return Err(MeshError::BadLength {
                    path: path.to_path_buf(),
                    length_mm: l,
                });
            }
            return Ok((l / longest, UnitsDecision::Length { length_mm: l }));
        }
        match self {
            Units::M => Ok((1000.0, UnitsDecision::Metres { detected: false })),
            Units::Cm => Ok((10.0, UnitsDecision::Centimetres)),
            Units::Mm if longest < 1.0 => Err(MeshError::MetresAsMm {
                path: path.to_path_buf(),
                size,
                hint: "pass --units m (or --units auto)".into(),
            }),
            Units::Auto if longest < 1.0 => Ok((1000.0, UnitsDecision::Metres { detected: true })),
            Units::Mm | Units::Auto if longest < MIN_PLAUSIBLE_MM => Err(MeshError::Unscaled {
                path: path.to_path_buf(),
                size,
                hint: "give its length with --length MM".into(),
            }),
            Units::Mm | Units::Auto => Ok((1.0, UnitsDecision::Millimetres)),
        }
    }
}

impl TriMesh {
    /// Loads a last or foot mesh: reads it, validates it as a closed solid (the error names
    /// the file and the first bad edge), and scales it to millimetres by `units` and
    /// `length_mm` (see [`Units::resolve`]).
    pub fn load_solid(
        path: impl AsRef<Path>,
        units: Units,
        length_mm: Option<f64>,
    ) -> Result<(TriMesh, LoadReport), MeshError> {
        let path = path.as_ref();
        let (mut m, cloud) = if super::cloud::is_cloud(path) {
            let (m, fit) = super::cloud::read_last_points(path)?;
            (m, Some(fit))
        } else {
            (TriMesh::read(path)?, None)
        };
        m.validate(path)?;
        let file_size = m.bbox().extent();
        let (scale, decision) = units.resolve(file_size, length_mm, path)?;
        if scale != 1.0 {
            m.scale(scale);
        }
        let mesh = m.validate(path)?;
        Ok((
            m,
            LoadReport {
                decision,
                scale,
                file_size,
                mesh,
                cloud: cloud.map(|f| super::cloud::CloudFit {
                    rms_mm: f.rms_mm * scale,
                    p99_mm: f.p99_mm * scale,
                    outside_max_mm: f.outside_max_mm * scale,
                    ..f
                }),
            },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_rules() {
        let p = Path::new("last.stl");
        let m = V3::new(0.262, 0.1, 0.09);
        assert_eq!(Units::Auto.resolve(m, None, p).unwrap().0, 1000.0);
        assert_eq!(Units::M.resolve(m, None, p).unwrap().0, 1000.0);
        let e = Units::Mm.resolve(m, None, p).unwrap_err().to_string();
        assert!(
            e.contains("last.stl") && e.contains("0.2620 x") && e.contains("--units m"),
            "{e}"
        );
        let u = V3::new(4.5, 1.5, 2.0);
        let e = Units::Auto.resolve(u, None, p).unwrap_err().to_string();
        assert!(e.contains("--length"), "{e}");
        let (s, d) = Units::Auto.resolve(u, Some(270.0), p).unwrap();
        assert_eq!((s, d), (60.0, UnitsDecision::Length { length_mm: 270.0 }));
        assert_eq!(
            Units::Auto
                .resolve(V3::new(270.0, 100.0, 90.0), None, p)
                .unwrap()
                .0,
            1.0
        );
        assert!(Units::Auto.resolve(u, Some(-1.0), p).is_err());
        assert_eq!("m".parse::<Units>(), Ok(Units::M));
    }
}
