//! Geometric invariants as property tests: triangulation and projection invert each other,
//! the plantar model passes through its grid points, and the scan grid survives grid.bin.

use footscan::detect::{LinePeak, Reject};
use footscan::scan::{LoadedConfig, ScanGrid};
use footscan::scandata::{FrameMeta, FramePoints};
use footscan::surface::{BezierNetwork, PointGrid};
use footscan_hal::Timestamp;
use proptest::prelude::*;
use std::path::Path;

/// The simulator's true camera model (config/sim.toml): a realistic tilt and distortion.
fn sim_model() -> footscan::calib::CameraModel {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml");
    let cfg = LoadedConfig::load(&path).expect("config/sim.toml");
    footscan::scan::sim::true_calibration(&cfg.config).model
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any pixel of the image at any slider position triangulates to a point that projects
    /// back onto the same pixel (to 1e-6 px).
    #[test]
    fn triangulation_inverts_projection(
        u in 0.02f64..0.98,
        v in 0.02f64..0.98,
        x in -50.0f64..350.0,
    ) {
        let m = sim_model();
        let (col, row) = (u * m.width as f64, v * m.height as f64);
        let tri = m.triangulator();
        if let Some(p) = tri.point(x, col, row) {
            prop_assert!(p.iter().all(|c| c.is_finite()));
            let q = m.project(x, p).expect("a triangulated point is in front of the camera");
            prop_assert!(
                (q[0] - col).abs() < 1e-6 && (q[1] - row).abs() < 1e-6,
                "({col}, {row}) at x = {x} -> {p:?} -> {q:?}"
            );
        }
    }

    /// The Bezier network interpolates: at integer parameters it returns its grid points
    /// (to 1e-9 mm), on any smooth height field over any positive grid spacing.
    #[test]
    fn interpolation_passes_its_points(
        nu in 2usize..14,
        nv in 2usize..14,
        dx in 0.2f64..3.0,
        dy in 0.1f64..2.0,
        a in -0.5f64..0.5,
        b in -0.5f64..0.5,
        w in 0.05f64..0.6,
    ) {
        let xs: Vec<f64> = (0..nu).map(|i| i as f64 * dx).collect();
        let ys: Vec<f64> = (0..nv).map(|j| j as f64 * dy).collect();
        let g = PointGrid::sample(
            |x, y| Some(5.0 + a * x + b * y + (w * x).sin() * (w * y).cos()),
            &xs,
            &ys,
        );
        let n = BezierNetwork::build(&g).unwrap();
        for i in 0..nu {
            for j in 0..nv {
                let p = n.eval(i as f64, j as f64).expect("a full grid has every segment");
                let q = g.get(i, j);
                for k in 0..3 {
                    prop_assert!((p[k] - q[k]).abs() < 1e-9, "({i}, {j}): {p:?} vs {q:?}");
                }
            }
        }
    }

    /// Whatever the frames, lines and points (NaN for no line), grid.bin reads back the same
    /// grid bit for bit.
    #[test]
    fn scan_grid_round_trips_through_grid_bin(
        rows in 1usize..6,
        cells in prop::collection::vec(
            (
                prop::option::of(-1e4f64..1e4),
                0.0f32..65535.0,
                0.0f32..40.0,
                0.0f32..1.0,
                0u8..5,
                prop::array::uniform3(-1e3f64..1e3),
            ),
            0..40,
        ),
        seq0 in 0u64..1_000_000,
        t0 in 0u64..u64::MAX / 2,
    ) {
        let frames = cells.len() / rows;
        let mut g = ScanGrid::new(rows);
        for f in 0..frames {
            let mut lines = Vec::new();
            let mut points = Vec::new();
            for (col, intensity, width, quality, reject, p) in &cells[f * rows..(f + 1) * rows] {
                let reject = match reject {
                    0 => None,
                    1 => Some(Reject::BelowThreshold),
                    2 => Some(Reject::Saturated),
                    3 => Some(Reject::Ambiguous),
                    _ => Some(Reject::Border),
                };
                lines.push(LinePeak {
                    col: col.unwrap_or(f64::NAN),
                    intensity: *intensity,
                    width: *width,
                    quality: *quality,
                    reject,
                });
                points.push(footscan_geom::P3::from(if col.is_some() { *p } else { [f64::NAN; 3] }));
            }
            g.push(FramePoints {
                meta: FrameMeta {
                    index: f as u64,
                    seq: seq0 + 2 * f as u64,
                    timestamp: Timestamp { nanos: t0 + 1_000_000 * f as u64 },
                    x_mm: 0.1 * f as f64 - 3.0,
                },
                lines,
                points,
            });
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grid.bin");
        g.save(&path).unwrap();
        let h = ScanGrid::load(&path).unwrap();
        prop_assert_eq!(h.rows, g.rows);
        prop_assert_eq!(&h.frames, &g.frames);
        prop_assert_eq!(h.lines.len(), g.lines.len());
        for (a, b) in h.lines.iter().zip(&g.lines) {
            prop_assert_eq!(a.col.to_bits(), b.col.to_bits());
            prop_assert_eq!(
                (a.intensity, a.width, a.quality, a.reject),
                (b.intensity, b.width, b.quality, b.reject)
            );
        }
        for (a, b) in h.points.iter().zip(&g.points) {
            prop_assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits));
        }
    }
}
