//! Which foot: footscan-geom's one `Side`, re-exported where the adjustment (mod.rs) and the
//! outline rules (outline.rs: which side is medial) have always named it.

pub use footscan_geom::Side;
