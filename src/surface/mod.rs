//! The plantar surface model (SPEC section 7): the Bezier network of seed 002 and the
//! comparators of its Table 1.
