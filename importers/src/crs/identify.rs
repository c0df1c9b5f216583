//! Identifying a CRS: from an EPSG code or a `.prj` WKT, its PROJ.4 definition and description.

use super::*;

/// The name of an EPSG definition, from its WKT (`PROJCS["name", …`).
fn epsg_name(code: u32) -> Option<String> {
    let def = crs_definitions::from_code(u16::try_from(code).ok()?)?;
    wkt::parse(def.wkt).and_then(|n| n.name().map(str::to_string))
}

/// The OGC WKT of EPSG code `code` (for a `.prj` file), when the registry has it.
pub fn epsg_wkt(code: u32) -> Option<&'static str> {
    crs_definitions::from_code(u16::try_from(code).ok()?).map(|d| d.wkt)
}

fn normalise(name: &str) -> String {
    name.chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_ascii_lowercase()
        .trim_start_matches('d')
        .to_string()
}

/// The datum part (`+datum=…` or `+towgs84=…`) of the first EPSG definition whose WKT datum
/// has the same name as `datum` (compared without case, spaces, `_` and ESRI's `D_` prefix) and
/// a datum shift: what PROJ would take from its database for a WKT without `TOWGS84`.
pub fn datum_shift_for(datum: &str) -> Option<String> {
    let want = normalise(datum);
    if want.is_empty() {
        return None;
    }
    (1024..=32767u16).find_map(|code| {
        let def = crs_definitions::from_code(code)?;
        // Geographic 2D definitions name the datum in their first DATUM node.
        if !def.proj4.starts_with("+proj=longlat") {
            return None;
        }
        let node = wkt::parse(def.wkt)?;
        let d = node.find("DATUM")?;
        if normalise(d.name()?) != want {
            return None;
        }
        def.proj4
            .split_whitespace()
            .find(|t| t.starts_with("+datum=") || t.starts_with("+towgs84="))
            .map(str::to_string)
    })
}

impl Crs {
    /// The PROJ string of this CRS (`None` for [`Crs::Unknown`]).
    pub fn proj4(&self) -> Option<String> {
        match self {
            Crs::Projected { proj4, .. } => Some(proj4.clone()),
            Crs::WebMercator => Some(WEB_MERCATOR.into()),
            Crs::Geographic { epsg: Some(code) } => {
                let def = u16::try_from(*code)
                    .ok()
                    .and_then(crs_definitions::from_code)
                    .map(|d| d.proj4)
                    .unwrap_or(WGS84_LONLAT);
                Some(def.into())
            }
            Crs::Geographic { epsg: None } => Some(WGS84_LONLAT.into()),
            Crs::Unknown => None,
        }
    }

    /// The CRS for an EPSG code: Web Mercator codes (3857, 900913, 3785, 102100, 102113) give
    /// [`Crs::WebMercator`]; geographic codes [`Crs::Geographic`]; projected codes
    /// [`Crs::Projected`] with the registry's name and PROJ string.
    ///
    /// # Errors
    /// [`CrsError::UnknownEpsg`] for a code that is not in the registry. A projected system
    /// whose unit is not the metre (US survey feet, say) is taken: [`Crs::metres_per_unit`]
    /// tells, and the metric frame reprojects it.
    pub fn from_epsg(code: u32) -> Result<Crs, CrsError> {
        if WEB_MERCATOR_CODES.contains(&code) {
            return Ok(Crs::WebMercator);
        }
        let def = u16::try_from(code)
            .ok()
            .and_then(crs_definitions::from_code)
            .ok_or(CrsError::UnknownEpsg { code })?;
        let name = epsg_name(code).unwrap_or_else(|| format!("EPSG:{code}"));
        let p = proj(def.proj4)?;
        if p.is_latlong() {
            return Ok(Crs::Geographic { epsg: Some(code) });
        }
        Ok(Crs::Projected {
            epsg: Some(code),
            name,
            proj4: def.proj4.to_string(),
        })
    }

