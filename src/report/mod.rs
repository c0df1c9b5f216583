//! Tables, plots and reports a person would rather look at than read.
//!
//! - [`plot`]: line and scatter plots to PNG / SVG.
//! - [`walk`]: writes a walk's records (Pina, Serón and Cerezo, §5.1): per-frame CSV, Table 1, Fig. 4, frames,
//!   JSON, HTML. This module only writes: the walk itself is [`crate::walk`].
//! - [`sweep`]: writes a far-field sweep ([`crate::walk::sweep`]): its table, the Pareto plot of
//!   error against frame time, the walk reports of one configuration per route, the diagnoses.

pub mod plot;
pub mod stream;
pub mod sweep;
pub mod walk;
