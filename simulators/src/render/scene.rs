//! What stands on the glass: the scenes a renderer images.

use crate::foot::Foot;
use crate::surface::Surface;
use std::sync::Arc;

/// A flat plate of unbounded extent at a known height (calibration target; 0 = a matte sheet
/// on the glass, the reference glass line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plate {
    pub height_mm: f64,
}

impl Surface for Plate {
    fn height(&self, _x: f64, _y: f64) -> Option<f64> {
        Some(self.height_mm)
    }
    fn max_height(&self) -> f64 {
        self.height_mm
    }
    fn plane_height(&self, _x0: f64, _tan_b: f64, _y: f64) -> Option<f64> {
        Some(self.height_mm)
    }
}

/// What stands on the glass.
// Built once per renderer: the size difference of the variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Scene {
    /// Nothing: no line (a glass reflection may still be configured).
    Empty,
    Foot(Foot),
    /// A flat plate; `Plate { height_mm: 0.0 }` gives the glass line of an empty-platform pass.
    Plate {
        height_mm: f64,
    },
    /// Any other target (staircase gauge, ...).
    Surface(Arc<dyn Surface>),
}

impl Scene {
    pub(super) fn surface(&self) -> Option<Arc<dyn Surface>> {
        match self {
            Scene::Empty => None,
            Scene::Foot(f) => Some(Arc::new(f.clone())),
            Scene::Plate { height_mm } => Some(Arc::new(Plate {
                height_mm: *height_mm,
            })),
            Scene::Surface(s) => Some(s.clone()),
        }
    }
}