    /// Recognises a WKT (WKT1 as in `.prj` files and GDAL/OGC, or WKT2) coordinate system.
    ///
    /// Web Mercator is recognised by an EPSG authority, by name (Web Mercator, Pseudo-Mercator,
    /// Mercator auxiliary sphere) or by a `Mercator_1SP` on a sphere of radius 6 378 137 m. A
    /// system with an EPSG authority takes its definition from the registry; any other is
    /// converted by `proj4wkt`, with the datum shift filled in by name when the WKT has none
    /// ([`datum_shift_for`]), and with the EPSG code inferred for UTM zones and ETRS-TM35FIN.
    ///
    /// # Errors
    /// [`CrsError::NotWkt`] when the text is not WKT, [`CrsError::UnknownEpsg`] for an authority
    /// code not in the registry, [`CrsError::WktConversion`] or [`CrsError::Projection`] for a
    /// projection `proj4rs` does not have (a unit other than the metre is taken, as in
    /// [`Crs::from_epsg`]).
    pub fn from_wkt(text: &str) -> Result<Crs, CrsError> {
        let text = text.trim().trim_start_matches('\u{feff}');
        let root = wkt::parse(text).ok_or_else(|| CrsError::NotWkt {
            why: format!(
                "expected KEYWORD[...], found {:?}",
                text.chars().take(40).collect::<String>()
            ),
        })?;
        let kw = root.keyword.to_ascii_uppercase();
        let root_epsg = root.authority_epsg();
        let name = root.name().unwrap_or("").to_string();
        match kw.as_str() {
            "PROJCS" | "PROJCRS" | "PROJECTEDCRS" => {
                if let Some(code) = root_epsg {
                    return match Crs::from_epsg(code)? {
                        Crs::Projected { epsg, proj4, .. } if !name.is_empty() => {
                            Ok(Crs::Projected { epsg, name, proj4 })
                        }
                        crs => Ok(crs),
                    };
                }
                let lname = name.to_ascii_lowercase().replace(['_', '-'], " ");
                let method = root
                    .find("PROJECTION")
                    .or_else(|| root.find("METHOD"))
                    .and_then(|n| n.name())
                    .unwrap_or("")
                    .to_ascii_lowercase()
                    .replace(['_', '-'], " ");
                let is_webmerc = lname.contains("web mercator")
                    || lname.contains("pseudo mercator")
                    || method.contains("auxiliary sphere")
                    || method.contains("pseudo mercator")
                    || (method.contains("mercator 1sp") && {
                        let ext = text.to_ascii_lowercase();
                        (ext.contains("+a=6378137") && ext.contains("+b=6378137"))
                            || ext.contains("auxiliary")
                    });
                if is_webmerc {
                    return Ok(Crs::WebMercator);
                }
                let mut proj4 =
                    proj4wkt::wkt_to_projstring(text).map_err(|e| CrsError::WktConversion {
                        name: name.clone(),
                        source: e.into(),
                    })?;
                // The linear unit (US survey feet, say) is the WKT's, whether or not the
                // conversion kept it.
                if let Some((_, factor)) = linear_unit(&root) {
                    if !(factor.is_finite() && factor > 0.0) {
                        return Err(CrsError::WktConversion {
                            name,
                            source: format!("the linear unit's factor {factor} is not a length")
                                .into(),
                        });
                    }
                    let stated = proj(&proj4).map(|p| p.to_meter()).unwrap_or(1.0);
                    if (stated - factor).abs() > 1e-12 * factor {
                        proj4 = proj4
                            .split_whitespace()
                            .filter(|t| !t.starts_with("+units=") && !t.starts_with("+to_meter="))
                            .collect::<Vec<_>>()
                            .join(" ");
                        proj4.push_str(&format!(" +to_meter={factor}"));
                    }
                }
                if !proj4.contains("+towgs84=") && !proj4.contains("+datum=") {
                    let datum = root.find("DATUM").and_then(|d| d.name()).unwrap_or("");
                    if let Some(shift) = datum_shift_for(datum) {
                        proj4.push(' ');
                        proj4.push_str(&shift);
                    }
                }
                proj(&proj4)?;
                // A UTM zone or TM35FIN in another unit is not that EPSG system.
                let metric = linear_unit(&root).is_none_or(|(_, f)| (f - 1.0).abs() <= 1e-12);
                let epsg = infer_epsg(&root, &lname, &method).filter(|_| metric);
                let name = if name.is_empty() {
                    epsg.and_then(epsg_name)
                        .unwrap_or_else(|| "unnamed projected CRS".into())
                } else {
                    name
                };
                Ok(Crs::Projected { epsg, name, proj4 })
            }
            "GEOGCS" | "GEOGCRS" | "GEOGRAPHICCRS" | "GEODCRS" => {
                if let Some(code) = root_epsg {
                    return Crs::from_epsg(code);
                }
                let datum = root.find("DATUM").and_then(|d| d.name()).unwrap_or("");
                let d = normalise(datum);
                let epsg = if d.contains("wgs1984") || d.contains("wgs84") || d.is_empty() {
                    Some(4326)
                } else {
                    // The geographic EPSG code whose datum has this name, for its datum shift.
                    (4000..=4999u16).find_map(|code| {
                        let def = crs_definitions::from_code(code)?;
                        let node = wkt::parse(def.wkt)?;
                        (normalise(node.find("DATUM")?.name()?) == d).then_some(u32::from(code))
                    })
                };
                Ok(Crs::Geographic { epsg })
            }
            other => Err(CrsError::NotWkt {
                why: format!("{other} is not a coordinate system keyword"),
            }),
        }
    }

