//! Two lasts placed for a join by their own landmarks (docs/method.md 11.6): each is measured
//! as `footscan last measure` measures it (so a last turned in its file, with heel to toe
//! along y, mirrored, or read from OBJ or PLY is stood the same way `last adjust` stands
//! it), the sides are checked, the toe last is moved so its joint line's centre meets the
//! back last's, and the cutting planes are put behind and ahead of the joints. Planes at
//! fixed fractions of each last's length (62 % and 70 %) cross as soon as one last is about
//! 13 % longer than the other; planes tied to the joint do not.

use super::JoinError;
use crate::measure_last::{measure_last, LastMeasures};
use footscan_geom::mesh::TriMesh;
use footscan_geom::plane::Plane;
use footscan_geom::Side;
use footscan_geom::{P3, V3};

/// The back plane lies this fraction of the way from the back last's heel point to its
/// joint line's centre (0.93: about 62 % of the length on the shared lasts, the paper's
/// back plane).
pub const BACK_PLANE_OF_JOINT: f64 = 0.93;
/// The toe plane lies this fraction of the way from the toe last's joint line's centre to
/// its toe point (0.10: about 70 % of the length on the shared lasts, the paper's toe
/// plane).
pub const TOE_PLANE_OF_FOREPART: f64 = 0.10;

/// What to do when the two lasts are of different sides.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sides {
    /// Refuse the pair (a right toe on a left back is a last for no foot).
    #[default]
    Refuse,
    /// Mirror the toe last onto the back last's side first.
    MirrorToe,
}

/// Both lasts in the common frame (x heel to toe, y to the left, z up with the back last
/// standing on its tread at z = 0, the back last's heel point at x = y = 0) and the planes
/// the landmarks give.
#[derive(Clone, Debug)]
pub struct Placed {
    pub back: TriMesh,
    pub toe: TriMesh,
    pub back_measures: LastMeasures,
    pub toe_measures: LastMeasures,
    /// Default planes (normal towards the toe).
    pub back_plane: Plane,
    pub toe_plane: Plane,
    /// The toe last was mirrored onto the back last's side ([`Sides::MirrorToe`]).
    pub toe_mirrored: bool,
    /// x of the joint line's centre of both lasts in the common frame (mm).
    pub joint_x: f64,
}

fn side_name(s: Option<Side>) -> &'static str {
    s.map_or("undecided", Side::as_str)
}

/// The mesh carried into its measuring frame.
fn in_frame(m: &TriMesh, lm: &LastMeasures) -> TriMesh {
    let f = &lm.frame;
    let mat = nalgebra::Matrix4::from_fn(|i, j| f[i][j]);
    let mut out = m.clone();
    out.transform_affine(&nalgebra::Affine3::from_matrix_unchecked(mat));
    out
}

fn measure(m: &TriMesh, name: &str, which: &str) -> Result<LastMeasures, JoinError> {
    measure_last(m.clone(), name).map_err(|e| JoinError::Landmarks {
        last: format!("{which} last {name}"),
        why: footscan_util::chain(&e),
    })
}

/// Centre of the joint line (MT1 and MT5) in the measuring frame.
fn joint(lm: &LastMeasures) -> V3 {
    let (a, b) = (lm.landmarks.mt1, lm.landmarks.mt5);
    V3::new(0.5 * (a.x + b.x), 0.5 * (a.y + b.y), 0.0)
}

fn across(x: f64, y: f64) -> Plane {
    Plane::with_axis(P3::new(x, y, 0.0), V3::x(), V3::y()).expect("unit axes")
}

/// Measures both lasts, checks their sides and places them at the joint (see the module
/// notes). `back_name` and `toe_name` name the inputs in errors.
pub fn place_pair(
    back: &TriMesh,
    back_name: &str,
    toe: &TriMesh,
    toe_name: &str,
    sides: Sides,
) -> Result<Placed, JoinError> {
    let bm = measure(back, back_name, "back")?;
    let mut tm = measure(toe, toe_name, "toe")?;
    let mut toe_mesh = in_frame(toe, &tm);
    let mut toe_mirrored = false;
    if let (Some(b), Some(t)) = (bm.side, tm.side) {
        if b != t {
            match sides {
                Sides::Refuse => {
                    return Err(JoinError::Sides {
                        back: back_name.to_string(),
                        back_side: side_name(Some(b)),
                        toe: toe_name.to_string(),
                        toe_side: side_name(Some(t)),
                    })
                }
                Sides::MirrorToe => {
                    // y -> -y in the measuring frame (heel point on y = 0): the same last
                    // for the other foot, measured again for its own joint points.
                    toe_mesh.scale_about(&P3::origin(), &V3::new(1.0, -1.0, 1.0));
                    tm = measure(&toe_mesh, toe_name, "toe")?;
                    toe_mesh = in_frame(&toe_mesh, &tm);
                    toe_mirrored = true;
                }
            }
        }
    }
    let back_mesh = in_frame(back, &bm);
    let (jb, jt) = (joint(&bm), joint(&tm));
    toe_mesh.translate(&(jb - jt));
    let back_plane = across(BACK_PLANE_OF_JOINT * jb.x, jb.y);
    let toe_tip = tm.landmarks.toe_point.x + (jb.x - jt.x);
    let toe_plane = across(jb.x + TOE_PLANE_OF_FOREPART * (toe_tip - jb.x), jb.y);
    Ok(Placed {
        back: back_mesh,
        toe: toe_mesh,
        back_measures: bm,
        toe_measures: tm,
        back_plane,
        toe_plane,
        toe_mirrored,
        joint_x: jb.x,
    })
}
