//! A saved scan as the foot of the clinic's customized last: the plantar figures of its
//! measurements.json, the girths a fitter measured with a tape, and a stock last from the
//! shop's collection, customized by the comfort rules
//! ([`footscan_last::customize::clinic`], docs/method.md 10.7). `footscan last customize
//! --scan` and footscand's last job share it, so both read a scan the same way.

use crate::measure::Measurements;
use crate::scandata::{ScanDir, ScanDirError};
use footscan_geom::mesh::{TriMesh, Units};
use footscan_geom::{quarter_turn, P2};
use footscan_last::customize::clinic::{customize_stock, Plantar, TapeGirths};
use footscan_last::customize::rules::RuleSet;
use footscan_last::customize::{CustomizeError, Customized, Inputs};
use std::path::{Path, PathBuf};

/// Why a scan could not be customized into a last; every variant names its input.
#[derive(Debug, thiserror::Error)]
pub enum ClinicLastError {
    #[error(
        "scan {}: no measurements.json: a customized last needs a measured foot (a scan whose \
         pipeline ran measure.foot, or `footscan measure --scan {}`)",
        dir.display(), dir.display()
    )]
    NoMeasurements { dir: PathBuf },
    #[error("{}", prefixed(path, why))]
    Input { path: PathBuf, why: String },
    /// The message carries the customization's whole chain after the stock's name, so the
    /// error is not a `source` (an edge printing the chain would say it twice).
    #[error("{}", named(stock, error))]
    Customize {
        stock: PathBuf,
        error: Box<CustomizeError>,
    },
}

/// `why` with the file in front unless it names it already.
pub fn prefixed(path: &Path, why: &str) -> String {
    let name = path.display().to_string();
    if why.contains(&name) {
        why.to_string()
    } else {
        format!("{name}: {why}")
    }
}

fn named(stock: &Path, e: &CustomizeError) -> String {
    prefixed(stock, &footscan_util::chain(e))
}

/// The plantar figures the rules need from a scan's measurements (docs/method.md section 8).
pub fn plantar_of(m: &Measurements) -> Plantar {
    // Waist width across the axis, between the waist points.
    let (d, left) = (m.axis_dir, quarter_turn(&m.axis_dir));
    let waist = (m.waist_inner - m.waist_outer).dot(&left).abs();
    // The footprint in the foot's frame: x along the axis from the heel point, y across it,
    // positive on the side of the first metatarsal head (medial).
    let h = m.heel_point;
    let across = |p: P2| (p - h).dot(&left);
    let medial = if across(m.mt1_head) >= 0.0 { 1.0 } else { -1.0 };
    let frame = |p: &P2| P2::new((p - h).dot(&d), medial * across(*p));
    let footprint = std::iter::once(&m.outline)
        .chain(&m.toe_outlines)
        .map(|l| l.iter().map(frame).collect())
        .collect();
    Plantar {
        side: m.side,
        length: m.foot_length_mm,
        ball_width: m.ball_width_mm,
        waist_width: waist,
        heel_width: m.heel_width_mm,
        footprint,
    }
}

/// The plantar figures of a scan directory's measurements.json.
pub fn plantar_of_scan(dir: &Path) -> Result<Plantar, ClinicLastError> {
    let m = match ScanDir::new(dir).load_measurements() {
        Ok(Some(m)) => m,
        Ok(None) => return Err(ClinicLastError::NoMeasurements { dir: dir.into() }),
        Err(ScanDirError::Read { path, source }) => {
            return Err(ClinicLastError::Input {
                path,
                why: footscan_util::chain(&source),
            })
        }
        Err(ScanDirError::Parse { path, source, .. }) => {
            return Err(ClinicLastError::Input {
                path,
                why: format!("not the measurements of a scan: {source}"),
            })
        }
    };
    Ok(plantar_of(&m))
}

/// Mesh formats a stock last is read from.
pub const STOCK_EXTENSIONS: [&str; 6] = ["stl", "obj", "ply", "asc", "xyz", "pts"];

/// Read a stock last: a closed mesh (STL, OBJ or PLY; millimetres or metres, z up).
pub fn load_stock(path: &Path) -> Result<TriMesh, ClinicLastError> {
    load_stock_as(path, Units::Auto, None)
}

/// [`load_stock`] with the file's units given, or its length (mm) for a last in model
/// units (`--units`, `--length`, as every last command takes them). Given neither (units
/// auto, no length), the entry of the `lasts.toml` beside the file says
/// (`footscan_last::collection`), as for the daemon's stock collection.
pub fn load_stock_as(
    path: &Path,
    units: Units,
    length_mm: Option<f64>,
) -> Result<TriMesh, ClinicLastError> {
    let (units, length_mm) = if units == Units::Auto && length_mm.is_none() {
        let r = footscan_last::collection::Collection::for_file(
            path,
            footscan_last::collection::ReadAs { units, length_mm },
        )
        .map_err(|e| ClinicLastError::Input {
            path: path.into(),
            why: e.to_string(),
        })?;
        (r.units, r.length_mm)
    } else {
        (units, length_mm)
    };
    let (m, _) =
        TriMesh::load_solid(path, units, length_mm).map_err(|e| ClinicLastError::Input {
            path: path.into(),
            // No unit or length option for a stock last: say what the file must be.
            why: e
                .retold(
                    "a stock last is read in millimetres or metres; save it in one of them",
                    "a stock last is read in millimetres or metres; for one in a modelling \
                     tool's units give the length of its longest side in the lasts.toml \
                     beside it (`[\"NAME\"] length_mm = 265`)",
                )
                .to_string(),
        })?;
    footscan_last::size::check_last_size(path, &m).map_err(|e| ClinicLastError::Input {
        path: path.into(),
        why: footscan_util::chain(&e),
    })?;
    Ok(m)
}

/// The clinic's last for the scan in `dir`: its plantar figures and `girths` applied to
/// the rules, the stock last at `stock` deformed to the targets. Nothing is written.
pub fn customize_scan(
    dir: &Path,
    girths: &TapeGirths,
    stock: &Path,
    rules: &RuleSet,
    inp: &Inputs,
) -> Result<Customized, ClinicLastError> {
    let plantar = plantar_of_scan(dir)?;
    let m = load_stock(stock)?;
    customize_stock(
        m,
        &stock.display().to_string(),
        &plantar,
        girths,
        rules,
        inp,
    )
    .map_err(|error| ClinicLastError::Customize {
        stock: stock.into(),
        error: Box::new(error),
    })
}
