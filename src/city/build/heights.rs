//! Heights from attributes: the rule of the module documentation of [`super`], and the report
//! of implausible values.

use blockwalk_importers::{AttrValue, Attributes};
use serde::Serialize;

use crate::city::model::HeightSource;

/// The tallest plausible building top, metres (the tallest building is 828 m).
pub const MAX_PLAUSIBLE_HEIGHT_M: f64 = 1000.0;

/// Field names searched, in order, for each height attribute, and the rules that turn them into
/// metres. See the module documentation of [`super`].
#[derive(Clone, Debug, PartialEq)]
pub struct HeightFields {
    /// Height in metres.
    pub height: Vec<String>,
    /// Number of storeys above ground.
    pub levels: Vec<String>,
    /// Storeys in the roof, added to `levels` when present.
    pub roof_levels: Vec<String>,
    /// Bottom of the prism in metres.
    pub min_height: Vec<String>,
    /// Bottom of the prism in storeys.
    pub min_level: Vec<String>,
    /// Metres per storey.
    pub storey_m: f64,
    /// Height when no field holds a usable value.
    pub default_height_m: f64,
}

impl Default for HeightFields {
    fn default() -> Self {
        let v = |s: &[&str]| s.iter().map(|x| x.to_string()).collect();
        HeightFields {
            height: v(&["height", "HEIGHT", "h", "Height"]),
            levels: v(&["levels", "building:levels", "LEVELS", "Levels"]),
            roof_levels: v(&["roof_lvls", "roof:levels"]),
            min_height: v(&["min_height", "MIN_HEIGHT"]),
            min_level: v(&["min_level", "building:min_level", "MIN_LEVEL"]),
            storey_m: 3.0,
            default_height_m: 9.0,
        }
    }
}

/// An attribute value that cannot be a building's height: not a number, negative, zero, or
/// above [`MAX_PLAUSIBLE_HEIGHT_M`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImplausibleHeight {
    /// The field.
    pub field: String,
    /// The value as read.
    pub value: String,
    /// What is wrong with it.
    pub why: String,
}

/// How one feature's height was decided.
#[derive(Clone, Debug, PartialEq)]
pub struct Heights {
    /// Top, metres above ground.
    pub height_m: f64,
    /// Bottom, metres above ground.
    pub min_height_m: f64,
    /// Where the top came from.
    pub source: HeightSource,
    /// Anything noteworthy (unusable values, clamping).
    pub notes: Vec<String>,
    /// Values that were present but cannot be a height (reported per building).
    pub implausible: Vec<ImplausibleHeight>,
}

/// The first of `names` that the feature has (not null): (name, value as a number or NaN).
fn first_number(attrs: &Attributes, names: &[String]) -> Option<(String, f64)> {
    names.iter().find_map(|n| match attrs.get(n) {
        None | Some(AttrValue::Null) => None,
        Some(v) => Some((n.clone(), v.as_f64().unwrap_or(f64::NAN))),
    })
}

/// True for a height in (0, [`MAX_PLAUSIBLE_HEIGHT_M`]] metres.
pub fn usable(x: f64) -> bool {
    x.is_finite() && x > 0.0 && x <= MAX_PLAUSIBLE_HEIGHT_M
}

fn raw(attrs: &Attributes, name: &str) -> String {
    match attrs.get(name) {
        Some(AttrValue::Text(s)) => format!("{s:?}"),
        Some(AttrValue::Int(i)) => i.to_string(),
        Some(AttrValue::Float(f)) => f.to_string(),
        Some(AttrValue::Bool(b)) => b.to_string(),
        Some(AttrValue::Null) | None => "null".into(),
    }
}

fn why_implausible(x: f64, what: &str) -> String {
    if !x.is_finite() {
        format!("not a number of {what}")
    } else if x < 0.0 {
        format!("negative {what}")
    } else if x == 0.0 {
        format!("zero {what}")
    } else {
        format!("{what} above {MAX_PLAUSIBLE_HEIGHT_M} m")
    }
}

