//! Planes: a point and a unit normal, with a right-handed 2D frame for sections.

use crate::{P2, P3, V3};

/// An oriented plane through `origin` with unit `normal`. Its positive side is where the
/// normal points. The local frame (`u`, `v`, `normal`) is right-handed, so a loop that is
/// counterclockwise in local (u, v) coordinates turns positively about the normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub origin: P3,
    pub normal: V3,
    /// First in-plane axis (unit).
    pub u: V3,
    /// Second in-plane axis, `normal x u` (unit).
    pub v: V3,
}

impl Plane {
    /// The plane through `origin` with normal `normal` (any length, not zero); None for a zero
    /// or non-finite normal. The in-plane axis `u` is the world axis least aligned with the
    /// normal, made orthogonal to it, so the frame is stable for axis-aligned planes
    /// (normal +z gives u = +x, v = +y).
    pub fn new(origin: P3, normal: V3) -> Option<Plane> {
        let n = normal.try_normalize(0.0)?;
        if !n.iter().all(|c| c.is_finite()) || !origin.iter().all(|c| c.is_finite()) {
            return None;
        }
        let a = n.abs();
        let seed = if a.x <= a.y && a.x <= a.z {
            V3::x()
        } else if a.y <= a.z {
            V3::y()
        } else {
            V3::z()
        };
        let u = (seed - n * n.dot(&seed)).normalize();
        let v = n.cross(&u);
        Some(Plane {
            origin,
            normal: n,
            u,
            v,
        })
    }

    /// The plane with the given frame: `u` is made orthogonal to the normal; None when `u` is
    /// (nearly) parallel to the normal.
    pub fn with_axis(origin: P3, normal: V3, u: V3) -> Option<Plane> {
        let n = normal.try_normalize(0.0)?;
        let u = (u - n * n.dot(&u)).try_normalize(1e-12)?;
        Some(Plane {
            origin,
            normal: n,
            u,
            v: n.cross(&u),
        })
    }

    /// The plane through three points, normal `(b - a) x (c - a)` (counterclockwise seen from
    /// the positive side); None when they are collinear.
    pub fn from_points(a: P3, b: P3, c: P3) -> Option<Plane> {
        let n = (b - a).cross(&(c - a));
        if n.norm() <= 1e-12 * (b - a).norm().max((c - a).norm()).powi(2) {
            return None;
        }
        Plane::with_axis(a, n, b - a)
    }

    /// The plane `axis = value` (axis 0, 1, 2 for x, y, z), normal along +axis.
    pub fn axis_aligned(axis: usize, value: f64) -> Plane {
        let mut o = P3::origin();
        o[axis] = value;
        let mut n = V3::zeros();
        n[axis] = 1.0;
        Plane::new(o, n).expect("unit axis normal")
    }

    /// Signed distance of `p`, positive on the side the normal points to.
    pub fn signed_distance(&self, p: &P3) -> f64 {
        self.normal.dot(&(p - self.origin))
    }

    /// Orthogonal projection of `p` onto the plane.
    pub fn project(&self, p: &P3) -> P3 {
        p - self.normal * self.signed_distance(p)
    }

    /// Local 2D coordinates of the projection of `p`.
    pub fn to_local(&self, p: &P3) -> P2 {
        let d = p - self.origin;
        P2::new(d.dot(&self.u), d.dot(&self.v))
    }

    /// The point of the plane at local coordinates `q`.
    pub fn to_world(&self, q: &P2) -> P3 {
        self.origin + self.u * q.x + self.v * q.y
    }

    /// The same plane with the normal reversed (and `v` reversed, keeping the frame right-handed).
    pub fn flipped(&self) -> Plane {
        Plane {
            origin: self.origin,
            normal: -self.normal,
            u: self.u,
            v: -self.v,
        }
    }

    /// The parameter t where the line `o + t d` meets the plane; None when parallel.
    pub fn intersect_line(&self, o: &P3, d: &V3) -> Option<f64> {
        let den = self.normal.dot(d);
        if den == 0.0 {
            return None;
        }
        Some(-self.signed_distance(o) / den)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_right_handed_and_round_trips() {
        let p = Plane::new(P3::new(1.0, 2.0, 3.0), V3::new(0.3, -0.5, 0.8)).unwrap();
        assert!((p.u.cross(&p.v) - p.normal).norm() < 1e-15);
        let q = P3::new(4.0, -1.0, 7.0);
        let back = p.to_world(&p.to_local(&q));
        assert!((back - p.project(&q)).norm() < 1e-12);
        assert!(p.signed_distance(&p.project(&q)).abs() < 1e-12);
        let z = Plane::axis_aligned(2, 5.0);
        assert_eq!((z.u, z.v), (V3::x(), V3::y()));
        assert_eq!(z.signed_distance(&P3::new(9.0, 9.0, 7.0)), 2.0);
        let t = Plane::from_points(P3::origin(), P3::new(1.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.0));
        assert_eq!(t.unwrap().normal, V3::z());
        assert!(
            Plane::from_points(P3::origin(), P3::new(1.0, 0.0, 0.0), P3::new(2.0, 0.0, 0.0))
                .is_none()
        );
        assert!(Plane::new(P3::origin(), V3::zeros()).is_none());
        let f = p.flipped();
        assert!((f.u.cross(&f.v) - f.normal).norm() < 1e-15);
        assert_eq!(
            z.intersect_line(&P3::origin(), &V3::new(0.0, 0.0, 2.0)),
            Some(2.5)
        );
    }
}
