//! Property tests of the mesh layer: sections, file round trips, signed distance.

use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::plane::Plane;
use footscan_geom::polygon::Polygon;
use footscan_geom::{P3, V3};
use nalgebra::{Matrix3, Rotation3};
use proptest::prelude::*;
use std::path::Path;

/// A random ellipsoid (convex): an icosphere under a random linear map and shift.
fn ellipsoid(axes: [f64; 3], rot: [f64; 3], shift: [f64; 3], levels: u32) -> TriMesh {
    let mut m = TriMesh::icosphere(P3::origin(), 1.0, levels);
    let r = Rotation3::from_scaled_axis(V3::from(rot));
    let a = r.matrix() * Matrix3::from_diagonal(&V3::from(axes));
    for p in &mut m.vertices {
        *p = P3::from(a * p.coords + V3::from(shift));
    }
    m
}

/// A star-shaped, non-convex closed mesh with vertices on a 1 mm grid, so that planes at
/// whole millimetres pass exactly through many vertices.
fn lumpy(seed: u64) -> TriMesh {
    let mut m = TriMesh::icosphere(P3::origin(), 1.0, 2);
    let mut x = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    for p in &mut m.vertices {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let r = 20.0 + ((x >> 33) % 9) as f64;
        *p = P3::from((p.coords * r).map(f64::round));
    }
    m
}

fn check_sections(m: &TriMesh, plane: &Plane) -> Result<(), TestCaseError> {
    let loops = m.section(plane);
    let mut area = 0.0;
    for l in &loops {
        prop_assert!(l.closed, "open loop of {} points", l.len());
        prop_assert!(l.len() >= 3);
        let d = l.max_plane_distance(plane);
        prop_assert!(d <= 1e-9, "section point {d} mm off its plane");
        // Consecutive points differ (no zero-length segments).
        for i in 0..l.len() {
            prop_assert!(l.points[i] != l.points[(i + 1) % l.len()]);
        }
        area += l.to_polygon(plane).signed_area();
    }
    // Material on the left: the total signed area (outer minus holes) is positive.
    prop_assert!(loops.is_empty() || area > 0.0, "section area {area}");
    Ok(())
}

