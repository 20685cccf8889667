//! TODO(geometry helper G1): triangle meshes
