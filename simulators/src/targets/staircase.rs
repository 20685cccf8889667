//! A staircase gauge block as a [`Surface`]: flat step faces at known heights, known step
//! lengths along the block and a known width across it, placed by the operator at a position
//! and yaw the calibration does not know. What the block is ([`StaircaseGeometry`]) and where
//! it stands ([`Placement`]) are described in `footscan_targets`, which calibration reads too;
//! this file only makes the description something the renderer can image.
//!
//! Seen from the camera below the glass, the step faces are the block's underside: the step j
//! face is at height `heights_mm[j]` over the rectangle `u in [U_j, U_j+1)`, `w in [0, W]` of
//! block coordinates, where `U_0 = 0`, `U_j+1 = U_j + lengths_mm[j]`,
//! `u = (x - x0) cos(yaw) + (y - y0) sin(yaw)` (along the block) and
//! `w = -(x - x0) sin(yaw) + (y - y0) cos(yaw)` (across it).
//!
//! The risers between steps are vertical and not part of the height field. The laser plane is
//! tilted by its pitch, so near a riser it may meet two step faces at the same y (the lower one,
//! nearest the camera, is kept, as the renderer does for folds) or none (it meets only the
//! riser face: no line in that row).

use crate::optics::{check_range, SimError};
use crate::render::Surface;
use footscan_targets::{Placement, StaircaseGeometry};

/// A staircase gauge block standing on the glass.
#[derive(Clone, Debug, PartialEq)]
pub struct Staircase {
    geometry: StaircaseGeometry,
    placement: Placement,
    cos: f64,
    sin: f64,
    /// Step starts U_0..U_n (n + 1 entries).
    starts: Vec<f64>,
    /// Step indices by ascending height (lowest face first).
    by_height: Vec<usize>,
    y_bounds: (f64, f64),
}

impl Staircase {
    pub fn new(geometry: StaircaseGeometry, placement: Placement) -> Result<Self, SimError> {
        geometry.validate()?;
        check_range("staircase.placement.x_mm", placement.x_mm, -1e4, 1e4)?;
        check_range("staircase.placement.y_mm", placement.y_mm, -1e4, 1e4)?;
        check_range(
            "staircase.placement.yaw_deg",
            placement.yaw_deg,
            -45.0,
            45.0,
        )?;
        let (sin, cos) = placement.yaw_deg.to_radians().sin_cos();
        let starts: Vec<f64> = (0..=geometry.heights_mm.len())
            .map(|j| geometry.step_start(j))
            .collect();
        let mut by_height: Vec<usize> = (0..geometry.heights_mm.len()).collect();
        by_height.sort_by(|&a, &b| geometry.heights_mm[a].total_cmp(&geometry.heights_mm[b]));
        let (len, w) = (geometry.length(), geometry.width_mm);
        let ys = [(0.0, 0.0), (len, 0.0), (0.0, w), (len, w)]
            .map(|(u, v)| placement.y_mm + u * sin + v * cos);
        let y_bounds = (
            ys.iter().copied().fold(f64::INFINITY, f64::min),
            ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        Ok(Staircase {
            geometry,
            placement,
            cos,
            sin,
            starts,
            by_height,
            y_bounds,
        })
    }

    pub fn geometry(&self) -> &StaircaseGeometry {
        &self.geometry
    }

    pub fn placement(&self) -> Placement {
        self.placement
    }

    /// Block coordinates (u along, w across) of world (x, y).
    pub fn to_block(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.placement.x_mm, y - self.placement.y_mm);
        (
            dx * self.cos + dy * self.sin,
            -dx * self.sin + dy * self.cos,
        )
    }

    /// World (x, y) of block coordinates (u, w).
    pub fn to_world(&self, u: f64, w: f64) -> (f64, f64) {
        (
            self.placement.x_mm + u * self.cos - w * self.sin,
            self.placement.y_mm + u * self.sin + w * self.cos,
        )
    }

    /// The step whose face covers world (x, y), if any.
    pub fn step_at(&self, x: f64, y: f64) -> Option<usize> {
        let (u, w) = self.to_block(x, y);
        if !(0.0..=self.geometry.width_mm).contains(&w) {
            return None;
        }
        let n = self.geometry.heights_mm.len();
        if !(u >= 0.0 && u < self.starts[n]) {
            return None;
        }
        // Few steps: a linear scan is fine.
        (0..n).find(|&j| u < self.starts[j + 1])
    }
}

impl Surface for Staircase {
    fn height(&self, x: f64, y: f64) -> Option<f64> {
        self.step_at(x, y).map(|j| self.geometry.heights_mm[j])
    }

    fn max_height(&self) -> f64 {
        self.geometry.heights_mm.iter().copied().fold(0.0, f64::max)
    }

    fn y_bounds(&self) -> (f64, f64) {
        self.y_bounds
    }