/// CI found this one: the plane y = 27 touches the lumpy solid from outside along a path of
/// on-plane edges, which gave a zero-area loop (the path and back) instead of no loop.
#[test]
fn plane_touching_along_a_path_of_edges_gives_no_loop() {
    let m = lumpy(6930683967020432615);
    assert!(m.check().is_ok());
    let plane = Plane::axis_aligned(1, 27.0);
    let on_plane = m
        .vertices
        .iter()
        .filter(|p| plane.signed_distance(p) == 0.0)
        .count();
    assert!(
        on_plane >= 3,
        "the case needs a path of on-plane vertices ({on_plane})"
    );
    for pl in [plane, plane.flipped()] {
        for l in m.section(&pl) {
            let a = l.to_polygon(&pl).signed_area();
            assert!(a > 0.0, "loop of {} points with area {a}", l.len());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn convex_sections_are_single_closed_loops_on_the_plane(
        axes in prop::array::uniform3(5.0f64..150.0),
        rot in prop::array::uniform3(-3.0f64..3.0),
        shift in prop::array::uniform3(-500.0f64..500.0),
        levels in 1u32..4,
        at in prop::array::uniform3(-1.0f64..1.0),
        normal in prop::array::uniform3(-1.0f64..1.0),
        through_vertex in any::<bool>(),
        vi in any::<prop::sample::Index>(),
    ) {
        let m = ellipsoid(axes, rot, shift, levels);
        let b = m.bbox();
        let origin = if through_vertex {
            m.vertices[vi.index(m.vertices.len())]
        } else {
            b.center() + b.extent().component_mul(&V3::from(at)) * 0.5
        };
        let Some(plane) = Plane::new(origin, V3::from(normal)) else { return Ok(()) };
        check_sections(&m, &plane)?;
        prop_assert!(m.section(&plane).len() <= 1, "a convex solid has one section loop");
    }

    #[test]
    fn sections_through_grid_vertices_close(seed in any::<u64>(), axis in 0usize..3, k in -30i32..30) {
        let m = lumpy(seed);
        prop_assume!(m.check().is_ok());
        let plane = Plane::axis_aligned(axis, k as f64);
        check_sections(&m, &plane)?;
        check_sections(&m, &plane.flipped())?;
        // Both sides of the plane see the same region.
        let a: f64 = m.section(&plane).iter().map(|l| l.to_polygon(&plane).signed_area()).sum();
        let f = plane.flipped();
        let b: f64 = m.section(&f).iter().map(|l| l.to_polygon(&f).signed_area()).sum();
        // Moving the plane infinitesimally up or down can differ only where faces lie in it.
        let any_face_in_plane = (0..m.triangles.len()).any(|t| {
            m.corners(t).iter().all(|p| plane.signed_distance(p) == 0.0)
        });
        if !any_face_in_plane {
            prop_assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn files_round_trip_exactly(
        axes in prop::array::uniform3(0.001f64..300.0),
        rot in prop::array::uniform3(-3.0f64..3.0),
        shift in prop::array::uniform3(-1e4f64..1e4),
    ) {
        let m = ellipsoid(axes, rot, shift, 1);
        let p = Path::new("mem");
        // PLY and OBJ keep vertex order: the identical mesh.
        prop_assert_eq!(&TriMesh::parse_ply(&m.to_ply(false), p).unwrap(), &m);
        prop_assert_eq!(&TriMesh::parse_ply(&m.to_ply(true), p).unwrap(), &m);
        prop_assert_eq!(&TriMesh::parse_obj(m.to_obj().as_bytes(), p).unwrap(), &m);
        // STL has no shared vertices: the same corners per triangle. ASCII is exact for any
        // f64; binary stores f32, exact for f32 coordinates.
        let (a, _) = TriMesh::parse_stl(m.to_stl_ascii("t").as_bytes(), p).unwrap();
        prop_assert_eq!(a.triangles.len(), m.triangles.len());
        for t in 0..m.triangles.len() {
            prop_assert_eq!(a.corners(t), m.corners(t));
        }
        let mut m32 = m.clone();
        for q in &mut m32.vertices {
            *q = q.map(|c| c as f32 as f64);
        }
        let (b, _) = TriMesh::parse_stl(&m32.to_stl_binary(), p).unwrap();
        prop_assert_eq!(b.vertices.len(), m32.vertices.len());
        for t in 0..m.triangles.len() {
            prop_assert_eq!(b.corners(t), m32.corners(t));
        }
    }

    #[test]
    fn box_signed_distance_is_analytic(
        lo in prop::array::uniform3(-50.0f64..0.0),
        size in prop::array::uniform3(1.0f64..80.0),
        q in prop::array::uniform3(-120.0f64..120.0),
    ) {
        let min = P3::from(lo);
        let max = min + V3::from(size);
        let m = TriMesh::cuboid(min, max);
        let bvh = Bvh::new(&m);
        let p = P3::from(q);
        // Analytic signed distance of a box.
        let c = nalgebra::center(&min, &max);
        let h = (max - min) / 2.0;
        let d = (p - c).abs() - h;
        let truth = d.map(|x| x.max(0.0)).norm() + d.max().min(0.0);
        let s = bvh.signed_distance(&p).unwrap();
        prop_assert!((s.distance - truth).abs() <= 1e-9, "{} vs {truth}", s.distance);
    }

    #[test]
    fn sphere_signed_distance_sign_and_size(
        q in prop::array::uniform3(-60.0f64..60.0),
        c in prop::array::uniform3(-10.0f64..10.0),
    ) {
        let r = 30.0;
        let centre = P3::from(c);
        let m = TriMesh::icosphere(centre, r, 4);
        // The polyhedron lies between the sphere and the sphere shrunk by `gap`.
        let gap = r - (0..m.triangles.len())
            .map(|t| {
                let pl = Plane::from_points(m.corners(t)[0], m.corners(t)[1], m.corners(t)[2]).unwrap();
                -pl.signed_distance(&centre)
            })
            .fold(f64::INFINITY, f64::min);
        let bvh = Bvh::new(&m);
        let p = P3::from(q);
        let analytic = (p - centre).norm() - r;
        let s = bvh.signed_distance(&p).unwrap();
        prop_assert!(s.distance >= analytic - 1e-9 && s.distance <= analytic + gap + 1e-9,
            "{} vs sphere {analytic}, gap {gap}", s.distance);
        if analytic < -gap {
            prop_assert!(s.distance < 0.0 && bvh.contains(&p));
        } else if analytic > 0.0 {
            prop_assert!(s.distance > 0.0 && !bvh.contains(&p));
        }
        // Rays from the centre leave through the surface between r - gap and r.
        let dir = (p - centre).try_normalize(1e-9).unwrap_or(V3::x());
        let hit = bvh.ray_cast(&centre, &dir, f64::INFINITY).unwrap();
        prop_assert!(hit.t <= r + 1e-9 && hit.t >= r - gap - 1e-9 && !hit.front);
    }
}

#[test]
fn convex_hull_of_section_matches_for_a_convex_solid() {
    let m = ellipsoid([40.0, 20.0, 10.0], [0.3, 0.2, 0.1], [0.0; 3], 3);
    let plane = Plane::new(P3::new(1.0, 2.0, 0.5), V3::new(0.2, 0.1, 1.0)).unwrap();
    let l = m.section(&plane);
    assert_eq!(l.len(), 1);
    let poly: Polygon = l[0].to_polygon(&plane);
    assert!((poly.convex_hull().area() - poly.area()).abs() < 1e-9 * poly.area());
}
