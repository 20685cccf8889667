//! Why a customization failed; its own file so the steps (curves, measure) and the driver
//! (mod.rs) all import it without importing each other.

#[derive(Debug, thiserror::Error)]
pub enum CustomizeError {
    #[error(transparent)]
    Mesh(#[from] footscan_geom::mesh::MeshError),
    #[error("{name}: not a foot: {why}")]
    NotAFoot { name: String, why: String },
    #[error("curve {curve}: {why}")]
    Curve { curve: String, why: String },
    #[error("curve {curve}: constraint {constraint} depends on the others (R R^T is singular); drop it or move it")]
    RankDeficient { curve: String, constraint: String },
    #[error("{why}")]
    Infeasible { why: String },
    /// The solve ended with these rules missed: (index in rule order, last minus target,
    /// mm); `why` is the whole-foot path's message.
    #[error("{why}")]
    Unmet {
        why: String,
        misses: Vec<(usize, f64)>,
    },
    #[error("{0}")]
    Rules(String),
    #[error("{path}: {why}")]
    Output { path: String, why: String },
}
