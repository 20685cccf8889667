//! TODO(geometry helper G1): plane
