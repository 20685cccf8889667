//! Export of B-spline/NURBS curves and surfaces to IGES 5.3 and STEP AP214.
//!
//! Both writers take the crate's [`NurbsCurve`] and [`NurbsSurface`] as they are (full knot
//! vectors, Euclidean control points plus optional weights, u-major surface nets) and write the
//! exact same geometry: knots, degrees, control points and weights are carried over without
//! re-parametrisation, so a reader evaluates the same point at the same parameter.
//!
//! - [`iges`]: entity 126 (rational B-spline curve) and 128 (rational B-spline surface) with
//!   their planar/closed/polynomial/periodic flags, millimetres in the global section.
//! - [`step`]: ISO 10303-21 with the AP214 (automotive_design) product boilerplate; surfaces as
//!   advanced faces bounded by their boundary iso-curves in a shell-based surface model,
//!   curves as a geometric curve set in a wireframe representation.
//!
//! Files are written atomically (a temporary file in the same directory, flushed to disk,
//! then renamed), so a reader never sees half a file and a failed export leaves nothing.
//!
//! No maintained Rust crate writes IGES. truck-stepio writes STEP, but only from truck's own
//! topology and geometry types (cgmath), so using it would mean converting every curve and
//! surface and building truck shells just to serialise them; the STEP entities needed here
//! are few and are written directly.

pub mod iges;
pub mod step;

use crate::nurbs::{NurbsCurve, NurbsSurface};
use crate::{P3, V3};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Why an export failed. Invalid geometry is reported before anything is written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A curve or surface is not a valid B-spline: `what` names it ("curve 2", "surface 0").
    #[error("{what}: {reason}")]
    Invalid { what: String, reason: String },
    /// Nothing to write.
    #[error("nothing to export: no curves and no surfaces")]
    Empty,
    /// Writing the file failed; `path` is the file asked for.
    #[error("{}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// What a file says about itself: the product/part name, who made it, when, and the
/// resolution (smallest distance that matters, mm) that readers may use as their tolerance.
#[derive(Debug, Clone)]
pub struct Header {
    /// Product or part name (STEP PRODUCT, IGES file name field).
    pub name: String,
    pub author: String,
    pub organization: String,
    /// Date and time of the file, written in UTC.
    pub time: SystemTime,
    /// Smallest meaningful distance in mm (IGES global resolution, STEP uncertainty).
    pub resolution_mm: f64,
}

impl Header {
    /// A header for `name` made now by footscan, with a resolution of 1e-6 mm.
    pub fn new(name: &str) -> Header {
        Header {
            name: name.to_string(),
            author: "footscan".to_string(),
            organization: String::new(),
            time: SystemTime::now(),
            resolution_mm: 1e-6,
        }
    }
}

/// Writes `bytes` to `path` atomically: a temporary file beside it, fsync, rename, then an
/// fsync of the directory (best effort). Errors name `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    let io = |source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let name = path.file_name().ok_or_else(|| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a file name",
        ))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = dir.join(tmp_name);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    if let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// A real number written so that it reads back to the same f64 (shortest round-trip digits)
/// and always with a decimal point, as both IGES and STEP require for reals.
pub fn real(x: f64) -> String {
    if x == 0.0 {
        return "0.".to_string();
    }
    let a = x.abs();
    let mut s = if (1e-4..1e15).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:E}")
    };
    match s.find('E') {
        Some(e) if !s[..e].contains('.') => s.insert(e, '.'),
        None if !s.contains('.') => s.push('.'),
        _ => {}
    }
    s
}

/// UTC calendar date and time of `t`: (year, month, day, hour, minute, second).
pub(crate) fn utc(t: SystemTime) -> (i64, u32, u32, u32, u32, u32) {
    let secs = match t.duration_since(SystemTime::UNIX_EPOCH) {
        Ok(d) => d.as_secs() as i64,
        Err(e) => -(e.duration().as_secs() as i64),
    };
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400) as u32;
    // Days since 1970-01-01 to a proleptic Gregorian date, counting in 400-year eras that
    // start on 1 March so the leap day falls at the end of each year.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day, sod / 3600, sod / 60 % 60, sod % 60)
}

/// Text made safe for both formats: printable ASCII only (others become '?').
pub(crate) fn ascii(s: &str) -> String {
    s.chars()
        .map(|c| if (' '..='~').contains(&c) { c } else { '?' })
        .collect()
}

/// A validation failure of the nurbs module, named by the export's own numbering.
fn invalid(what: String, e: crate::nurbs::NurbsError) -> ExportError {
    let msg = e.to_string();
    // The nurbs error starts with "curve: ", "surface: " or "surface u: "; keep the direction.
    let reason = match msg.split_once(": ") {
        Some(("curve" | "surface", rest)) => rest.to_string(),
        Some((head, rest)) if head.starts_with("surface ") => format!("in {}: {rest}", &head[8..]),
        _ => msg,
    };
    ExportError::Invalid { what, reason }
}

pub(crate) fn check_curve(k: usize, c: &NurbsCurve) -> Result<(), ExportError> {
    c.validate().map_err(|e| invalid(format!("curve {k}"), e))
}

pub(crate) fn check_surface(k: usize, s: &NurbsSurface) -> Result<(), ExportError> {
    s.validate().map_err(|e| invalid(format!("surface {k}"), e))
}

/// A tolerance for "the same point" relative to the size of a control net.
pub(crate) fn same_point_tol(points: &[P3]) -> f64 {
    let m = points
        .iter()
        .flat_map(|q| q.iter())
        .fold(0.0f64, |m, c| m.max(c.abs()));
    1e-9 * (1.0 + m)
}

