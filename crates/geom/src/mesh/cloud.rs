//! A closed mesh through a scanned last's points (an XYZ point cloud, as last scanners and
//! digitisers write them).
//!
//! A last is a solid blob with no through-holes: scaled along its principal axes to a unit
//! ball it is star-shaped about its centre almost everywhere (the rays from the centre cross
//! its surface once), so its surface is a radius over the sphere of directions. The mesh is
//! an icosphere whose every vertex is pushed out to the Gaussian-weighted mean radius of the
//! points seen in a cone about its direction; directions no point covers take their
//! neighbours' radius. Closed and 2-manifold by construction, whatever the points.
//! docs/method.md 9.6 gives the fit on the shared scanned last.

use super::{Bvh, TriMesh};
use crate::{P3, V3};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// Fewer points than this cannot describe a last.
pub const MIN_POINTS: usize = 1000;
/// More points than this are not read (a last scan has tens of thousands; 4 million XYZ
/// lines is about 120 MB of text).
pub const MAX_POINTS: usize = 4_000_000;
/// Icosphere subdivisions: 20 480 triangles, a vertex every 2 degrees of direction.
const LEVEL: u32 = 5;
/// Half-angle of the cone a vertex takes its radius from, in vertex spacings.
const CONE: f64 = 1.5;
/// The band of radii below a cone's outermost point taken as the outside (a fraction of
/// the radius: 6 % is 3 mm across a last's width).
const OUTER_BAND: f64 = 0.06;

/// Deeper inside the solid than this (mm), a point is on an inner wall.
const INNER_MM: f64 = 2.0;

/// How well the mesh follows the points on its outside (mm), for the load report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudFit {
    pub points: usize,
    /// Points inside the solid by more than 2 mm: inner walls (a slot, a hinge cut), left
    /// out of the figures below.
    pub inner_points: usize,
    pub rms_mm: f64,
    pub p99_mm: f64,
    /// The farthest point outside the mesh: where it cuts into the scanned last.
    pub outside_max_mm: f64,
    /// Vertices no point's cone reached, filled from their neighbours.
    pub filled_vertices: usize,
}

/// Whether `path` names a point cloud by its extension (.asc, .xyz, .pts).
pub fn is_cloud(path: &std::path::Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "asc" | "xyz" | "pts"))
}

/// Longer lines than this are not points (three numbers and a few extra columns).
const MAX_LINE: usize = 4096;

/// A point-cloud file read and made a closed mesh ([`last_from_points`]); errors name the
/// file.
///
/// The text is streamed twice (once to count the points, once to read them), never held
/// whole: what the load holds grows by one 24-byte point per line, and a point's line is at
/// least 6 bytes ("1 2 3\n"), so reading stays within 4x the file (issue 37).
pub fn read_last_points(path: &std::path::Path) -> Result<(TriMesh, CloudFit), super::MeshError> {
    let parse = |what: String| super::MeshError::Parse {
        path: path.to_path_buf(),
        what,
    };
    let open = || {
        std::fs::File::open(path)
            .map(|f| std::io::BufReader::with_capacity(64 * 1024, f))
            .map_err(|source| super::MeshError::Io {
                path: path.to_path_buf(),
                source,
            })
    };
    let xyz = |w: String| parse(format!("a point cloud (XYZ text): {w}"));
    let (count, _) = scan_xyz(open()?, None).map_err(xyz)?;
    let (_, pts) = scan_xyz(open()?, Some(count)).map_err(xyz)?;
    last_from_points(pts).map_err(|w| parse(format!("a point cloud of a last: {w}")))
}

/// XYZ bytes made a closed mesh, as [`read_last_points`] does with a file (the fuzz
/// targets' entry).
pub fn last_from_xyz(bytes: &[u8]) -> Result<(TriMesh, CloudFit), String> {
    last_from_points(parse_xyz_bytes(bytes)?)
}

/// Reads XYZ text: three numbers per line (more columns, e.g. normals or colour, are
/// ignored), blank lines and lines starting with '#' or '//' skipped.
pub fn parse_xyz(text: &str) -> Result<Vec<P3>, String> {
    parse_xyz_bytes(text.as_bytes())
}

/// [`parse_xyz`] on bytes: counted first, so the points are allocated once at their number.
pub fn parse_xyz_bytes(bytes: &[u8]) -> Result<Vec<P3>, String> {
    let (count, _) = scan_xyz(bytes, None)?;
    Ok(scan_xyz(bytes, Some(count))?.1)
}

