//! Tables, plots and reports a person would rather look at than read.
//!
//! - [`plot`]: line and scatter plots to PNG / SVG.
//! - [`walk`]: the walk benchmark (seed 003 §5.1): per-frame CSV, Table 1, Fig. 4, frames, HTML.

pub mod plot;
pub mod walk;
