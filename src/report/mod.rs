//! Tables, plots and reports a person would rather look at than read.

pub mod plot;
