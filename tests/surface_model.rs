//! The Bezier network on the simulator's analytic foot sampled like a scan: exact
//! interpolation, accuracy against the analytic surface, height map, continuity, mesh.

use footscan::surface::compare::{eval_params, representation_errors, rms, Fitted, Method};
use footscan::surface::{closed_from_heightmap, BezierNetwork, PointGrid};
use footscan_sim::foot::{Foot, FootParams};

fn foot() -> Foot {
    Foot::new(FootParams::default()).unwrap()
}

/// Frames 0.5 mm apart except a denser stretch (acceleration), rows 0.125 mm apart and, as in
/// the scanner, y scaled by (D + h) / D so it depends on the height.
fn scan_like(foot: &Foot, frame_step: f64, row_step: f64) -> PointGrid {
    let mut xs = Vec::new();
    let mut x = 100.0;
    while x < 370.0 {
        xs.push(x);
        x += if x < 120.0 {
            frame_step * 0.6
        } else {
            frame_step
        };
    }
    let nr = (130.0 / row_step) as usize;
    let mut pts = Vec::new();
    for &x in &xs {
        for j in 0..nr {
            let y0 = -60.0 + row_step * j as f64;
            // Solve y = y0 (D + h(x, y)) / D by fixed point (h varies slowly with y).
            let mut y = y0;
            let mut p = [f64::NAN; 3];
            for _ in 0..6 {
                match foot.height(x, y) {
                    Some(h) => {
                        y = y0 * (250.0 + h) / 250.0;
                        p = [x, y, h];
                    }
                    None => {
                        p = [f64::NAN; 3];
                        break;
                    }
                }
            }
            if p[0].is_finite() {
                p[2] = foot.height(x, p[1]).unwrap_or(f64::NAN);
            }
            pts.push(footscan_geom::P3::from(if p[2].is_finite() {
                p
            } else {
                [f64::NAN; 3]
            }));
        }
    }
    PointGrid::new(xs.len(), nr, pts)
}

#[test]
fn interpolates_every_grid_point_to_1e9_mm() {
    let f = foot();
    let g = scan_like(&f, 1.0, 0.5);
    let net = BezierNetwork::build(&g).unwrap();
    assert!(net.segments().len() > 1000, "{}", net.segments().len());
    assert!(net.skipped() > 0);
    let mut checked = 0;
    let mut worst: f64 = 0.0;
    for seg in net.segments() {
        let (i0, j0) = (3 * seg.a as usize, 3 * seg.b as usize);
        // Periods: 3, shorter at the grid's end.
        let (ku, kv) = ((g.nu - 1 - i0).min(3), (g.nv - 1 - j0).min(3));
        for di in 0..=ku {
            for dj in 0..=kv {
                let (i, j) = (i0 + di, j0 + dj);
                let p = seg.eval(di as f64 / ku as f64, dj as f64 / kv as f64);
                let q = g.get(i, j);
                for k in 0..3 {
                    worst = worst.max((p[k] - q[k]).abs());
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 10_000);
    assert!(worst < 1e-9, "worst interpolation error {worst} mm");
}

#[test]
fn represents_the_analytic_sole_and_its_heightmap() {
    let f = foot();
    let truth = |x: f64, y: f64| f.height(x, y);
    // Table-1-like spacing and scan resolution.
    for (frame, row, bound_mm) in [(2.9, 1.1, 0.05), (0.5, 0.125, 0.01)] {
        let g = scan_like(&f, frame, row);
        let net = BezierNetwork::build(&g).unwrap();
        let params = eval_params(&net, 4, 8);
        let fit = Fitted::Network(net);
        let e = representation_errors(&fit, &params, &truth);
        assert!(e.len() as f64 > 0.99 * params.len() as f64);
        let r = rms(&e);
        assert!(
            r < bound_mm,
            "spacing {frame} x {row}: representation RMS {r} mm"
        );
        let Fitted::Network(net) = fit else {
            unreachable!()
        };
        let m = net.eval_heightmap(0.5);
        let mut e = Vec::new();
        for j in 0..m.ny {
            for i in 0..m.nx {
                let z = m.get(i, j);
                if z.is_finite() {
                    e.push(z - truth(m.x(i), m.y(j)).expect("model cell inside the foot"));
                }
            }
        }
        assert!(e.len() > 40_000, "{} cells", e.len());
        let r = rms(&e);
        assert!(
            r < bound_mm,
            "spacing {frame} x {row}: height map RMS {r} mm"
        );
    }
}

#[test]
fn continuity_jump_is_measured_and_the_c2_spline_has_none() {
    let f = foot();
    let g = scan_like(&f, 2.9, 1.1);
    let net = BezierNetwork::build(&g).unwrap();
    let c = net.continuity(8);
    assert!(c.edges > 500);
    // Exact data on a smooth surface: the jump comes from the basis alone and is real.
    assert!(c.max_deg > 1.0 && c.mean_deg > 0.01, "{c:?}");
    assert!(c.mean_deg < 5.0, "{c:?}");
    // The interpolating C2 spline on the same grid is smooth across its knot lines.
    let Fitted::Spline(s) = Fitted::build(Method::BSplineInterp, &g).unwrap() else {
        unreachable!()
    };
    let n = |s0: f64, t0: f64| {
        let d = s.eval_d1(s0, t0);
        d.du.cross(&d.dv).normalize()
    };
    let (s0, t0) = (40.0, 60.5);
    let (l, r) = (n(s0 - 1e-9, t0), n(s0 + 1e-9, t0));
    assert!((l[0] - r[0]).abs() + (l[1] - r[1]).abs() + (l[2] - r[2]).abs() < 1e-6);
}

#[test]
fn closed_mesh_of_the_model_is_watertight() {
    let f = foot();
    let g = scan_like(&f, 1.0, 0.5);
    let net = BezierNetwork::build(&g).unwrap();
    let m = net.eval_heightmap(1.0);
    let mesh = closed_from_heightmap(&m, -2.0);
    mesh.check_closed().unwrap();
    // Volume between the sole and z = -2 over the region, against the height map's sum.
    let cells: f64 = m.z.iter().filter(|z| z.is_finite()).map(|z| z + 2.0).sum();
    let v = mesh.volume();
    assert!(
        v > 0.0 && (v - cells).abs() < 0.05 * cells,
        "{v} vs {cells}"
    );
}