    /// Metres per coordinate unit: 1 for metric projected systems and for Web Mercator, the
    /// unit's length for a projected system in another unit (0.3048006096 for US survey
    /// feet); `None` for geographic and unknown systems.
    pub fn metres_per_unit(&self) -> Option<f64> {
        match self {
            Crs::Projected { proj4, .. } => Some(proj(proj4).map_or(1.0, |p| p.to_meter())),
            Crs::WebMercator => Some(1.0),
            Crs::Geographic { .. } | Crs::Unknown => None,
        }
    }

    /// True for a projected system in metres, whose coordinates are used as they are.
    pub fn is_metric_projected(&self) -> bool {
        matches!(self, Crs::Projected { .. })
            && self
                .metres_per_unit()
                .is_some_and(|f| (f - 1.0).abs() <= 1e-12)
    }

    /// One short human phrase, e.g. `EPSG:3067 ETRS89 / TM35FIN`.
    pub fn describe(&self) -> String {
        match self {
            Crs::Projected {
                epsg: Some(code),
                name,
                ..
            } => format!("EPSG:{code} {name}"),
            Crs::Projected {
                epsg: None, name, ..
            } => format!("{name} (projected, no EPSG code)"),
            Crs::WebMercator => "EPSG:3857 Web Mercator".into(),
            Crs::Geographic { epsg: Some(code) } => format!("EPSG:{code} geographic lon/lat"),
            Crs::Geographic { epsg: None } => "geographic lon/lat".into(),
            Crs::Unknown => "unknown CRS".into(),
        }
    }
}

/// The linear unit of a projected WKT node, as (name, metres per unit), when it states one.
pub(super) fn linear_unit(root: &wkt::Node) -> Option<(String, f64)> {
    let unit = root
        .children()
        .find(|c| {
            c.keyword.eq_ignore_ascii_case("UNIT") || c.keyword.eq_ignore_ascii_case("LENGTHUNIT")
        })
        .or_else(|| root.find("LENGTHUNIT"))?;
    let name = unit.name()?.to_string();
    let factor = unit.number(1)?;
    Some((name, factor))
}

/// EPSG code of a projected WKT without an authority: UTM zones (by name, or by a transverse
/// Mercator with k0 = 0.9996 and false easting 500 000 on a 6° zone meridian) and ETRS-TM35FIN.
/// Only names the system: its definition is the WKT's own.
fn infer_epsg(root: &wkt::Node, lname: &str, method: &str) -> Option<u32> {
    let datum = root
        .find("DATUM")
        .and_then(|d| d.name())
        .unwrap_or("")
        .to_ascii_lowercase();
    let wgs84 = datum.contains("wgs") && datum.contains("84");
    let etrs =
        datum.contains("etrs") || datum.contains("european terrestrial") || datum.contains("euref");
    let nad83 =
        datum.contains("north american") && datum.contains("1983") || datum.contains("nad83");
    if lname.contains("tm35fin") {
        return Some(3067);
    }
    let zone_from_name = lname.find("utm zone ").and_then(|i| {
        let rest = &lname[i + 9..];
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        let zone: u32 = digits.parse().ok()?;
        let hemi = rest[digits.len()..].chars().next().unwrap_or('n');
        Some((zone, hemi != 's'))
    });
    let zone = zone_from_name.or_else(|| {
        if !method.contains("transverse mercator") {
            return None;
        }
        let param = |name: &str| {
            root.children()
                .filter(|c| c.keyword.eq_ignore_ascii_case("PARAMETER"))
                .find(|c| c.name().is_some_and(|n| n.eq_ignore_ascii_case(name)))
                .and_then(|c| c.number(1))
        };
        let cm = param("central_meridian")?;
        let k = param("scale_factor")?;
        let fe = param("false_easting")?;
        let fnorth = param("false_northing").unwrap_or(0.0);
        let z = (cm + 183.0) / 6.0;
        if (k - 0.9996).abs() > 1e-9
            || (fe - 500_000.0).abs() > 1e-6
            || (z - z.round()).abs() > 1e-9
        {
            return None;
        }
        Some((z.round() as u32, fnorth.abs() < 1e-6))
    })?;
    let (z, north) = zone;
    if !(1..=60).contains(&z) {
        return None;
    }
    if wgs84 {
        Some(if north { 32600 + z } else { 32700 + z })
    } else if etrs && north && (28..=38).contains(&z) {
        Some(25800 + z)
    } else if nad83 && north && z <= 23 {
        Some(26900 + z)
    } else {
        None
    }
}
