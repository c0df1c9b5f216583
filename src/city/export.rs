//! Export: glTF binary and GeoJSON.
