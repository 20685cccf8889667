//! TODO(geometry helper G1): polygon
