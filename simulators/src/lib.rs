//! footscan simulator.
