//! GRBL slider driver (placeholder until the driver lands).
