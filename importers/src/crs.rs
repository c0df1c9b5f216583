//! Coordinate reference systems and the transform to a metric ground frame.
//!
//! A [`Crs`] is recognised from a WKT text ([`Crs::from_wkt`]: a Shapefile `.prj`, a GeoPackage
//! `gpkg_spatial_ref_sys.definition`) or from an EPSG code ([`Crs::from_epsg`]). Only what
//! blockwalk needs is kept: is it true ground metres (projected), Web Mercator, or geographic
//! degrees.
//!
//! [`Crs::metric_transform`] builds the map to ground metres. Projected and unknown systems are
//! used as they are. Web Mercator is first inverted to WGS84 longitude/latitude on its sphere
//! (R = 6 378 137 m, EPSG:3857 guidance note 7-2 §1.3.3.2), then, like geographic coordinates,
//! projected with a transverse Mercator on the WGS84 ellipsoid centred on the data (Krüger
//! series to order n⁶, in the form given by Karney, "Transverse Mercator with an accuracy of a few
//! nanometers", J. Geodesy 85 (2011), eqs. 7–11, 35–36). The central meridian and the origin
//! latitude are the data centre, the scale factor is 1 and there is no false easting/northing,
//! so metric coordinates are small around the data and scale error is below 1e-7 within 3 km.

use serde::Serialize;

/// A coordinate reference system, as far as blockwalk needs to know it.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Crs {
    /// A projected CRS in metres whose units are true ground metres up to the projection's small
    /// scale error (UTM, ETRS-TM35FIN, national grids): used as it is.
    Projected {
        /// EPSG code when known.
        epsg: Option<u32>,
        /// Human-readable name.
        name: String,
    },
    /// Web Mercator (EPSG:3857 / 900913): metres on the projection, 1/cos(latitude) too long on
    /// the ground.
    WebMercator,
    /// Geographic longitude/latitude in degrees (WGS84 / EPSG:4326, OSM, RFC 7946 GeoJSON).
    Geographic {
        /// EPSG code when known.
        epsg: Option<u32>,
    },
    /// No CRS information was found; coordinates are taken as metres.
    Unknown,
}

/// WGS84 semi-major axis (m), also the radius of the Web Mercator sphere.
const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// Maps a layer's own coordinates to a metric ground frame and back.
///
/// For a projected CRS this is the identity. For Web Mercator and geographic coordinates it is a
/// local transverse Mercator projection (WGS84) centred on the data, so that distances and areas
/// are true ground metres.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MetricTransform {
    /// The CRS it maps from.
    pub crs: Crs,
    /// Longitude/latitude (degrees) of the local projection's centre, for non-projected CRS.
    pub center_lonlat: Option<[f64; 2]>,
    /// The local transverse Mercator, when the transform is not the identity.
    #[serde(skip)]
    tm: Option<LocalTm>,
}

impl MetricTransform {
    /// Layer coordinates → metric ground coordinates.
    ///
    /// Projected/unknown: the identity. Web Mercator: inverse spherical Mercator, then the local
    /// transverse Mercator. Geographic (lon, lat in degrees): the local transverse Mercator.
    pub fn to_metric(&self, p: [f64; 2]) -> [f64; 2] {
        match (&self.crs, &self.tm) {
            (Crs::WebMercator, Some(tm)) => {
                let [lon, lat] = web_mercator_to_lonlat(p);
                tm.forward(lon, lat)
            }
            (Crs::Geographic { .. }, Some(tm)) => tm.forward(p[0], p[1]),
            _ => p,
        }
    }

    /// Metric ground coordinates → layer coordinates (inverse of [`Self::to_metric`]).
    pub fn from_metric(&self, p: [f64; 2]) -> [f64; 2] {
        match (&self.crs, &self.tm) {
            (Crs::WebMercator, Some(tm)) => {
                let [lon, lat] = tm.inverse(p);
                lonlat_to_web_mercator([lon, lat])
            }
            (Crs::Geographic { .. }, Some(tm)) => tm.inverse(p),
            _ => p,
        }
    }

    /// True when [`Self::to_metric`] is the identity.
    pub fn is_identity(&self) -> bool {
        self.tm.is_none()
    }

