//! A last's size checked before any stage works on it (docs/method.md 9.3): a mesh read with
//! the wrong units (a last in millimetres given `--units m` is 299 m long) or a pair of lasts
//! of different sizes is refused, naming the file, the size found and the valid range,
//! before anything is computed or written.

use footscan_geom::mesh::TriMesh;
use nalgebra::{Matrix3, Vector3};
use std::path::{Path, PathBuf};

/// A last is this long (mm, its extent along its longest principal axis): a child's last
/// from 100 mm (EU size 15 is a 100 mm foot), the largest adult lasts about 340 mm plus
/// room for a long toe.
pub const LAST_LENGTH_MM: (f64, f64) = (100.0, 380.0);

/// Two lasts to be joined may differ in length by this fraction of the longer at most
/// (a size group: 13 % is about five Paris sizes on a 260 mm last).
pub const SIZE_GROUP: f64 = 0.13;

#[derive(Debug, thiserror::Error)]
pub enum SizeError {
    #[error(
        "last {}: {length_mm:.1} mm long is not a last's size: a last is {:.0}-{:.0} mm long \
         (check --units, or give --length for an unscaled file)",
        path.display(), LAST_LENGTH_MM.0, LAST_LENGTH_MM.1
    )]
    NotALast { path: PathBuf, length_mm: f64 },
    #[error(
        "lasts {} ({a_mm:.1} mm) and {} ({b_mm:.1} mm) differ in length by {:.1} %, more than a \
         size group ({:.0} %); pass --allow-size-mismatch to join them anyway",
        a.display(), b.display(), 100.0 * rel, 100.0 * SIZE_GROUP
    )]
    Mismatch {
        a: PathBuf,
        a_mm: f64,
        b: PathBuf,
        b_mm: f64,
        rel: f64,
    },
}

/// The last's length for the size check: the extent of its vertices along their principal
/// axis of largest spread (independent of how the file is turned).
pub fn last_length_mm(m: &TriMesh) -> f64 {
    let n = m.vertices.len().max(1) as f64;
    let c: Vector3<f64> = m.vertices.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    for p in &m.vertices {
        let d = p.coords - c;
        cov += d * d.transpose();
    }
    let e = cov.symmetric_eigen();
    let axis: Vector3<f64> = e.eigenvectors.column(e.eigenvalues.imax()).into();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &m.vertices {
        let t = (p.coords - c).dot(&axis);
        lo = lo.min(t);
        hi = hi.max(t);
    }
    hi - lo
}

/// The mesh's length if it is a last's (`LAST_LENGTH_MM`), else the error naming the file.
pub fn check_last_size(path: &Path, m: &TriMesh) -> Result<f64, SizeError> {
    let l = last_length_mm(m);
    if l.is_finite() && (LAST_LENGTH_MM.0..=LAST_LENGTH_MM.1).contains(&l) {
        Ok(l)
    } else {
        Err(SizeError::NotALast {
            path: path.to_path_buf(),
            length_mm: l,
        })
    }
}

/// Two lasts' lengths within a size group of each other (`SIZE_GROUP` of the longer).
pub fn check_pair(a: (&Path, f64), b: (&Path, f64)) -> Result<(), SizeError> {
    let rel = (a.1 - b.1).abs() / a.1.max(b.1);
    if rel <= SIZE_GROUP {
        Ok(())
    } else {
        Err(SizeError::Mismatch {
            a: a.0.to_path_buf(),
            a_mm: a.1,
            b: b.0.to_path_buf(),
            b_mm: b.1,
            rel,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use footscan_geom::P3;

    #[test]
    fn sizes() {
        let m = |l: f64| TriMesh::cuboid(P3::origin(), P3::new(l, 0.35 * l, 0.4 * l));
        assert!(check_last_size(Path::new("a.stl"), &m(250.0)).is_ok());
        for bad in [60.0, 299_000.0] {
            let e = check_last_size(Path::new("a.stl"), &m(bad)).unwrap_err();
            let s = footscan_util::chain(&e);
            assert!(s.contains("a.stl") && s.contains("100-380"), "{s}");
        }
        assert!(check_pair((Path::new("a"), 250.0), (Path::new("b"), 270.0)).is_ok());
        let e = check_pair((Path::new("a"), 250.0), (Path::new("b"), 300.0)).unwrap_err();
        assert!(e.to_string().contains("--allow-size-mismatch"), "{e}");
    }
}
