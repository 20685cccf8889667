//! TODO(geometry helper G1): bbox
