/// Why a calibration could not be made. Every message says what was missing or wrong and what
/// would be valid; a calibration that fails here is never written.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    #[error(
        "the plate was seen at {got} distinct height(s) ({heights}); the in-system calibration \
         needs at least {need} (eq. 20-21 solve c_x and D per row from three heights): add \
         heights to the plan"
    )]
    TooFewHeights {
        got: usize,
        need: usize,
        heights: String,
    },
    #[error("{target}: no usable rows ({detail})")]
    NoUsableRows { target: String, detail: String },
    #[error("{what} did not converge")]
    NotConverged {
        what: String,
        #[source]
        source: super::lm::LmError,
    },
    #[error("the calibration is implausible and was not kept: {0}")]
    Implausible(String),
    #[error("calibration plan: {0}")]
    Plan(String),
    #[error("camera or slider")]
    Device(#[from] footscan_hal::HalError),
    /// The scanner's devices could not be opened (the message names the device and what to
    /// try).
    #[error("opening the scanner: {0}")]
    Open(String),
    #[error("simulator: {0}")]
    Sim(String),
    #[error("OpenCV reference calibration: {0}")]
    OpenCv(String),
    #[error(
        "method `opencv` needs footscan built with the `opencv` cargo feature (on by default; \
         this build has it off)"
    )]
    OpenCvDisabled,
    #[error("cancelled")]
    Cancelled,
    /// The guided procedure stopped at a step (the operator aborted, or a check kept failing).
    #[error("calibration aborted at step {step} ({title}): {reason}")]
    Aborted {
        step: usize,
        title: String,
        reason: String,
    },
    /// The fit is worse than the configured limits allow; nothing was written.
    #[error("the calibration exceeds its limits and was not written: {0}")]
    Limits(String),
}
