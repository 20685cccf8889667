//! The printed checkerboard of the OpenCV reference calibration, and a board's pose.
//!
//! Board coordinates (u, v) in mm, inner corner (i, j) at `(i * square, j * square)`; the
//! squares cover `u in [-square, inner_cols * square]`, `v in [-square, inner_rows * square]`,
//! with a white margin of `margin_mm` around them. A [`BoardPose`] places the board in the
//! world: `P = origin + R (u, v, 0)`, `R = Rz Ry Rx` of `rotation_deg`.

use crate::{check_range, TargetError};
use footscan_geom::rotation::rotation_zyx_deg;
use serde::{Deserialize, Serialize};

/// A printed checkerboard.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Checkerboard {
    /// Inner corners along u (OpenCV's pattern width).
    pub inner_cols: u32,
    /// Inner corners along v (pattern height).
    pub inner_rows: u32,
    pub square_mm: f64,
    /// White border around the squares.
    pub margin_mm: f64,
}

impl Default for Checkerboard {
    fn default() -> Self {
        Checkerboard {
            inner_cols: 9,
            inner_rows: 6,
            square_mm: 12.0,
            margin_mm: 8.0,
        }
    }
}

impl Checkerboard {
    /// Board coordinates of every inner corner, row by row (v outer, u inner).
    pub fn corners(&self) -> Vec<[f64; 2]> {
        let s = self.square_mm;
        (0..self.inner_rows)
            .flat_map(|j| (0..self.inner_cols).map(move |i| [i as f64 * s, j as f64 * s]))
            .collect()
    }

    /// Board extent `[u0, u1] x [v0, v1]` including the margin.
    pub fn extent(&self) -> [f64; 4] {
        let (s, m) = (self.square_mm, self.margin_mm);
        [
            -s - m,
            self.inner_cols as f64 * s + m,
            -s - m,
            self.inner_rows as f64 * s + m,
        ]
    }

    /// Whether the print is black at board coordinates (square (a, b) = (floor(u / square),
    /// floor(v / square)) is black when a + b is even), None off the board. How bright black
    /// and white look is the renderer's business, not the board's.
    pub fn is_black(&self, u: f64, v: f64) -> Option<bool> {
        let [u0, u1, v0, v1] = self.extent();
        if !(u >= u0 && u <= u1 && v >= v0 && v <= v1) {
            return None;
        }
        let s = self.square_mm;
        let (a, b) = ((u / s).floor(), (v / s).floor());
        let in_squares = a >= -1.0
            && a <= self.inner_cols as f64 - 1.0
            && b >= -1.0
            && b <= self.inner_rows as f64 - 1.0;
        Some(in_squares && (a + b).rem_euclid(2.0) == 0.0)
    }

    pub fn validate(&self) -> Result<(), TargetError> {
        if self.inner_cols < 2 || self.inner_rows < 2 {
            return Err(TargetError::invalid(
                "board.inner_cols x inner_rows",
                format!("{}x{}", self.inner_cols, self.inner_rows),
                "at least 2x2 inner corners",
            ));
        }
        check_range("board.square_mm", self.square_mm, 1.0, 500.0)?;
        check_range("board.margin_mm", self.margin_mm, 0.0, 500.0)
    }
}

/// Where the board is: `P = origin + R (u, v, 0)` with `R = Rz Ry Rx` of `rotation_deg`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoardPose {
    pub origin_mm: [f64; 3],
    pub rotation_deg: [f64; 3],
}

impl BoardPose {
    /// World point of board coordinates (u, v).
    pub fn world(&self, u: f64, v: f64) -> [f64; 3] {
        let r = rotation_zyx_deg(self.rotation_deg);
        let o = self.origin_mm;
        [
            o[0] + r[0][0] * u + r[0][1] * v,
            o[1] + r[1][0] * u + r[1][1] * v,
            o[2] + r[2][0] * u + r[2][1] * v,
        ]
    }

    /// Unit normal of the board plane (board z axis) in the world.
    pub fn normal(&self) -> [f64; 3] {
        let r = rotation_zyx_deg(self.rotation_deg);
        [r[0][2], r[1][2], r[2][2]]
    }
}
