//! Foot landmarks and measurements (SPEC section 8).
