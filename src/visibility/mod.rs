//! Occlusion culling with occluder shadows and a cull map (seed 004 §3.2), and the visibility
//! oracle that checks it.
