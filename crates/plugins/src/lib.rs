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
pub mod wasi;
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

/// The values a per-scan stage reports: one `key value` per line (blank lines and lines
/// starting with `#` ignored), keys of 1-64 of `[a-z0-9_]`, values finite numbers. The
/// error names the line and what would be valid.
pub fn parse_values(report: &[u8]) -> Result<Vec<(String, f64)>, String> {
    let text = std::str::from_utf8(report).map_err(|_| {
        "reported bytes that are not UTF-8 text; report `key value` lines".to_string()
    })?;
    let mut out: Vec<(String, f64)> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let (Some(key), Some(value), None) = (words.next(), words.next(), words.next()) else {
            return Err(format!(
                "reported line {} {line:?}; each line must be `key value`",
                n + 1
            ));
        };
        let key_ok = !key.is_empty()
            && key.len() <= 64
            && key
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
        if !key_ok {
            return Err(format!(
                "reported the key {key:?} on line {}; keys are 1-64 of a-z, 0-9 and _",
                n + 1
            ));
        }
        let v: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                format!(
                    "reported {key} = {value:?} on line {}; values must be finite numbers",
                    n + 1
                )
            })?;
        if out.iter().any(|(k, _)| k == key) {
            return Err(format!("reported {key} twice (line {})", n + 1));
        }
        out.push((key.to_string(), v));
    }
    Ok(out)
}
