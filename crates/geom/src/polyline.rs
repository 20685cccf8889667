//! TODO(geometry helper G1): polyline
