//! Geometry shared by the model, measurement and last stages.

mod raster;

pub use raster::HeightMap;