/// The knot span and the p + 1 non-zero basis functions at `u`, clamped into the domain.
fn basis(knots: &[f64], p: usize, n_points: usize, u: f64) -> (usize, Vec<f64>) {
    let u = u.clamp(knots[p], knots[n_points]);
    let span = crate::nurbs::basis::find_span(n_points - 1, p, u, knots);
    let mut b = vec![0.0; p + 1];
    crate::nurbs::basis::basis_funs(span, u, p, knots, &mut b);
    (span, b)
}

/// Start and end point of a curve's domain.
pub(crate) fn curve_ends(c: &NurbsCurve) -> (P3, P3) {
    let (a, b) = c.domain();
    (c.point(a), c.point(b))
}

/// The iso-parametric curve of a surface at u = `t` (`along_u == false`: a curve in v) or
/// at v = `t` (`along_u == true`: a curve in u), exactly, as a curve on the other knot vector.
pub(crate) fn iso_curve(s: &NurbsSurface, along_u: bool, t: f64) -> NurbsCurve {
    let w = |k: usize| s.weights.as_ref().map_or(1.0, |w| w[k]);
    let (deg_fixed, knots_fixed, n_fixed, n_free) = if along_u {
        (s.degree_v, &s.knots_v, s.nv, s.nu)
    } else {
        (s.degree_u, &s.knots_u, s.nu, s.nv)
    };
    let (span, b) = basis(knots_fixed, deg_fixed, n_fixed, t);
    let mut points = Vec::with_capacity(n_free);
    let mut weights = Vec::with_capacity(n_free);
    for free in 0..n_free {
        let mut acc = [0.0; 4];
        for (k, bk) in b.iter().enumerate() {
            let fixed = span - deg_fixed + k;
            let idx = if along_u {
                free * s.nv + fixed
            } else {
                fixed * s.nv + free
            };
            let (q, wq) = (s.points[idx], w(idx));
            acc[0] += bk * wq * q.x;
            acc[1] += bk * wq * q.y;
            acc[2] += bk * wq * q.z;
            acc[3] += bk * wq;
        }
        points.push(P3::new(acc[0] / acc[3], acc[1] / acc[3], acc[2] / acc[3]));
        weights.push(acc[3]);
    }
    let rational = s.weights.is_some();
    NurbsCurve {
        degree: if along_u { s.degree_u } else { s.degree_v },
        knots: if along_u {
            s.knots_u.clone()
        } else {
            s.knots_v.clone()
        },
        points,
        weights: rational.then_some(weights),
        periodic: if along_u { s.periodic_u } else { s.periodic_v },
    }
}

/// Whether two curves on the same knots have the same control points and weights (so are
/// the same curve) within `tol`.
pub(crate) fn same_curve(a: &NurbsCurve, b: &NurbsCurve, tol: f64) -> bool {
    let w = |c: &NurbsCurve, i: usize| c.weights.as_ref().map_or(1.0, |w| w[i]);
    a.points.len() == b.points.len()
        && (0..a.points.len()).all(|i| {
            (a.points[i] - b.points[i]).norm() <= tol
                && (w(a, i) - w(b, i)).abs() <= 1e-12 * w(a, i).max(1.0)
        })
}

/// Whether all control points of a curve coincide (a boundary collapsed to a point).
pub(crate) fn degenerate(c: &NurbsCurve, tol: f64) -> bool {
    c.points.iter().all(|q| (q - c.points[0]).norm() <= tol)
}

/// The unit normal of the plane holding all `points` (within `tol`), if there is one.
/// A NURBS curve lies in the convex hull of its control points, so a planar control net
/// means a planar curve.
pub(crate) fn plane_normal(points: &[P3], tol: f64) -> Option<V3> {
    let c = points.iter().fold(V3::zeros(), |a, q| a + q.coords) / points.len() as f64;
    let mut m = nalgebra::Matrix3::zeros();
    for q in points {
        let d = q.coords - c;
        m += d * d.transpose();
    }
    let e = m.symmetric_eigen();
    let (k, _) =
        e.eigenvalues.iter().enumerate().fold(
            (0, f64::INFINITY),
            |b, (i, &v)| if v < b.1 { (i, v) } else { b },
        );
    let n: V3 = e.eigenvectors.column(k).into_owned();
    // Collinear or coincident points lie in many planes: no unique normal to write.
    let mut sorted: Vec<f64> = e.eigenvalues.iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    if sorted[1] <= tol * tol {
        return None;
    }
    points
        .iter()
        .all(|q| (q.coords - c).dot(&n).abs() <= tol)
        .then_some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_round_trip_with_a_point() {
        for x in [0.0, 1.0, -2.5, 1e-7, 123456.789, 1e20, -3.0e-300, 0.1 + 0.2] {
            let s = real(x);
            assert!(s.contains('.'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap(), x, "{s}");
        }
        assert_eq!(real(1.0), "1.");
        assert_eq!(real(1e-7), "1.E-7");
    }

    #[test]
    fn utc_dates() {
        let t = |s: u64| SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(s);
        assert_eq!(utc(t(0)), (1970, 1, 1, 0, 0, 0));
        // 2000-02-29 12:34:56 UTC
        assert_eq!(utc(t(951_827_696)), (2000, 2, 29, 12, 34, 56));
        // 2024-12-31 23:59:59 UTC
        assert_eq!(utc(t(1_735_689_599)), (2024, 12, 31, 23, 59, 59));
    }
}
