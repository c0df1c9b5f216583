//! Scripted camera routes (seed 003 §5).
