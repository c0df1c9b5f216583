//! Validation and repair of footprint rings and polygons.