    /// One line for the summary: what CRS was found and what was done with it.
    pub fn describe(&self) -> String {
        let centre = self
            .center_lonlat
            .map(|[lon, lat]| format_lonlat(lon, lat))
            .unwrap_or_default();
        match &self.crs {
            Crs::WebMercator => {
                let lat = self.center_lonlat.map(|c| c[1]).unwrap_or(0.0);
                let k = 1.0 / lat.to_radians().cos();
                format!(
                    "EPSG:3857 Web Mercator: reprojected to a local transverse Mercator at \
                     {centre} (ground metres; Mercator units are {k:.2}× too long here)"
                )
            }
            Crs::Geographic { .. } => format!(
                "{}: projected to a local transverse Mercator at {centre} (ground metres)",
                self.crs.describe()
            ),
            Crs::Projected { .. } => {
                format!(
                    "{}: projected metres, used as they are",
                    self.crs.describe()
                )
            }
            Crs::Unknown => "no CRS found: coordinates taken as metres, used as they are".into(),
        }
    }
}

fn format_lonlat(lon: f64, lat: f64) -> String {
    let ns = if lat >= 0.0 { 'N' } else { 'S' };
    let ew = if lon >= 0.0 { 'E' } else { 'W' };
    format!("{:.3}°{ns} {:.3}°{ew}", lat.abs(), lon.abs())
}

/// Web Mercator (x, y) → WGS84 (lon, lat) in degrees, on the sphere of radius a
/// (EPSG guidance note 7-2, "Popular Visualisation Pseudo Mercator", reverse case).
pub fn web_mercator_to_lonlat(p: [f64; 2]) -> [f64; 2] {
    let lon = (p[0] / WGS84_A).to_degrees();
    let lat = (p[1] / WGS84_A).sinh().atan().to_degrees();
    [lon, lat]
}

/// WGS84 (lon, lat) in degrees → Web Mercator (x, y) (forward case of the same formula).
pub fn lonlat_to_web_mercator(p: [f64; 2]) -> [f64; 2] {
    let x = WGS84_A * p[0].to_radians();
    let y = WGS84_A * p[1].to_radians().tan().asinh();
    [x, y]
}

/// A transverse Mercator on the WGS84 ellipsoid with k0 = 1, central meridian `lon0` and the
/// northing measured from latitude `lat0` (Karney 2011, Krüger series to order n⁶).
#[derive(Clone, Debug, PartialEq)]
struct LocalTm {
    lon0: f64,
    /// Rectifying radius A (Karney eq. 14).
    a_rect: f64,
    /// First eccentricity.
    e: f64,
    alpha: [f64; 6],
    beta: [f64; 6],
    /// Northing of the origin latitude on the central meridian, subtracted from every y.
    y0: f64,
}