/// One pass over XYZ text: the number of point lines, and with `count` given (that number,
/// from a first pass) the points themselves in a Vec allocated once. A line is held at most
/// [`MAX_LINE`] bytes long, so nothing but the points grows with the input.
fn scan_xyz(
    mut r: impl std::io::BufRead,
    count: Option<usize>,
) -> Result<(usize, Vec<P3>), String> {
    use std::io::{BufRead, Read};
    let mut pts = Vec::with_capacity(count.unwrap_or(0));
    let (mut counted, mut line) = (0usize, Vec::with_capacity(256));
    for n in 1.. {
        line.clear();
        let got = r
            .by_ref()
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut line)
            .map_err(|e| format!("line {n}: {e}"))?;
        if got == 0 {
            break;
        }
        if line.len() > MAX_LINE && line.last() != Some(&b'\n') {
            return Err(format!(
                "line {n} is longer than {MAX_LINE} bytes: not a point (three numbers x y z \
                 per line)"
            ));
        }
        let l = std::str::from_utf8(&line)
            .map_err(|_| format!("line {n} is not text: not a point (three numbers x y z)"))?
            .trim();
        if l.is_empty() || l.starts_with('#') || l.starts_with("//") {
            continue;
        }
        counted += 1;
        if counted > MAX_POINTS {
            return Err(format!(
                "more than {MAX_POINTS} points: not a last's scan (thin it first)"
            ));
        }
        let Some(cap) = count else { continue };
        let mut f = l
            .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
            .filter(|s| !s.is_empty())
            .map(str::parse::<f64>);
        let mut next = || match f.next() {
            Some(Ok(v)) if v.is_finite() => Ok(v),
            _ => Err(format!(
                "line {n}: {:?} is not a point (three numbers x y z per line)",
                &l[..l.floor_char_boundary(120)]
            )),
        };
        let p = P3::new(next()?, next()?, next()?);
        if pts.len() == cap {
            return Err(format!(
                "line {n}: more points than counted (the file changed)"
            ));
        }
        pts.push(p);
    }
    // After the second pass, so that a bad line is named before the count is judged.
    if count.is_some() && counted < MIN_POINTS {
        return Err(format!(
            "{counted} points: a last's scan has thousands ({MIN_POINTS} at least)"
        ));
    }
    Ok((counted, pts))
}

/// The distance along the unit direction `d` to the plane fitted (weighted least squares)
/// to the points `near` (weight, position), when there are enough of them spread over a
/// patch and the ray does not graze the plane.
fn plane_radius(near: &[(f64, V3)], d: &V3) -> Option<f64> {
    if near.len() < 6 {
        return None;
    }
    let sw: f64 = near.iter().map(|(w, _)| w).sum();
    let m = near.iter().fold(V3::zeros(), |s, (w, p)| s + p * *w) / sw;
    let cov = near.iter().fold(nalgebra::Matrix3::zeros(), |s, (w, p)| {
        let q = p - m;
        s + q * q.transpose() * *w
    }) / sw;
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    // A patch, not a line of points: its second spread well above its thickness.
    if eig.eigenvalues[order[1]] < 4.0 * eig.eigenvalues[order[0]].max(0.0) {
        return None;
    }
    let n = eig.eigenvectors.column(order[0]).into_owned();
    let nd = n.dot(d);
    if nd.abs() < 0.2 {
        return None;
    }
    let r = n.dot(&m) / nd;
    (r > 0.0).then_some(r)
}

