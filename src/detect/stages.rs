//! The detectors as named pipeline stages (`detect.<name>` in `[[pipeline.stages]]`).

use super::{build, DetectParams, NAMES};
use crate::pipeline::{Node, Registry};
use crate::scan::item::Item;
use crate::scan::stages::Detect;
use crate::scan::{params, ScanContext};

fn describe(name: &str) -> &'static str {
    match name {
        "bezier" => "laser line per row, the paper's Bezier method as written (threshold, window n)",
        "bezier-plus" => "laser line per row, improved Bezier: width-sized re-centred window, bias table, continuity along the line (threshold, window_sigmas, smooth_rows, jump_px, ...)",
        "cog" => "laser line per row by thresholded centre of gravity (threshold, DN)",
        "parabolic" => "laser line per row by a 3-point parabola (threshold)",
        "gaussian" => "laser line per row by a 3-point Gaussian (log-parabola) fit (threshold)",
        "blais-rioux" => "laser line per row by the Blais-Rioux 4th-order derivative zero crossing (threshold)",
        "steger" => "laser line per row by the Gaussian-derivative zero crossing (threshold, sigma)",
        _ => "laser line detector",
    }
}

fn stage_name(name: &str) -> &'static str {
    match name {
        "bezier" => "detect.bezier",
        "bezier-plus" => "detect.bezier-plus",
        "cog" => "detect.cog",
        "parabolic" => "detect.parabolic",
        "gaussian" => "detect.gaussian",
        "blais-rioux" => "detect.blais-rioux",
        "steger" => "detect.steger",
        _ => "detect",
    }
}

pub fn register_stages(r: &mut Registry<Item, ScanContext>) {
    for name in NAMES {
        let stage = stage_name(name);
        r.register(stage, describe(name), move |p, ctx: &ScanContext| {
            let p: DetectParams = params(p)?;
            let det = build(name, &p)?;
            Ok(Node::stage(
                Detect::new(stage, det).with_tap(ctx.tap.clone()),
            ))
        });
    }
}
