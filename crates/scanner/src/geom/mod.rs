//! Geometry shared by the model, measurement and last stages.

/// The plantar height map, in footscan-geom with the rest of the shared vocabulary.
pub use footscan_geom::HeightMap;
