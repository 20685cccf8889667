//! Why a join failed: a file of its own because the join (mod.rs) and its steps (sections.rs,
//! ...) all return it, and a step must not import the module that calls it.

use footscan_geom::nurbs::NurbsError;

/// Why a join failed. Every variant names the last, plane or section at fault.
#[derive(Debug, thiserror::Error)]
pub enum JoinError {
    #[error(
        "{last} last: the {plane} misses it (no section); move the plane inside the last \
         (--back-plane / --toe-plane: X mm from the heel, P% of the last's length, or \
         ox,oy,oz,nx,ny,nz)"
    )]
    PlaneMisses { last: String, plane: String },
    #[error(
        "{last} last: the {plane} cuts it into {loops} loops; a joining plane must cut the \
         last in one closed loop (move it away from the ends and the top: --back-plane / \
         --toe-plane)"
    )]
    ManyLoops {
        last: String,
        plane: String,
        loops: usize,
    },
    #[error(
        "the lasts do not overlap in length: back last spans x {back_lo:.1}..{back_hi:.1} mm, \
         toe last {toe_lo:.1}..{toe_hi:.1} mm; place them in one frame first"
    )]
    NoOverlap {
        back_lo: f64,
        back_hi: f64,
        toe_lo: f64,
        toe_hi: f64,
    },
    #[error(
        "the toe plane ({toe}) is not ahead of the back plane ({back}) along the back plane's \
         normal: the gap would be {gap:.1} mm; the toe part must start where the back part ends \
         (give --back-plane and --toe-plane further apart: X mm from the heel, P% of the \
         last's length, or ox,oy,oz,nx,ny,nz; without them the planes are placed behind and \
         ahead of the joints)"
    )]
    PlanesOverlap { back: String, toe: String, gap: f64 },
    #[error(
        "the back last {back} is a {back_side} last and the toe last {toe} a {toe_side} last: \
         their join would fit no foot; give two lasts of one side, or pass --mirror-toe to \
         mirror the toe last onto the back last's side"
    )]
    Sides {
        back: String,
        back_side: &'static str,
        toe: String,
        toe_side: &'static str,
    },
    #[error(
        "the {last} last is {length_mm:.1} mm long, not a last's size ({lo:.0}-{hi:.0} mm): a \
         last in millimetres read as metres is 1000 times too long (check the units)",
        lo = crate::size::LAST_LENGTH_MM.0,
        hi = crate::size::LAST_LENGTH_MM.1
    )]
    NotALast { last: &'static str, length_mm: f64 },
    #[error("{last}: its landmarks cannot be found for the join ({why})")]
    Landmarks { last: String, why: String },
    #[error("section {section} cannot be aligned: {reason}")]
    NotAligned { section: String, reason: String },
    #[error("invalid parameter {name} = {value}: {valid}")]
    Param {
        name: &'static str,
        value: String,
        valid: &'static str,
    },
    #[error("surface construction failed")]
    Nurbs(#[from] NurbsError),
}