impl LocalTm {
    fn new(lon0: f64, lat0: f64) -> Self {
        let f = WGS84_F;
        let n = f / (2.0 - f);
        let (n2, n3) = (n * n, n * n * n);
        let (n4, n5, n6) = (n2 * n2, n2 * n3, n3 * n3);
        let a_rect = WGS84_A / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0 + n6 / 256.0);
        // Karney 2011 eq. 35.
        let alpha = [
            n / 2.0 - 2.0 * n2 / 3.0 + 5.0 * n3 / 16.0 + 41.0 * n4 / 180.0 - 127.0 * n5 / 288.0
                + 7891.0 * n6 / 37800.0,
            13.0 * n2 / 48.0 - 3.0 * n3 / 5.0 + 557.0 * n4 / 1440.0 + 281.0 * n5 / 630.0
                - 1983433.0 * n6 / 1935360.0,
            61.0 * n3 / 240.0 - 103.0 * n4 / 140.0
                + 15061.0 * n5 / 26880.0
                + 167603.0 * n6 / 181440.0,
            49561.0 * n4 / 161280.0 - 179.0 * n5 / 168.0 + 6601661.0 * n6 / 7257600.0,
            34729.0 * n5 / 80640.0 - 3418889.0 * n6 / 1995840.0,
            212378941.0 * n6 / 319334400.0,
        ];
        // Karney 2011 eq. 36.
        let beta = [
            n / 2.0 - 2.0 * n2 / 3.0 + 37.0 * n3 / 96.0 - n4 / 360.0 - 81.0 * n5 / 512.0
                + 96199.0 * n6 / 604800.0,
            n2 / 48.0 + n3 / 15.0 - 437.0 * n4 / 1440.0 + 46.0 * n5 / 105.0
                - 1118711.0 * n6 / 3870720.0,
            17.0 * n3 / 480.0 - 37.0 * n4 / 840.0 - 209.0 * n5 / 4480.0 + 5569.0 * n6 / 90720.0,
            4397.0 * n4 / 161280.0 - 11.0 * n5 / 504.0 - 830251.0 * n6 / 7257600.0,
            4583.0 * n5 / 161280.0 - 108847.0 * n6 / 3991680.0,
            20648693.0 * n6 / 638668800.0,
        ];
        let e = (f * (2.0 - f)).sqrt();
        let mut tm = LocalTm {
            lon0,
            a_rect,
            e,
            alpha,
            beta,
            y0: 0.0,
        };
        tm.y0 = tm.forward(lon0, lat0)[1];
        tm
    }

    /// (lon, lat) degrees → (x, y) metres.
    fn forward(&self, lon: f64, lat: f64) -> [f64; 2] {
        let phi = lat.to_radians();
        let mut dl = lon - self.lon0;
        if dl > 180.0 {
            dl -= 360.0;
        } else if dl < -180.0 {
            dl += 360.0;
        }
        let lam = dl.to_radians();
        // Conformal latitude as tan χ (Karney eqs. 7–9).
        let s = phi.sin();
        let t = (s.atanh() - self.e * (self.e * s).atanh()).sinh();
        let xi_p = t.atan2(lam.cos());
        let eta_p = (lam.sin() / (1.0 + t * t).sqrt()).atanh();
        let mut xi = xi_p;
        let mut eta = eta_p;
        for (j, a) in self.alpha.iter().enumerate() {
            let k = 2.0 * (j + 1) as f64;
            xi += a * (k * xi_p).sin() * (k * eta_p).cosh();
            eta += a * (k * xi_p).cos() * (k * eta_p).sinh();
        }
        [self.a_rect * eta, self.a_rect * xi - self.y0]
    }

    /// (x, y) metres → (lon, lat) degrees.
    fn inverse(&self, p: [f64; 2]) -> [f64; 2] {
        let xi = (p[1] + self.y0) / self.a_rect;
        let eta = p[0] / self.a_rect;
        let mut xi_p = xi;
        let mut eta_p = eta;
        for (j, b) in self.beta.iter().enumerate() {
            let k = 2.0 * (j + 1) as f64;
            xi_p -= b * (k * xi).sin() * (k * eta).cosh();
            eta_p -= b * (k * xi).cos() * (k * eta).sinh();
        }
        let sh = eta_p.sinh();
        let c = xi_p.cos();
        let tau_p = xi_p.sin() / (sh * sh + c * c).sqrt();
        let lam = sh.atan2(c);
        // Newton iteration for tan φ from the conformal tan χ (Karney eqs. 19–21).
        let e2 = self.e * self.e;
        let mut tau = tau_p;
        for _ in 0..8 {
            let s1 = (1.0 + tau * tau).sqrt();
            let sigma = (self.e * (self.e * tau / s1).atanh()).sinh();
            let tau_i = tau * (1.0 + sigma * sigma).sqrt() - sigma * s1;
            let d = (tau_p - tau_i) / (1.0 + tau_i * tau_i).sqrt() * (1.0 + (1.0 - e2) * tau * tau)
                / ((1.0 - e2) * s1);
            tau += d;
            if d.abs() < 1e-15 * tau.abs().max(1.0) {
                break;
            }
        }
        [self.lon0 + lam.to_degrees(), tau.atan().to_degrees()]
    }
}

impl Crs {
    /// Builds the transform to metric ground coordinates for data centred at `center` (in this
    /// CRS's own coordinates).
    ///
    /// A centre that is not finite, or a latitude beyond ±89°, is clamped so that the transform is
    /// always defined (such data are not city data anyway).
    pub fn metric_transform(&self, center: [f64; 2]) -> MetricTransform {
        let lonlat = match self {
            Crs::WebMercator => Some(web_mercator_to_lonlat(center)),
            Crs::Geographic { .. } => Some(center),
            Crs::Projected { .. } | Crs::Unknown => None,
        };
        let lonlat = lonlat.map(|[lon, lat]| {
            let lon = if lon.is_finite() { lon } else { 0.0 };
            let lon = (lon + 180.0).rem_euclid(360.0) - 180.0;
            let lat = if lat.is_finite() { lat } else { 0.0 };
            [lon, lat.clamp(-89.0, 89.0)]
        });
        MetricTransform {
            crs: self.clone(),
            center_lonlat: lonlat,
            tm: lonlat.map(|[lon, lat]| LocalTm::new(lon, lat)),
        }
    }

