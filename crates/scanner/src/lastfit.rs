//! A scan as the foot of the last stages: the scanner's measurements and scan grid turned into
//! the plain inputs of [`footscan_last::adjust`] ([`FootPlantar`]), and the whole bottom
//! adjustment of a saved scan ([`adjust_scan`]) that `footscan last adjust` and the pipeline
//! stage `last.adjust` share.
//!
//! Heights come from the scan grid rasterised on the adjustment's cell (0.5 mm: each cell the
//! mean of the 3-6 measured points in it), not from the Bezier network: the adjustment only
//! compares heights and then fits its own cubic B-spline bottom through them, so the
//! network's normal jumps across segment edges (docs/method.md section 7.4) never reach the
//! bottom surface, and cells the network leaves out at the outline are kept.

use crate::measure::{rasterize_grid, MeasureError, Measurements};
use crate::scandata::{ScanDir, ScanDirError, ScanGrid};
use footscan_last::adjust::last::{
    deform_last, prepare_last, scanned_bottom, DeformReport, LastOptions, PreparedLast,
};
use footscan_last::adjust::output::{Report, Written};
use footscan_last::adjust::surface::{fit_bottom, BottomSurface};
use footscan_last::adjust::{
    self, AdjustError, AdjustOptions, Adjustment, FootLandmarks, FootPlantar, LastBottom,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Why a scan could not be adjusted to a last; every variant names its input.
#[derive(Debug, thiserror::Error)]
pub enum LastFitError {
    #[error(
        "scan {}: no measurements.json: measure the foot first (`footscan measure --scan {}`, \
         or name the measure.foot stage before last.adjust in the pipeline)",
        dir.display(), dir.display()
    )]
    NoMeasurements { dir: PathBuf },
    #[error("scan {}: {what}: {why}", dir.display())]
    Scan {
        dir: PathBuf,
        what: String,
        why: String,
    },
    #[error(transparent)]
    Measure(#[from] MeasureError),
    #[error(transparent)]
    Adjust(#[from] AdjustError),
}

/// The foot of a scan: outline, toe pads and landmarks from the measurements, heights from the
/// grid rasterised on `cell_mm`.
pub fn foot_plantar(
    source: &str,
    grid: &ScanGrid,
    m: &Measurements,
    cell_mm: f64,
) -> Result<FootPlantar, MeasureError> {
    let map = rasterize_grid(grid, cell_mm)?;
    Ok(FootPlantar {
        source: source.to_string(),
        side: m.side,
        outline: m.outline.clone(),
        toe_outlines: m.toe_outlines.clone(),
        landmarks: FootLandmarks {
            heel_point: m.heel_point,
            toe_tip: m.toe_tip,
            hallux: m.hallux_point,
            mt1_head: m.mt1_head,
            mt5_head: m.mt5_head,
            waist_inner: m.waist_inner,
            waist_outer: m.waist_outer,
            arch_point: m.arch_point,
            arch_height_mm: m.arch_height_mm,
        },
        heights: map,
    })
}

/// Reads a saved scan's grid.bin and measurements.json as the adjustment's foot.
pub fn foot_from_scan_dir(dir: &Path, cell_mm: f64) -> Result<FootPlantar, LastFitError> {
    let scan_err = |what: &str, why: String| LastFitError::Scan {
        dir: dir.to_path_buf(),
        what: what.to_string(),
        why,
    };
    let scan = ScanDir::new(dir);
    let m = match scan.load_measurements() {
        Ok(Some(m)) => m,
        Ok(None) => {
            return Err(LastFitError::NoMeasurements {
                dir: dir.to_path_buf(),
            })
        }
        Err(ScanDirError::Read { source, .. }) => {
            return Err(scan_err(
                ScanDir::MEASUREMENTS,
                footscan_util::chain(&source),
            ))
        }
        Err(ScanDirError::Parse { source, .. }) => {
            return Err(scan_err(
                ScanDir::MEASUREMENTS,
                format!("not the scanner's measurements ({source})"),
            ))
        }
    };
    let grid = scan
        .load_grid()
        .map_err(|e| scan_err(ScanDir::GRID, footscan_util::chain(&e)))?;
    Ok(foot_plantar(
        &dir.display().to_string(),
        &grid,
        &m,
        cell_mm,
    )?)
}

/// Knobs of [`adjust_scan`] beyond the last file's own.
#[derive(Clone, Copy, Debug)]
pub struct AdjustScanOptions {
    pub adjust: AdjustOptions,
    /// Control point spacing of the bottom B-spline surface (mm).
    pub surface_spacing_mm: f64,
    /// Height over which the deformation of the whole last fades out (mm; at least four times
    /// the largest change is used).
    pub fade_mm: f64,
}

/// A fade height outside (0, 200] mm was asked for.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("fade {0} mm: valid range is (0, 200]")]
pub struct FadeOutOfRange(pub f64);

impl AdjustScanOptions {
    /// The defaults with the fade a user asked for (the CLI's --fade-mm, the stage's
    /// fade_mm), checked here once for both.
    pub fn with_fade_mm(fade_mm: f64) -> Result<Self, FadeOutOfRange> {
        if !(fade_mm > 0.0 && fade_mm <= 200.0) {
            return Err(FadeOutOfRange(fade_mm));
        }
        Ok(AdjustScanOptions {
            fade_mm,
            ..AdjustScanOptions::default()
        })
    }
}

impl Default for AdjustScanOptions {
    fn default() -> Self {
        AdjustScanOptions {
            adjust: AdjustOptions::default(),
            surface_spacing_mm: 3.0,
            fade_mm: 30.0,
        }
    }
}

/// A last as the adjustment's input: a last mesh (its bottom found as its downward-facing
/// region; the whole last is deformed too), or the scan of a last's bottom (a scan directory
/// of `footscan scan --config config/sim-last.toml` or of a last on the real scanner: the
/// bottom only, so nothing to deform).
pub enum LastSource {
    Mesh(Box<PreparedLast>),
    Scan { dir: PathBuf, bottom: LastBottom },
}

/// A last scan cut by the scan range or the camera's view (scan.json's quality gate) has
/// lost its heel, toe or a side: its length and side would be guessed from what is left (a
/// right last cut at the toe was read as a left one and mirrored), so it is refused.
fn refuse_cut_last_scan(dir: &Path) -> Result<(), LastFitError> {
    let Ok(text) = std::fs::read(ScanDir::new(dir).summary_path()) else {
        return Ok(()); // an older scan directory: nothing to go by
    };
    let json: serde_json::Value =
        serde_json::from_slice(&text).map_err(|e| LastFitError::Scan {
            dir: dir.to_path_buf(),
            what: ScanDir::SUMMARY.into(),
            why: e.to_string(),
        })?;
    let cut: Vec<&str> = json["quality"]["cut"]
        .as_array()
        .map(|a| a.iter().filter_map(|c| c.as_str()).collect())
        .unwrap_or_default();
    if cut.is_empty() {
        return Ok(());
    }
    Err(LastFitError::Scan {
        dir: dir.to_path_buf(),
        what: format!(
            "the last runs past the {} ({})",
            cut.join(" and the "),
            ScanDir::SUMMARY
        ),
        why: "part of its bottom was not scanned, so its length and side cannot be told; \
              scan it again with the whole last inside the scan range (config/sim-last.toml \
              says which lengths fit)"
            .into(),
    })
}

impl LastSource {
    /// A directory is a scan of a last bottom (its grid.bin), anything else a mesh file.
    pub fn load(path: &Path, opts: &LastOptions, cell_mm: f64) -> Result<Self, LastFitError> {
        if path.is_dir() {
            refuse_cut_last_scan(path)?;
            let grid = ScanDir::new(path)
                .load_grid()
                .map_err(|e| LastFitError::Scan {
                    dir: path.to_path_buf(),
                    what: format!(
                        "{} (a last scan directory needs its scan grid)",
                        ScanDir::GRID
                    ),
                    why: footscan_util::chain(&e),
                })?;
            let below = rasterize_grid(&grid, cell_mm)?;
            let source = format!("last scan {}", path.display());
            let bottom = scanned_bottom(&source, &below, opts.down_cos)?;
            Ok(LastSource::Scan {
                dir: path.to_path_buf(),
                bottom,
            })
        } else {
            Ok(LastSource::Mesh(Box::new(prepare_last(path, opts)?)))
        }
    }

    pub fn bottom(&self) -> &LastBottom {
        match self {
            LastSource::Mesh(p) => &p.bottom,
            LastSource::Scan { bottom, .. } => bottom,
        }
    }

    pub fn path(&self) -> &Path {
        match self {
            LastSource::Mesh(p) => &p.path,
            LastSource::Scan { dir, .. } => dir,
        }
    }

    pub fn mesh(&self) -> Option<&PreparedLast> {
        match self {
            LastSource::Mesh(p) => Some(p),
            LastSource::Scan { .. } => None,
        }
    }
}

/// One adjustment's results and timings (ms), before anything is written.
pub struct AdjustedLast {
    pub adjustment: Adjustment,
    pub surface: BottomSurface,
    /// The whole last deformed (a mesh input only).
    pub deformed: Option<(footscan_geom::mesh::TriMesh, DeformReport)>,
    pub report: Report,
    pub adjust_ms: f64,
    pub surface_ms: f64,
    pub deform_ms: f64,
}

impl AdjustedLast {
    /// What [`footscan_last::adjust::output`] writes besides the bottom: the prepared last
    /// and its deformed mesh, for a mesh input.
    pub fn whole_last<'a>(
        &'a self,
        last: &'a LastSource,
    ) -> Option<(&'a PreparedLast, &'a footscan_geom::mesh::TriMesh)> {
        Some((last.mesh()?, &self.deformed.as_ref()?.0))
    }
}

