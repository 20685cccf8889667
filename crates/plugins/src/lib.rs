//! Stages from outside the binary: WebAssembly modules run in-process by wasmtime
//! ([`wasm`]), behind the same stage contract as the built-in stages.
//!
//! This crate knows nothing of frames, pipelines or configs: it loads a plugin, checks it
//! against the ABI, runs it under limits and turns everything it does wrong into a
//! [`PluginError`] that names the plugin. The scanner wraps it in its `wasm` stage; the wasm
//! runtime's dependencies live here alone so no other crate pays for them.
//!
//! The ABI, the limits and the examples are in docs/plugins.md.

pub mod exec;
pub mod rows;
pub mod wasm;

/// Why a plugin could not be used. Every message starts with the plugin (its file) so a
/// failed scan or a refused config names the culprit.
#[derive(Debug, thiserror::Error)]
pub enum PluginError {
    /// Refused at start: the file does not load, exports the wrong functions, imports what it
    /// was not granted, or refuses a parameter.
    #[error("plugin {plugin}: {reason}")]
    Load { plugin: String, reason: String },
    /// Went wrong while running: a trap, the fuel or memory limit, an output the ABI forbids.
    #[error("plugin {plugin} {what}")]
    Fault { plugin: String, what: String },
}

impl PluginError {
    pub fn plugin(&self) -> &str {
        match self {
            Self::Load { plugin, .. } | Self::Fault { plugin, .. } => plugin,
        }
    }
}
