//! The `wasm` and `exec` stages' detector: a WebAssembly module or an external process
//! (crate `footscan-plugins`) seen through the same [`LinePeak`] rows as the built-in detectors, so triangulation, the live
//! preview and the archive cannot tell them apart.
//!
//! Unlike [`crate::detect::Detector`], a plugin can fail on any frame (a trap, a limit, output
//! the ABI forbids); the failure ends the scan with the plugin's own reason.

use crate::detect::{LinePeak, Reject};
use crate::pipeline::BoxError;
use footscan_hal::{Frame, Pixels};
use footscan_plugins::exec::ExecDetector;
use footscan_plugins::wasm::{self, RowOut, WasmDetector};

enum Inner {
    Wasm(WasmDetector),
    Exec(ExecDetector),
}

/// A plugin's detector, with its output buffer kept between frames.
pub struct PluginDetector {
    inner: Inner,
    rows: Vec<RowOut>,
}

const REJECTS: [Reject; 5] = [
    Reject::BelowThreshold,
    Reject::Saturated,
    Reject::Ambiguous,
    Reject::Border,
    Reject::Isolated,
];

impl PluginDetector {
    pub fn new(inner: WasmDetector) -> Self {
        Self::with(Inner::Wasm(inner))
    }

    pub fn exec(inner: ExecDetector) -> Self {
        Self::with(Inner::Exec(inner))
    }

    fn with(inner: Inner) -> Self {
        // The ABI's codes 1..=5 are these rejects in this order (docs/plugins.md).
        debug_assert_eq!(wasm::REJECT_CODES[1..].len(), REJECTS.len());
        Self {
            inner,
            rows: Vec::new(),
        }
    }

    /// Fill `out` (one per row of `frame`) or fail naming the plugin.
    pub fn detect(&mut self, frame: &Frame, out: &mut [LinePeak]) -> Result<(), BoxError> {
        let px = match &frame.pixels {
            Pixels::Gray8(p) => wasm::Pixels::Gray8(p),
            Pixels::Gray16(p) => wasm::Pixels::Gray16(p),
        };
        self.rows.resize(out.len(), EMPTY);
        match &mut self.inner {
            Inner::Wasm(d) => d.detect(frame.width, frame.height, px, &mut self.rows)?,
            Inner::Exec(d) => d.detect(frame.width, frame.height, px, &mut self.rows)?,
        }
        for (o, r) in out.iter_mut().zip(&self.rows) {
            *o = match r.reject {
                0 => LinePeak {
                    col: r.col,
                    intensity: r.intensity,
                    width: r.width,
                    quality: r.quality,
                    reject: None,
                },
                code => LinePeak::rejected(REJECTS[code as usize - 1], r.intensity),
            };
        }
        Ok(())
    }
}

const EMPTY: RowOut = RowOut {
    col: f64::NAN,
    intensity: 0.0,
    width: 0.0,
    quality: 0.0,
    reject: 1,
};
