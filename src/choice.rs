//! Enums chosen by name: the structures, the occlusion, buildings and far-field modes.
//!
//! Each such enum implements [`Choice`] (its names, one per value, and a line of help per value)
//! and [`std::str::FromStr`] through it, so a front end can list the valid names and parse them
//! without knowing the enums; an unknown name is refused with a [`ChoiceError`] that lists the
//! valid ones.

/// An enum whose values are chosen by name.
pub trait Choice: Copy + Sized + 'static {
    /// What the value chooses, for messages (`"occlusion mode"`).
    const WHAT: &'static str;
    /// Every value, in the order they are listed.
    const ALL: &'static [Self];
    /// The value's name (what parses back into it).
    fn name(self) -> &'static str;
    /// One line saying what the value does.
    fn help(self) -> &'static str;

    /// The value called `name`.
    ///
    /// # Errors
    /// [`ChoiceError`] (naming [`Choice::WHAT`], the name and the valid names) when no value is
    /// called `name`.
    fn from_name(name: &str) -> Result<Self, ChoiceError> {
        Self::ALL
            .iter()
            .copied()
            .find(|c| c.name() == name)
            .ok_or_else(|| ChoiceError {
                what: Self::WHAT,
                value: name.to_string(),
                valid: Self::ALL.iter().map(|c| c.name()).collect(),
            })
    }
}

/// A name that is none of an enum's values.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} '{value}': expected one of {}", valid.join(", "))]
pub struct ChoiceError {
    /// What the value chooses (`"occlusion mode"`).
    pub what: &'static str,
    /// The name given.
    pub value: String,
    /// The valid names.
    pub valid: Vec<&'static str>,
}

/// Implements [`Choice`], [`std::str::FromStr`] and [`std::fmt::Display`] (the name) for an
/// enum: `choices!(Type, "what", Variant => "name", "help"; …)`.
macro_rules! choices {
    ($ty:ty, $what:literal, $($variant:ident => $name:literal, $help:literal;)+) => {
        impl $crate::choice::Choice for $ty {
            const WHAT: &'static str = $what;
            const ALL: &'static [Self] = &[$(<$ty>::$variant),+];
            fn name(self) -> &'static str {
                match self {
                    $(<$ty>::$variant => $name,)+
                }
            }
            fn help(self) -> &'static str {
                match self {
                    $(<$ty>::$variant => $help,)+
                }
            }
        }

        impl ::std::str::FromStr for $ty {
            type Err = $crate::choice::ChoiceError;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                <$ty as $crate::choice::Choice>::from_name(s)
            }
        }

        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.pad($crate::choice::Choice::name(*self))
            }
        }
    };
}
pub(crate) use choices;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::index::Structure;
    use crate::scene::BuildingsMode;
    use crate::walk::{FarMode, OcclusionMode};

    fn round_trip<T: Choice + std::str::FromStr + PartialEq + std::fmt::Debug>() {
        for &c in T::ALL {
            assert_eq!(T::from_name(c.name()), Ok(c));
            assert!(!c.help().is_empty());
        }
    }

    #[test]
    fn every_name_parses_back() {
        round_trip::<Structure>();
        round_trip::<OcclusionMode>();
        round_trip::<BuildingsMode>();
        round_trip::<FarMode>();
        assert_eq!("scenegraph".parse::<Structure>(), Ok(Structure::SceneGraph));
        assert_eq!(Structure::Bqr.to_string(), "bqr");
    }

    #[test]
    fn an_unknown_name_lists_the_valid_ones() {
        let e = "sometimes".parse::<OcclusionMode>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown occlusion mode 'sometimes': expected one of off, on, auto"
        );
        let e = "BQR".parse::<Structure>().unwrap_err();
        assert_eq!(
            e.valid,
            ["none", "flat", "vamsplit", "bqr", "rstar", "scenegraph"]
        );
    }
}