    /// Exact: the lowest step face `j` with `(x0 + tan_b h_j, y)` on that face.
    fn plane_height(&self, x0: f64, tan_b: f64, y: f64) -> Option<f64> {
        self.by_height.iter().find_map(|&j| {
            let h = self.geometry.heights_mm[j];
            (self.step_at(x0 + tan_b * h, y) == Some(j)).then_some(h)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(yaw: f64) -> Staircase {
        Staircase::new(
            StaircaseGeometry {
                heights_mm: vec![6.0, 12.0, 18.0],
                lengths_mm: vec![10.0, 10.0, 20.0],
                width_mm: 30.0,
            },
            Placement {
                x_mm: 100.0,
                y_mm: -10.0,
                yaw_deg: yaw,
            },
        )
        .unwrap()
    }

    #[test]
    fn heights_follow_the_steps_and_the_yaw() {
        let s = block(0.0);
        assert_eq!(s.height(99.9, 0.0), None);
        assert_eq!(s.height(100.1, 0.0), Some(6.0));
        assert_eq!(s.height(115.0, 0.0), Some(12.0));
        assert_eq!(s.height(139.9, 19.9), Some(18.0));
        assert_eq!(s.height(115.0, 20.1), None);
        assert_eq!(s.height(140.1, 0.0), None);
        assert_eq!(s.y_bounds(), (-10.0, 20.0));
        let r = block(30.0);
        for &(u, w, h) in &[
            (5.0, 1.0, Some(6.0)),
            (15.0, 29.0, Some(12.0)),
            (41.0, 5.0, None),
        ] {
            let (x, y) = r.to_world(u, w);
            assert_eq!(r.height(x, y), h, "u {u} w {w}");
            let (u2, w2) = r.to_block(x, y);
            assert!((u2 - u).abs() < 1e-12 && (w2 - w).abs() < 1e-12);
        }
    }

    #[test]
    fn rendered_truth_is_exact_across_risers() {
        use crate::optics::Optics;
        use crate::render::{NoiseConfig, Renderer, RowTruth, Scene};
        let o = Optics::default();
        let s = Staircase::new(
            StaircaseGeometry {
                heights_mm: vec![7.0, 14.0, 21.0],
                lengths_mm: vec![20.0; 3],
                width_mm: 60.0,
            },
            Placement {
                x_mm: 122.0,
                y_mm: -27.0,
                yaw_deg: 3.0,
            },
        )
        .unwrap();
        let r = Renderer::new(
            o.clone(),
            NoiseConfig::noise_free(),
            Scene::Surface(std::sync::Arc::new(s.clone())),
            1,
        )
        .unwrap();
        let proj = o.projector();
        let mut crossings = 0;
        // Head positions where a riser crosses the line inside the frame.
        for x in (0..60).map(|i| 66.0 + 0.1 * i as f64) {
            let t = r.truth(x);
            let mut heights = Vec::new();
            for (row, rt) in t.rows.iter().enumerate() {
                let RowTruth::Line { col, point } = rt else {
                    continue;
                };
                let img = proj.project(x, *point).unwrap();
                assert!(
                    (img[1] - row as f64).abs() < 1e-6,
                    "x {x} row {row}: {img:?}"
                );
                assert!((img[0] - col).abs() < 1e-9);
                assert_eq!(s.height(point[0], point[1]), Some(point[2]));
                // No lower face crosses this row: the lower face, nearer the camera, would win.
                for &hl in s.geometry().heights_mm.iter().filter(|&&hl| hl < point[2]) {
                    let at = |y: f64| {
                        let p = [proj.laser_x(x, y, hl), y, hl];
                        (proj.project(x, p).unwrap()[1] - row as f64, p)
                    };
                    let mut y = point[1];
                    for _ in 0..30 {
                        let (f, _) = at(y);
                        let d = (at(y + 1e-6).0 - f) / 1e-6;
                        y -= f / d;
                    }
                    let (f, p) = at(y);
                    assert!(f.abs() < 1e-6);
                    assert_ne!(
                        s.height(p[0], p[1]),
                        Some(hl),
                        "x {x} row {row}: face {} shown over face {hl}",
                        point[2]
                    );
                }
                heights.push(point[2]);
            }
            heights.dedup();
            crossings += usize::from(heights.len() > 1);
        }
        assert!(crossings > 5, "{crossings} frames with a riser");
    }

    #[test]
    fn tilted_plane_sees_the_lowest_face_and_gaps_at_risers() {
        let s = block(0.0);
        // Step faces: 6 mm on x in [100, 110), 12 on [110, 120), 18 on [120, 140).
        let tb = 0.01;
        assert_eq!(s.plane_height(115.0, tb, 0.0), Some(12.0));
        // 109.9 + 0.06 is still on the 6 mm face.
        assert_eq!(s.plane_height(109.9, tb, 0.0), Some(6.0));
        // 109.95 + 0.06 is past the riser; 109.95 + 0.12 is on the 12 mm face.
        assert_eq!(s.plane_height(109.95, tb, 0.0), Some(12.0));
        // 119.9 + 0.12 is past the next riser; 119.9 + 0.18 is on the 18 mm face.
        assert_eq!(s.plane_height(119.9, tb, 0.0), Some(18.0));
        // With the plane leaning the other way an ascending riser leaves a gap:
        // 120.15 - 0.12 is on the 18 mm face (not 12), 120.15 - 0.18 is on the 12 mm face.
        assert_eq!(s.plane_height(120.15, -tb, 0.0), None);
        assert_eq!(s.plane_height(120.25, -tb, 0.0), Some(18.0));
        // Off the block.
        assert_eq!(s.plane_height(150.0, tb, 0.0), None);
        assert!(Staircase::new(
            StaircaseGeometry {
                heights_mm: vec![1.0],
                lengths_mm: vec![],
                width_mm: 10.0
            },
            Placement {
                x_mm: 0.0,
                y_mm: 0.0,
                yaw_deg: 0.0
            }
        )
        .is_err());
    }
}