/// Adjusts a last to a foot: the bottom ([`adjust::adjust`]), its B-spline surface and, for
/// a last mesh, the whole last deformed to it.
pub fn adjust_last(
    foot: &FootPlantar,
    last: &LastSource,
    opts: &AdjustScanOptions,
) -> Result<AdjustedLast, AdjustError> {
    let t = Instant::now();
    let a = adjust::adjust(foot, last.bottom(), &opts.adjust)?;
    let adjust_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let surf = fit_bottom(&a, opts.surface_spacing_mm)?;
    let surface_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let deformed = match last.mesh() {
        Some(p) => Some(deform_last(p, &a, opts.fade_mm)?),
        None => None,
    };
    let deform_ms = t.elapsed().as_secs_f64() * 1e3;
    let report = Report::new(
        &foot.source,
        &last.path().display().to_string(),
        &a,
        &surf,
        deformed.as_ref().map(|d| d.1),
    );
    Ok(AdjustedLast {
        adjustment: a,
        surface: surf,
        deformed,
        report,
        adjust_ms,
        surface_ms,
        deform_ms,
    })
}

/// `footscan last adjust`: the scan in `scan_dir` against the last (a mesh file or a last
/// scan directory), outputs into `out` (all or nothing).
pub fn adjust_scan(
    scan_dir: &Path,
    last_path: &Path,
    last_opts: &LastOptions,
    opts: &AdjustScanOptions,
    out: &Path,
) -> Result<(AdjustedLast, Written), LastFitError> {
    let foot = foot_from_scan_dir(scan_dir, opts.adjust.cell_mm)?;
    let last = LastSource::load(last_path, last_opts, opts.adjust.cell_mm)?;
    let done = adjust_last(&foot, &last, opts)?;
    let written = adjust::output::write_outputs(
        out,
        &done.adjustment,
        &done.surface,
        done.whole_last(&last),
        &done.report,
    )?;
    Ok((done, written))
}