    /// The CRS for an EPSG code. Web Mercator codes (3857, 900913, 3785, 102100, 102113) give
    /// [`Crs::WebMercator`]; geographic 2D codes (4326, 4258, 4269, and the 4000–4999 block) give
    /// [`Crs::Geographic`]; every other code is taken as a projected CRS in metres.
    pub fn from_epsg(code: u32) -> Crs {
        match code {
            3857 | 900913 | 3785 | 102100 | 102113 => Crs::WebMercator,
            4000..=4999 => Crs::Geographic { epsg: Some(code) },
            _ => Crs::Projected {
                epsg: Some(code),
                name: epsg_name(code),
            },
        }
    }

    /// Recognises a WKT (WKT1 as in `.prj` files and GDAL/OGC, or WKT2) coordinate system.
    ///
    /// Web Mercator is recognised by an EPSG authority, by name (Web Mercator, Pseudo-Mercator,
    /// Mercator auxiliary sphere) or by a `Mercator_1SP` projection on a sphere of radius
    /// 6 378 137 m. Any other `PROJCS` is [`Crs::Projected`], with the EPSG code from its
    /// `AUTHORITY`, or inferred for UTM zones and ETRS-TM35FIN. A lone `GEOGCS` is
    /// [`Crs::Geographic`]. Returns `None` when the text is not WKT at all.
    pub fn from_wkt(text: &str) -> Option<Crs> {
        let root = wkt::parse(text)?;
        let kw = root.keyword.to_ascii_uppercase();
        let root_epsg = root.authority_epsg();
        match kw.as_str() {
            "PROJCS" | "PROJCRS" | "PROJECTEDCRS" => {
                if let Some(code) = root_epsg {
                    if let Crs::WebMercator = Crs::from_epsg(code) {
                        return Some(Crs::WebMercator);
                    }
                }
                let name = root.name().unwrap_or("").to_string();
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
                    return Some(Crs::WebMercator);
                }
                let epsg = root_epsg.or_else(|| infer_epsg(&root, &lname, &method));
                let name = if name.is_empty() {
                    epsg.map(epsg_name)
                        .unwrap_or_else(|| "unnamed projected CRS".into())
                } else {
                    name
                };
                Some(Crs::Projected { epsg, name })
            }
            "GEOGCS" | "GEOGCRS" | "GEOGRAPHICCRS" | "GEODCRS" => {
                let epsg = root_epsg.or_else(|| {
                    let datum = root.find("DATUM").and_then(|d| d.name()).unwrap_or("");
                    let d = datum.to_ascii_lowercase();
                    (d.contains("wgs_1984") || d.contains("wgs 1984") || d.contains("wgs84"))
                        .then_some(4326)
                });
                Some(Crs::Geographic { epsg })
            }
            _ => None,
        }
    }

    /// One short human phrase, e.g. `EPSG:3067 ETRS89 / TM35FIN`.
    pub fn describe(&self) -> String {
        match self {
            Crs::Projected {
                epsg: Some(code),
                name,
            } => format!("EPSG:{code} {name}"),
            Crs::Projected { epsg: None, name } => format!("{name} (projected, no EPSG code)"),
            Crs::WebMercator => "EPSG:3857 Web Mercator".into(),
            Crs::Geographic { epsg: Some(code) } => format!("EPSG:{code} geographic lon/lat"),
            Crs::Geographic { epsg: None } => "geographic lon/lat".into(),
            Crs::Unknown => "unknown CRS".into(),
        }
    }
}

