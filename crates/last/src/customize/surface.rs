//! The last as one NURBS surface for IGES and STEP: every third section of the last mesh
//! interpolated by a periodic cubic with uniform parameters (so all sections share one knot
//! vector), skinned along the axis, and closed at both ends by a section collapsed to the
//! end centroid (a pole), so the surface encloses the same solid as last.stl.

use super::{CustomizeError, Customized};
use footscan_geom::nurbs::{fit, skin, NurbsCurve, NurbsSurface};
use footscan_geom::P3;

pub fn last_surface(c: &Customized) -> Result<NurbsSurface, CustomizeError> {
    let n = super::shape::AROUND;
    let v = &c.last.vertices;
    let k = (v.len() - 2) / n;
    let err = |e: footscan_geom::nurbs::NurbsError| CustomizeError::Curve {
        curve: "last surface".into(),
        why: footscan_util::chain(&e),
    };
    let params: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    let mut pick: Vec<usize> = (0..k).step_by(3).collect();
    if *pick.last().unwrap() != k - 1 {
        pick.push(k - 1);
    }
    let mut secs: Vec<NurbsCurve> = Vec::new();
    for &r in &pick {
        let ring: Vec<P3> = v[r * n..(r + 1) * n].to_vec();
        secs.push(fit::interpolate_closed_with(&ring, &params, 3).map_err(err)?);
    }
    let pole = |c: &NurbsCurve, at: P3| {
        let mut d = c.clone();
        for p in &mut d.points {
            *p = at;
        }
        d
    };
    let (c0, c1) = (v[k * n], v[k * n + 1]);
    let first = pole(&secs[0], c0);
    let last = pole(&secs[secs.len() - 1], c1);
    let mut all = vec![first];
    all.extend(secs);
    all.push(last);
    skin::skin(&all, None, 3).map_err(err)
}
