//! The detectors as named pipeline stages (`detect.<name>` in `[[pipeline.stages]]`).

use super::CogDetector;
use crate::pipeline::{Node, Registry};
use crate::scan::item::Item;
use crate::scan::stages::Detect;
use crate::scan::{params, ScanContext};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CogParams {
    #[serde(default = "default_threshold")]
    threshold: f32,
}

fn default_threshold() -> f32 {
    30.0
}

pub fn register_stages(r: &mut Registry<Item, ScanContext>) {
    r.register(
        "detect.cog",
        "laser line per row by thresholded centre of gravity (threshold, DN)",
        |p, _ctx: &ScanContext| {
            let p: CogParams = params(p)?;
            if !(p.threshold > 0.0 && p.threshold < 255.0) {
                return Err(
                    format!("threshold = {}: valid range is (0, 255) DN", p.threshold).into(),
                );
            }
            Ok(Node::stage(Detect::new(
                "detect.cog",
                Box::new(CogDetector::new(p.threshold)),
            )))
        },
    );
}
