//! Geometry shared by the model, measurement and last stages.

mod height_map;

pub use height_map::HeightMap;