/// The linear unit of a projected WKT, as (name, metres per unit), when it states one.
pub(crate) fn wkt_linear_unit(text: &str) -> Option<(String, f64)> {
    let root = wkt::parse(text)?;
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

fn epsg_name(code: u32) -> String {
    match code {
        3067 => "ETRS89 / TM35FIN(E,N)".into(),
        32601..=32660 => format!("WGS 84 / UTM zone {}N", code - 32600),
        32701..=32760 => format!("WGS 84 / UTM zone {}S", code - 32700),
        25828..=25838 => format!("ETRS89 / UTM zone {}N", code - 25800),
        26901..=26923 => format!("NAD83 / UTM zone {}N", code - 26900),
        5514 => "S-JTSK / Krovak East North".into(),
        2154 => "RGF93 v1 / Lambert-93".into(),
        27700 => "OSGB36 / British National Grid".into(),
        _ => format!("EPSG:{code}"),
    }
}

/// EPSG code of a projected WKT without an authority: UTM zones (by name, or by a transverse
/// Mercator with k0 = 0.9996 and false easting 500 000 on a 6° zone meridian) and ETRS-TM35FIN.
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

/// A small WKT tree parser: `KEYWORD[item, item, ...]` where an item is a quoted string, a
/// number, a bare word or a nested node. Accepts `[]` and `()` brackets.
mod wkt {
    #[derive(Debug)]
    pub(super) enum Item {
        Text(String),
        Word(String),
        Node(Node),
    }

    #[derive(Debug)]
    pub(super) struct Node {
        pub keyword: String,
        pub items: Vec<Item>,
    }

    impl Node {
        pub fn name(&self) -> Option<&str> {
            match self.items.first() {
                Some(Item::Text(s)) => Some(s),
                _ => None,
            }
        }
        /// The `i`-th item as a number.
        pub fn number(&self, i: usize) -> Option<f64> {
            match self.items.get(i) {
                Some(Item::Word(w)) | Some(Item::Text(w)) => w.trim().parse().ok(),
                _ => None,
            }
        }
        pub fn children(&self) -> impl Iterator<Item = &Node> {
            self.items.iter().filter_map(|i| match i {
                Item::Node(n) => Some(n),
                _ => None,
            })
        }
        /// Depth-first search for the first node with this keyword.
        pub fn find(&self, keyword: &str) -> Option<&Node> {
            for c in self.children() {
                if c.keyword.eq_ignore_ascii_case(keyword) {
                    return Some(c);
                }
                if let Some(n) = c.find(keyword) {
                    return Some(n);
                }
            }
            None
        }
        /// The EPSG code of this node's own `AUTHORITY["EPSG","n"]` or `ID["EPSG",n]`.
        pub fn authority_epsg(&self) -> Option<u32> {
            self.children()
                .filter(|c| {
                    c.keyword.eq_ignore_ascii_case("AUTHORITY")
                        || c.keyword.eq_ignore_ascii_case("ID")
                })
                .find(|c| c.name().is_some_and(|n| n.eq_ignore_ascii_case("EPSG")))
                .and_then(|c| match c.items.get(1) {
                    Some(Item::Text(s)) | Some(Item::Word(s)) => s.trim().parse().ok(),
                    _ => None,
                })
        }
    }

    pub(super) fn parse(text: &str) -> Option<Node> {
        let chars: Vec<char> = text.trim().trim_start_matches('\u{feff}').chars().collect();
        let mut pos = 0;
        let node = parse_node(&chars, &mut pos, 0)?;
        Some(node)
    }

    fn skip_ws(c: &[char], pos: &mut usize) {
        while *pos < c.len() && c[*pos].is_whitespace() {
            *pos += 1;
        }
    }

    fn parse_node(c: &[char], pos: &mut usize, depth: usize) -> Option<Node> {
        if depth > 64 {
            return None;
        }
        skip_ws(c, pos);
        let start = *pos;
        while *pos < c.len() && (c[*pos].is_ascii_alphanumeric() || c[*pos] == '_') {
            *pos += 1;
        }
        if *pos == start {
            return None;
        }
        let keyword: String = c[start..*pos].iter().collect();
        skip_ws(c, pos);
        if *pos >= c.len() || !(c[*pos] == '[' || c[*pos] == '(') {
            return None;
        }
        *pos += 1;
        let mut items = Vec::new();
        loop {
            skip_ws(c, pos);
            if *pos >= c.len() {
                return None;
            }
            match c[*pos] {
                ']' | ')' => {
                    *pos += 1;
                    break;
                }
                ',' => *pos += 1,
                '"' => {
                    *pos += 1;
                    let mut s = String::new();
                    loop {
                        if *pos >= c.len() {
                            return None;
                        }
                        if c[*pos] == '"' {
                            // A doubled quote is an escaped quote.
                            if *pos + 1 < c.len() && c[*pos + 1] == '"' {
                                s.push('"');
                                *pos += 2;
                                continue;
                            }
                            *pos += 1;
                            break;
                        }
                        s.push(c[*pos]);
                        *pos += 1;
                    }
                    items.push(Item::Text(s));
                }
                _ => {
                    // A nested node or a bare word (number, enumeration value).
                    let save = *pos;
                    let mut p2 = *pos;
                    while p2 < c.len() && (c[p2].is_ascii_alphanumeric() || c[p2] == '_') {
                        p2 += 1;
                    }
                    let mut p3 = p2;
                    skip_ws(c, &mut p3);
                    if p2 > save && p3 < c.len() && (c[p3] == '[' || c[p3] == '(') {
                        items.push(Item::Node(parse_node(c, pos, depth + 1)?));
                    } else {
                        let mut w = String::new();
                        while *pos < c.len() && !matches!(c[*pos], ',' | ']' | ')') {
                            w.push(c[*pos]);
                            *pos += 1;
                        }
                        items.push(Item::Word(w.trim().to_string()));
                    }
                }
            }
        }
        Some(Node { keyword, items })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BUBENEC_PRJ: &str = r#"PROJCS["WGS_1984_Web_Mercator_Auxiliary_Sphere",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Mercator_Auxiliary_Sphere"],PARAMETER["False_Easting",0.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",0.0],PARAMETER["Standard_Parallel_1",0.0],PARAMETER["Auxiliary_Sphere_Type",0.0],UNIT["Meter",1.0]]"#;
    const UTM33_PRJ: &str = r#"PROJCS["WGS_1984_UTM_Zone_33N",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",15.0],PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]"#;
    const TM35_PRJ: &str = r#"PROJCS["EUREF-FIN_TM35FIN",GEOGCS["GCS_EUREF_FIN",DATUM["EUREF-FIN",SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",27.0],PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]"#;
    const OGC_3857: &str = r#"PROJCS["WGS 84 / Pseudo-Mercator",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Mercator_1SP"],PARAMETER["central_meridian",0],PARAMETER["scale_factor",1],PARAMETER["false_easting",0],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],EXTENSION["PROJ4","+proj=merc +a=6378137 +b=6378137 +lat_ts=0 +lon_0=0 +x_0=0 +y_0=0 +k=1 +units=m +nadgrids=@null +wktext +no_defs"]]"#;

    #[test]
    fn recognises_the_bundled_prj_files() {
        assert_eq!(Crs::from_wkt(BUBENEC_PRJ), Some(Crs::WebMercator));
        assert_eq!(Crs::from_wkt(OGC_3857), Some(Crs::WebMercator));
        assert_eq!(
            Crs::from_wkt(UTM33_PRJ),
            Some(Crs::Projected {
                epsg: Some(32633),
                name: "WGS_1984_UTM_Zone_33N".into()
            })
        );
        assert!(matches!(
            Crs::from_wkt(TM35_PRJ),
            Some(Crs::Projected {
                epsg: Some(3067),
                ..
            })
        ));
        assert_eq!(wkt_linear_unit(TM35_PRJ), Some(("Meter".to_string(), 1.0)));
    }

    #[test]
    fn geographic_and_authority_and_garbage() {
        let g = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;
        assert_eq!(Crs::from_wkt(g), Some(Crs::Geographic { epsg: Some(4326) }));
        let p = r#"PROJCS["Some grid",GEOGCS["x",DATUM["y",SPHEROID["z",1,2]]],PROJECTION["Lambert_Conformal_Conic_2SP"],UNIT["metre",1],AUTHORITY["EPSG","2154"]]"#;
        assert_eq!(
            Crs::from_wkt(p),
            Some(Crs::Projected {
                epsg: Some(2154),
                name: "Some grid".into()
            })
        );
        assert_eq!(Crs::from_wkt("not a wkt"), None);
        assert_eq!(Crs::from_wkt("PROJCS[\"unterminated\""), None);
        assert_eq!(Crs::from_epsg(3857), Crs::WebMercator);
        assert_eq!(Crs::from_epsg(4326), Crs::Geographic { epsg: Some(4326) });
        assert_eq!(
            Crs::from_epsg(32633).describe(),
            "EPSG:32633 WGS 84 / UTM zone 33N"
        );
    }

    /// The textbook spherical formula, written independently: lat = 2·atan(e^(y/R)) − π/2.
    #[test]
    fn web_mercator_known_point() {
        let (x, y) = (1_603_599.221, 6_464_369.816);
        let r = 6_378_137.0_f64;
        let lon = x / r * 180.0 / std::f64::consts::PI;
        let lat = (2.0 * (y / r).exp().atan() - std::f64::consts::FRAC_PI_2) * 180.0
            / std::f64::consts::PI;
        let [lo, la] = web_mercator_to_lonlat([x, y]);
        assert!((lo - lon).abs() < 1e-12 && (la - lat).abs() < 1e-12);
        // Prague Bubeneč is near 14.40°E 50.10°N.
        assert!(
            (lo - 14.405).abs() < 0.01 && (la - 50.104).abs() < 0.01,
            "{lo} {la}"
        );
        let back = lonlat_to_web_mercator([lo, la]);
        assert!((back[0] - x).abs() < 1e-6 && (back[1] - y).abs() < 1e-6);
    }

    /// On the central meridian, northing from the equator is the meridian arc; 1° of latitude at
    /// 50°N is 111 229.0 m on WGS84 (meridian arc series, Bowring's table).
    #[test]
    fn tm_meridian_arc_and_scale() {
        let tm = LocalTm::new(15.0, 0.0);
        let a = tm.forward(15.0, 49.5)[1];
        let b = tm.forward(15.0, 50.5)[1];
        // Independent check: numerical integral of the meridian radius M(φ) = a(1−e²)/(1−e²sin²φ)^1.5.
        let e2 = WGS84_F * (2.0 - WGS84_F);
        let n = 20_000;
        let (p0, p1) = (49.5_f64.to_radians(), 50.5_f64.to_radians());
        let h = (p1 - p0) / n as f64;
        let mut s = 0.0;
        for i in 0..n {
            let p = p0 + (i as f64 + 0.5) * h;
            s += WGS84_A * (1.0 - e2) / (1.0 - e2 * p.sin().powi(2)).powf(1.5) * h;
        }
        assert!(((b - a) - s).abs() < 1e-4, "{} vs {s}", b - a);
        // East-west at the central meridian: parallel radius N cos φ per radian.
        let p = 50.0_f64.to_radians();
        let nrad = WGS84_A / (1.0 - e2 * p.sin().powi(2)).sqrt();
        let tm50 = LocalTm::new(15.0, 50.0);
        let dx = tm50.forward(15.0 + 1e-4, 50.0)[0] - tm50.forward(15.0 - 1e-4, 50.0)[0];
        let expect = nrad * p.cos() * (2e-4_f64).to_radians();
        assert!((dx - expect).abs() / expect < 1e-9, "{dx} vs {expect}");
        // The origin maps to (0, 0).
        let o = tm50.forward(15.0, 50.0);
        assert!(o[0].abs() < 1e-9 && o[1].abs() < 1e-9);
    }

    #[test]
    fn round_trips() {
        let t = Crs::WebMercator.metric_transform([1_603_900.0, 6_464_700.0]);
        assert!(!t.is_identity());
        for dx in [-3000.0, -500.0, 0.0, 700.0, 2500.0] {
            for dy in [-2000.0, 0.0, 1000.0, 4000.0] {
                let p = [1_603_900.0 + dx, 6_464_700.0 + dy];
                let m = t.to_metric(p);
                let q = t.from_metric(m);
                let m2 = t.to_metric(q);
                assert!((m2[0] - m[0]).abs() < 1e-6 && (m2[1] - m[1]).abs() < 1e-6);
                assert!((q[0] - p[0]).abs() < 1e-6 && (q[1] - p[1]).abs() < 1e-6);
            }
        }
        let g = Crs::Geographic { epsg: Some(4326) }.metric_transform([24.94, 60.17]);
        for p in [[24.93, 60.16], [24.96, 60.18], [24.94, 60.17]] {
            let m = g.to_metric(p);
            let q = g.from_metric(m);
            assert!((q[0] - p[0]).abs() < 1e-11 && (q[1] - p[1]).abs() < 1e-11);
            let m2 = g.to_metric(q);
            assert!((m2[0] - m[0]).abs() < 1e-6 && (m2[1] - m[1]).abs() < 1e-6);
        }
        let p = Crs::from_epsg(3067).metric_transform([385_000.0, 6_672_000.0]);
        assert!(p.is_identity());
        assert_eq!(p.to_metric([1.0, 2.0]), [1.0, 2.0]);
        assert!(t.describe().contains("1.56×"), "{}", t.describe());
        assert!(t.describe().contains("50.10"), "{}", t.describe());
    }
}
