//! Which foot. A file of its own because both the adjustment (mod.rs) and the outline rules
//! (outline.rs: which side is medial) need it, and the outline must not import the module
//! that uses it.

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Left,
    Right,
}