/// A closed mesh through `pts` (see the module documentation), and how far the points lie
/// from it.
///
/// The points are taken by value and sorted in place by direction cell, so that nothing
/// else held grows with their number (a direction per point, a cell list, the distances
/// for the 99th percentile all did: 40 bytes a point beyond the points themselves).
pub fn last_from_points(mut pts: Vec<P3>) -> Result<(TriMesh, CloudFit), String> {
    if pts.len() < MIN_POINTS {
        return Err(format!("{} points: too few for a last", pts.len()));
    }
    let n = pts.len() as f64;
    let c = pts.iter().fold(V3::zeros(), |s, p| s + p.coords) / n;
    let cov = pts.iter().fold(nalgebra::Matrix3::zeros(), |s, p| {
        let d = p.coords - c;
        s + d * d.transpose()
    }) / n;
    let eig = nalgebra::SymmetricEigen::new(cov);
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let e1 = eig.eigenvectors.column(order[0]).into_owned();
    let e2 = eig.eigenvectors.column(order[1]).into_owned();
    let e = [e1, e2, e1.cross(&e2)];
    let local = |p: &P3| {
        let d = p.coords - c;
        V3::new(d.dot(&e[0]), d.dot(&e[1]), d.dot(&e[2]))
    };
    let mut half = V3::zeros();
    for p in &pts {
        half = half.sup(&local(p).abs());
    }
    if half.min() <= 0.0 || !half.min().is_finite() {
        return Err("the points lie in a plane or a line: not a solid".into());
    }
    // A point's direction and radius in the scaled frame (None at the centre).
    let dir = |p: &P3| {
        let s = local(p).component_div(&half);
        let r = s.norm();
        (r > 1e-9).then(|| (s / r, r))
    };
    let ico = TriMesh::icosphere(P3::origin(), 1.0, LEVEL);
    let sphere: Vec<V3> = ico.vertices.iter().map(|p| p.coords.normalize()).collect();
    let faces = ico.triangles;
    let spacing = 63.43f64.to_radians() / (1 << LEVEL) as f64;
    let cone = CONE * spacing;
    let (cos_cone, sigma) = (cone.cos(), 0.5 * cone);
    // Directions bucketed on a grid over [-1, 1]^3 with cells of the cone's chord.
    let cell = 2.0 * (0.5 * cone).sin() * 2.0;
    let key = |u: &V3| {
        (
            (u.x / cell).floor() as i32,
            (u.y / cell).floor() as i32,
            (u.z / cell).floor() as i32,
        )
    };
    let key_of = |p: &P3| dir(p).map(|(u, _)| key(&u));
    // In place (an unstable sort allocates nothing); ties broken by position so the order,
    // and so every sum below, is the same on every run.
    pts.sort_unstable_by(|a, b| {
        key_of(a)
            .cmp(&key_of(b))
            .then(a.x.total_cmp(&b.x))
            .then(a.y.total_cmp(&b.y))
            .then(a.z.total_cmp(&b.z))
    });
    // Each occupied cell's run of points: at most one entry per cell of the fixed grid.
    let mut grid: HashMap<(i32, i32, i32), std::ops::Range<usize>> = HashMap::new();
    let mut start = 0;
    while start < pts.len() {
        let k = key_of(&pts[start]);
        let end = start + pts[start..].partition_point(|p| key_of(p) == k);
        if let Some(k) = k {
            grid.insert(k, start..end);
        }
        start = end;
    }
    let mut near: Vec<(f64, V3)> = Vec::new();
    let mut radius: Vec<Option<f64>> = sphere
        .iter()
        .map(|d| {
            let k = key(d);
            let mut sw = 0.0;
            near.clear();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(ids) = grid.get(&(k.0 + dx, k.1 + dy, k.2 + dz)) else {
                            continue;
                        };
                        for p in &pts[ids.clone()] {
                            let Some((u, r)) = dir(p) else { continue };
                            let cs = u.dot(d);
                            if cs >= cos_cone {
                                let a = cs.min(1.0).acos() / sigma;
                                let w = (-a * a).exp();
                                sw += w;
                                near.push((w, u * r));
                            }
                        }
                    }
                }
            }
            if sw <= 0.0 {
                return None;
            }
            // The outside only: a scan may hold inner walls (the shared scanned last has a
            // slot 8 mm wide down its forefoot), and their points, averaged in, pulled the
            // outside in by up to 10 mm.
            let rmax = near.iter().map(|(_, p)| p.norm()).fold(0.0, f64::max);
            near.retain(|(_, p)| p.norm() >= (1.0 - OUTER_BAND) * rmax);
            let (sw, sr) = near
                .iter()
                .fold((0.0, 0.0), |(a, b), (w, p)| (a + w, b + w * p.norm()));
            // The ray through the plane fitted to those points where they make a patch.
            Some(plane_radius(&near, d).unwrap_or(sr / sw))
        })
        .collect();
    drop(grid);
    // Directions no point covers: their neighbours' mean, spread until all are set.
    let filled_vertices = radius.iter().filter(|r| r.is_none()).count();
    if filled_vertices * 4 > sphere.len() {
        return Err(format!(
            "the points cover only {:.0} % of the directions round their centre: not a whole \
             last (a scan of one side, or several objects)",
            100.0 * (sphere.len() - filled_vertices) as f64 / sphere.len() as f64
        ));
    }
    let mut nbr = vec![Vec::new(); sphere.len()];
    for t in &faces {
        for k in 0..3 {
            nbr[t[k] as usize].push(t[(k + 1) % 3]);
        }
    }
    while radius.iter().any(Option::is_none) {
        let next: Vec<Option<f64>> = (0..sphere.len())
            .map(|i| {
                radius[i].or_else(|| {
                    let known: Vec<f64> =
                        nbr[i].iter().filter_map(|&j| radius[j as usize]).collect();
                    (!known.is_empty()).then(|| known.iter().sum::<f64>() / known.len() as f64)
                })
            })
            .collect();
        radius = next;
    }
    let world = |d: &V3, r: f64| {
        let s = d * r;
        P3::from(c + e[0] * (s.x * half.x) + e[1] * (s.y * half.y) + e[2] * (s.z * half.z))
    };
    let vertices: Vec<P3> = sphere
        .iter()
        .zip(&radius)
        .map(|(d, r)| world(d, r.expect("filled")))
        .collect();
    let mesh = TriMesh {
        vertices,
        triangles: faces,
    };
    let bvh = Bvh::new(&mesh);
    // Points inside the solid by more than INNER_MM are on inner walls, not on its outside.
    // One signed distance per point gives both the distance and the side (a closest point
    // and then an inside test made the same nearest-triangle search twice). The 99th
    // percentile needs only the largest 1 % of the distances: they are kept in a heap
    // (non-negative floats order as their bits do).
    let keep = pts.len() / 100 + 2;
    let mut top: BinaryHeap<Reverse<u64>> = BinaryHeap::with_capacity(keep + 1);
    let (mut inner, mut outside_max, mut outside, mut sq) = (0, 0.0f64, 0usize, 0.0f64);
    for p in &pts {
        let Some(s) = bvh.signed_distance(p) else {
            continue;
        };
        let (dist, inside) = (s.distance.abs(), s.distance < 0.0);
        if dist > INNER_MM && inside {
            inner += 1;
        } else {
            outside += 1;
            sq += dist * dist;
            top.push(Reverse(dist.to_bits()));
            if top.len() > keep {
                top.pop();
            }
        }
        if !inside {
            outside_max = outside_max.max(dist);
        }
    }
    let rms = (sq / outside.max(1) as f64).sqrt();
    // The value the sorted distances hold at rank round(0.99 (n - 1)), counted from the top.
    let p99 = if outside == 0 {
        0.0
    } else {
        let from_top = outside - 1 - ((0.99 * (outside - 1) as f64).round() as usize);
        let mut largest: Vec<u64> = top.into_iter().map(|Reverse(b)| b).collect();
        largest.sort_unstable_by(|a, b| b.cmp(a));
        f64::from_bits(largest[from_top.min(largest.len() - 1)])
    };
    Ok((
        mesh,
        CloudFit {
            points: pts.len(),
            inner_points: inner,
            rms_mm: rms,
            p99_mm: p99,
            outside_max_mm: outside_max,
            filled_vertices,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ellipsoid's points come back as a closed mesh within a fraction of their spacing.
    #[test]
    fn ellipsoid_points_make_a_closed_mesh_through_them() {
        let (a, b, c) = (130.0, 45.0, 55.0);
        let mut pts = Vec::new();
        let n = 200;
        for i in 0..n {
            for j in 0..n {
                let th = std::f64::consts::PI * (i as f64 + 0.5) / n as f64;
                let ph = 2.0 * std::f64::consts::PI * j as f64 / n as f64;
                pts.push(P3::new(
                    10.0 + a * th.cos(),
                    -3.0 + b * th.sin() * ph.cos(),
                    40.0 + c * th.sin() * ph.sin(),
                ));
            }
        }
        let (m, fit) = last_from_points(pts).unwrap();
        m.check_closed().expect("closed");
        assert!(m.volume() > 0.0, "outward");
        let v = 4.0 / 3.0 * std::f64::consts::PI * a * b * c;
        assert!(
            (m.volume() / v - 1.0).abs() < 0.01,
            "volume {} of {v}",
            m.volume()
        );
        assert!(fit.rms_mm < 0.2 && fit.outside_max_mm < 1.0, "{fit:?}");
        assert_eq!(fit.filled_vertices, 0);
    }

    #[test]
    fn bad_xyz_is_named() {
        let e = parse_xyz("# header\n1 2 3\n4 five 6\n").unwrap_err();
        assert!(e.contains("line 3") && e.contains("three numbers"), "{e}");
        let e = parse_xyz("1 2 3\n").unwrap_err();
        assert!(e.contains("1000 at least"), "{e}");
    }
}
