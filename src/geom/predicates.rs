//! Robust 2D predicates (orientation, point in ring), built on the `robust` crate.
