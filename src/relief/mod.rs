//! Multi-level relief impostors: the second far field (its tree so far) (Andujar, Brunet, Chica and Navazo,
//! *Visualization of Large-Scale Urban Models through Multi-Level Relief Impostors*, Computer
//! Graphics Forum 29(8), 2010).
//!
//! - [`tree`]: the object-space quaternary tree over buildings (§3, §4.1): buildings closer than a
//!   gap merged first, each building group sent to a child by its barycentre so that no group is
//!   ever cut, the overlap ratio δ of formula (1) per level, and formulas (3)–(9) evaluated
//!   against the built tree ([`tree::Formulas`]).

pub mod tree;

pub use tree::{Formulas, LevelStats, ReliefNode, ReliefTree, TreeError, TreeParams, TreeReport};