/// Decides a building's heights from its attributes (see the module documentation of
/// [`super`]); implausible values are listed in [`Heights::implausible`] and the next source is
/// tried.
pub fn heights_from_attributes(attrs: &Attributes, f: &HeightFields) -> Heights {
    let mut notes = Vec::new();
    let mut implausible = Vec::new();
    let mut flag = |name: &str, why: String, notes: &mut Vec<String>| {
        notes.push(format!("unusable {name}={}: {why}", raw(attrs, name)));
        implausible.push(ImplausibleHeight {
            field: name.to_string(),
            value: raw(attrs, name),
            why,
        });
    };
    let mut chosen = None;
    if let Some((name, h)) = first_number(attrs, &f.height) {
        if usable(h) {
            chosen = Some((h, HeightSource::Height));
        } else {
            flag(&name, why_implausible(h, "height"), &mut notes);
        }
    }
    if chosen.is_none() {
        if let Some((name, l)) = first_number(attrs, &f.levels) {
            let roof = first_number(attrs, &f.roof_levels)
                .filter(|(_, r)| r.is_finite() && *r >= 0.0)
                .map(|(_, r)| r)
                .unwrap_or(0.0);
            let h = (l + roof) * f.storey_m;
            if l.is_finite() && l > 0.0 && usable(h) {
                chosen = Some((h, HeightSource::Levels));
            } else {
                flag(&name, why_implausible(h, "height from levels"), &mut notes);
            }
        }
    }
    let (height_m, source) = chosen.unwrap_or((f.default_height_m, HeightSource::Default));
    let mut min_height_m = 0.0;
    if let Some((name, m)) = first_number(attrs, &f.min_height) {
        if m.is_finite() && (0.0..=MAX_PLAUSIBLE_HEIGHT_M).contains(&m) {
            min_height_m = m;
        } else {
            flag(&name, why_implausible(m, "bottom height"), &mut notes);
        }
    } else if let Some((name, l)) = first_number(attrs, &f.min_level) {
        let m = l * f.storey_m;
        if m.is_finite() && (0.0..=MAX_PLAUSIBLE_HEIGHT_M).contains(&m) {
            min_height_m = m;
        } else {
            flag(
                &name,
                why_implausible(m, "bottom height from levels"),
                &mut notes,
            );
        }
    }
    if min_height_m >= height_m {
        notes.push(format!(
            "bottom {min_height_m} m at or above top {height_m} m: bottom clamped to 0"
        ));
        min_height_m = 0.0;
    }
    Heights {
        height_m,
        min_height_m,
        source,
        notes,
        implausible,
    }
}

/// The report key of a height source.
pub fn source_name(s: HeightSource) -> &'static str {
    match s {
        HeightSource::Height => "height",
        HeightSource::Levels => "levels",
        HeightSource::Default => "default",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attrs(kv: &[(&str, AttrValue)]) -> Attributes {
        kv.iter().map(|(k, v)| (k.to_string(), v.clone())).collect()
    }

    #[test]
    fn heights_follow_the_documented_rule() {
        let f = HeightFields::default();
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Float(12.5))]), &f);
        assert_eq!((h.height_m, h.source), (12.5, HeightSource::Height));
        assert!(h.implausible.is_empty());
        let h = heights_from_attributes(
            &attrs(&[
                ("height", AttrValue::Null),
                ("levels", AttrValue::Int(4)),
                ("roof_lvls", AttrValue::Int(1)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.source), (15.0, HeightSource::Levels));
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Text("x".into()))]), &f);
        assert_eq!((h.height_m, h.source), (9.0, HeightSource::Default));
        assert_eq!(h.notes.len(), 1);
        let h = heights_from_attributes(
            &attrs(&[
                ("levels", AttrValue::Float(2.0)),
                ("min_level", AttrValue::Int(3)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.min_height_m), (6.0, 0.0));
        assert!(h.notes[0].contains("clamped"));
        let h = heights_from_attributes(
            &attrs(&[
                ("height", AttrValue::Float(30.0)),
                ("min_height", AttrValue::Float(10.0)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.min_height_m), (30.0, 10.0));
    }

    #[test]
    fn scientific_notation_is_read_whole_and_implausible_values_are_listed() {
        let f = HeightFields::default();
        // "1e9" was once read as 1 m.
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Text("1e9".into()))]), &f);
        assert_eq!(h.source, HeightSource::Default);
        assert_eq!(h.implausible.len(), 1);
        assert_eq!(h.implausible[0].field, "height");
        assert!(
            h.implausible[0].why.contains("above 1000"),
            "{:?}",
            h.implausible
        );
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Text("1.2e1".into()))]), &f);
        assert_eq!((h.height_m, h.source), (12.0, HeightSource::Height));
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Float(-4.0))]), &f);
        assert_eq!(h.source, HeightSource::Default);
        assert!(h.implausible[0].why.contains("negative"));
        let h = heights_from_attributes(
            &attrs(&[
                ("height", AttrValue::Int(2000)),
                ("levels", AttrValue::Int(5)),
            ]),
            &f,
        );
        assert_eq!((h.height_m, h.source), (15.0, HeightSource::Levels));
        assert_eq!(h.implausible.len(), 1);
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Text("12,5".into()))]), &f);
        assert_eq!(h.height_m, 12.5);
        let h = heights_from_attributes(&attrs(&[("height", AttrValue::Text("inf".into()))]), &f);
        assert_eq!(h.source, HeightSource::Default);
        assert!(h.implausible[0].why.contains("not a number"));
    }
}
