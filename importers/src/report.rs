//! The import report: every feature read is accounted for.

use serde::Serialize;

/// A feature the importer could not turn into geometry, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Refusal {
    /// The feature's id in its file ([`crate::Feature::fid`]).
    pub fid: u64,
    /// Why it was refused, in words a user understands.
    pub reason: String,
}

/// What one reader did with one file.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ImportReport {
    /// Records found in the file.
    pub read: usize,
    /// Features handed on in [`crate::Layer::features`].
    pub imported: usize,
    /// Features refused, with reasons.
    pub refused: Vec<Refusal>,
    /// Things the reader noticed that concern the whole layer (CRS found, fields missing, …).
    pub notes: Vec<String>,
}

impl ImportReport {
    /// Records a refused feature.
    pub fn refuse(&mut self, fid: u64, reason: impl Into<String>) {
        self.refused.push(Refusal {
            fid,
            reason: reason.into(),
        });
    }
}
