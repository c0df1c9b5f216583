//! Elevation grids (DEMs) read from GeoTIFF.
//!
//! [`read_dem`] reads a single-band GeoTIFF (strips or tiles; 8/16/32-bit integers, 32/64-bit
//! floats) with its georeferencing (GeoKeys: the CRS, the pixel-is-area / pixel-is-point
//! convention, the tie point and pixel scale or a model transformation) and its nodata value
//! (GDAL's `GDAL_NODATA` tag).
//!
//! The pixels are decoded by the pure-Rust `tiff` crate: uncompressed, LZW, Deflate (both tag
//! values, 8 and 32946) and PackBits, with no predictor, the horizontal predictor (2) or the
//! floating-point predictor (3, float samples only). JPEG, ZSTD, WebP and the fax codings are
//! refused with a message naming the compression. The georeferencing tags are read here, from
//! the raw tag values.

use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::{Path, PathBuf};

use tiff::decoder::ifd::Value;
use tiff::decoder::{ChunkType, Decoder, DecodingResult};
use tiff::tags::Tag;
use tiff::{TiffError, TiffFormatError};

use crate::Crs;

/// What a GeoTIFF's pixel values stand for (the GeoKey `GTRasterTypeGeoKey`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PixelIs {
    /// A value is the mean over the pixel's square; the tie point is the square's corner
    /// (`RasterPixelIsArea`, the default).
    Area,
    /// A value is a sample at a point; the tie point is that point (`RasterPixelIsPoint`).
    Point,
}

/// A regular elevation grid in its own CRS.
///
/// Sample `(col, row)` (row 0 is the first row of the file) lies at the CRS position
/// `x = transform[0] + transform[1]·col + transform[2]·row`,
/// `y = transform[3] + transform[4]·col + transform[5]·row`: the affine map is to the
/// *sample's position* (a pixel-is-area file's pixel centre), so the convention is already
/// applied and a consumer never adds half a pixel.
#[derive(Clone, Debug)]
pub struct DemGrid {
    /// The file read.
    pub source: PathBuf,
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Elevations in metres, row-major (`values[row * width + col]`); nodata is `NaN`.
    pub values: Vec<f64>,
    /// Sample (col, row) → CRS position; see the type's documentation.
    pub transform: [f64; 6],
    /// The grid's CRS from its GeoKeys ([`Crs::Unknown`] when it has none).
    pub crs: Crs,
    /// The pixel convention the file declares.
    pub pixel_is: PixelIs,
    /// The file's nodata value, if it declares one.
    pub nodata: Option<f64>,
    /// Samples that are nodata (the declared value, or not finite).
    pub nodata_count: usize,
    /// The sample type as stored (`int16`, `float32`, …).
    pub sample_type: String,
    /// `strips` or `tiles`.
    pub layout: &'static str,
}

impl DemGrid {
    /// The CRS position of sample `(col, row)`; fractional indices interpolate the affine map
    /// (so `(-0.5, -0.5)` is the outer corner of a pixel-is-area file's first pixel).
    pub fn position(&self, col: f64, row: f64) -> [f64; 2] {
        let t = &self.transform;
        [
            t[0] + t[1] * col + t[2] * row,
            t[3] + t[4] * col + t[5] * row,
        ]
    }

    /// The fractional `(col, row)` of the CRS position `(x, y)`: the inverse of
    /// [`DemGrid::position`]. `None` when the transform is degenerate (not invertible) or the
    /// result is not finite. The index may lie outside the grid.
    pub fn fractional_index(&self, x: f64, y: f64) -> Option<[f64; 2]> {
        let t = &self.transform;
        let det = t[1] * t[5] - t[2] * t[4];
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (dx, dy) = (x - t[0], y - t[3]);
        let col = (t[5] * dx - t[2] * dy) / det;
        let row = (t[1] * dy - t[4] * dx) / det;
        (col.is_finite() && row.is_finite()).then_some([col, row])
    }

    /// `[min x, min y, max x, max y]` of the sample positions (the four corner samples). These
    /// are sample positions, not pixel edges: a pixel-is-area grid's pixels reach half a pixel
    /// further. An empty grid gives the position of sample `(0, 0)`.
    pub fn bounds(&self) -> [f64; 4] {
        let c = self.width.saturating_sub(1) as f64;
        let r = self.height.saturating_sub(1) as f64;
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for [x, y] in [
            self.position(0.0, 0.0),
            self.position(c, 0.0),
            self.position(0.0, r),
            self.position(c, r),
        ] {
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
        b
    }

    /// The elevation of sample `(col, row)` (`NaN` for nodata).
    ///
    /// # Panics
    /// When `(col, row)` is outside the grid.
    pub fn value(&self, col: usize, row: usize) -> f64 {
        assert!(
            col < self.width && row < self.height,
            "sample ({col}, {row}) is outside the {} × {} grid",
            self.width,
            self.height
        );
        self.values[row * self.width + col]
    }

    /// `(min, max)` of the elevations, ignoring nodata; `(NaN, NaN)` when every sample is nodata.
    pub fn stats(&self) -> (f64, f64) {
        let (lo, hi) = self
            .values
            .iter()
            .filter(|v| !v.is_nan())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if lo > hi {
            (f64::NAN, f64::NAN)
        } else {
            (lo, hi)
        }
    }
}

/// Why a DEM could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// The file could not be opened or read.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not a GeoTIFF this reader can use (and why).
    #[error("{file}: {problem}")]
    Format {
        /// The file.
        file: String,
        /// What is wrong.
        problem: String,
    },
}

/// Reads a single-band GeoTIFF elevation grid (the first image of the file; overviews and
/// masks in later images are not read).
///
/// - **Samples**: one per pixel, `int8`, `uint8`, `int16`, `uint16`, `int32`, `uint32`,
///   `float32` or `float64`, in strips or tiles, compressed as the module documentation says.
/// - **Georeferencing**: `ModelPixelScaleTag` with `ModelTiepointTag` (the first tie point), as
///   GDAL prefers them, else `ModelTransformationTag`, which must be north-up (no rotation or
///   shear: rotated grids are refused).
/// - **Pixel convention** (`GTRasterTypeGeoKey`): pixel-is-area (1, and the default) puts the
///   tie point at a pixel's corner, so sample `(col, row)` is at raster position
///   `(col + ½, row + ½)`; pixel-is-point (2) puts it on the sample itself. [`DemGrid::transform`]
///   has the convention applied.
/// - **CRS**: `ProjectedCSTypeGeoKey`, else `GeographicTypeGeoKey`, through [`Crs::from_epsg`].
///   When `GTModelTypeGeoKey` says the model is projected only the projected key is used (the
///   geographic key then names the projection's base datum, not the grid's coordinates); when it
///   says geographic only the geographic key is used. No key, a user-defined code (32767) or an
///   undefined one (0) give [`Crs::Unknown`] and the read succeeds: the caller decides whether a
///   grid without CRS is usable. A code [`Crs::from_epsg`] refuses is an error.
/// - **Units**: `VerticalUnitsGeoKey` in feet (9002) or US survey feet (9003) is converted to
///   metres; metres (9001), user-defined (32767) or no key are taken as metres; any other unit
///   is refused.
/// - **Nodata**: the `GDAL_NODATA` tag (42113). As GDAL does, the value is first converted to
///   the sample type (rounded to `float32` for a `float32` grid; never matching an integer grid
///   when it is fractional or out of the type's range); samples equal to it, and samples that
///   are not finite, become `NaN` and are counted in [`DemGrid::nodata_count`].
///
/// A panic in the TIFF decoder on a corrupt file is caught and reported as a
/// [`DemError::Format`] (the panic message still reaches the process's panic hook).
///
/// # Errors
/// [`DemError::Io`] when the file cannot be opened or read; [`DemError::Format`] naming the
/// file and the problem when it is not a TIFF, is truncated or corrupt, has no (or unusable)
/// georeferencing, a rotated or sheared transformation, zero size, more than one sample per
/// pixel, an unsupported sample type or compression, or a CRS code that is not known.
pub fn read_dem(path: &Path) -> Result<DemGrid, DemError> {
    let file = path.display().to_string();
    let fail = |f: Fail| match f {
        Fail::Format(problem) => DemError::Format {
            file: file.clone(),
            problem,
        },
        Fail::Io(source) => DemError::Io {
            file: file.clone(),
            source,
        },
    };
    let f = File::open(path).map_err(|e| fail(Fail::Io(e)))?;
    let file_len = f.metadata().map_err(|e| fail(Fail::Io(e)))?.len();
    let mut reader = BufReader::new(f);
    check_signature(&mut reader, file_len).map_err(fail)?;

    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        decode(reader, file_len, path)
    }))
    .unwrap_or_else(|p| {
        let what = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".into());
        Err(Fail::Format(format!(
            "the TIFF decoder failed ({what}): the file is corrupt"
        )))
    });
    decoded.map_err(fail)
}

/// An error before the file's name is attached.
enum Fail {
    Format(String),
    Io(std::io::Error),
}

impl From<String> for Fail {
    fn from(s: String) -> Fail {
        Fail::Format(s)
    }
}

impl From<&str> for Fail {
    fn from(s: &str) -> Fail {
        Fail::Format(s.into())
    }
}

/// Turns a `tiff` error met while doing `what` into a [`Fail`]: an operating-system error stays
/// an I/O error, an early end of file is a truncation, the rest is a format problem.
fn tiff_fail(what: &'static str) -> impl Fn(TiffError) -> Fail {
    move |e| match e {
        TiffError::IoError(io) if io.raw_os_error().is_some() => Fail::Io(io),
        TiffError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            Fail::Format(format!("truncated: the file ends while {what} ({io})"))
        }
        TiffError::FormatError(TiffFormatError::InvalidDimensions(w, h)) => {
            Fail::Format(format!("zero-size image ({w} × {h} pixels)"))
        }
        e => Fail::Format(format!("{what}: {e}")),
    }
}

/// Refuses a file that does not start like a TIFF (classic or BigTIFF), before the decoder
/// sees it.
fn check_signature<R: Read + Seek>(r: &mut R, file_len: u64) -> Result<(), Fail> {
    let mut head = Vec::with_capacity(4);
    r.by_ref()
        .take(4)
        .read_to_end(&mut head)
        .map_err(Fail::Io)?;
    r.rewind().map_err(Fail::Io)?;
    match head.as_slice() {
        b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+" => Ok(()),
        _ if file_len == 0 => Err("not a TIFF file: the file is empty".into()),
        _ => {
            let shown: Vec<String> = head.iter().map(|b| format!("{b:02x}")).collect();
            Err(format!(
                "not a TIFF file: it starts with bytes {} instead of `II*\\0` or `MM\\0*`",
                shown.join(" ")
            )
            .into())
        }
    }
}

/// The sample types read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SampleType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl SampleType {
    fn name(self) -> &'static str {
        match self {
            SampleType::I8 => "int8",
            SampleType::U8 => "uint8",
            SampleType::I16 => "int16",
            SampleType::U16 => "uint16",
            SampleType::I32 => "int32",
            SampleType::U32 => "uint32",
            SampleType::F32 => "float32",
            SampleType::F64 => "float64",
        }
    }

    fn bytes(self) -> u64 {
        match self {
            SampleType::I8 | SampleType::U8 => 1,
            SampleType::I16 | SampleType::U16 => 2,
            SampleType::I32 | SampleType::U32 | SampleType::F32 => 4,
            SampleType::F64 => 8,
        }
    }

    /// From `SampleFormat` (1 unsigned, 2 signed, 3 IEEE float) and `BitsPerSample`.
    fn from_tags(format: u16, bits: u16) -> Result<SampleType, String> {
        Ok(match (format, bits) {
            (1, 8) => SampleType::U8,
            (2, 8) => SampleType::I8,
            (1, 16) => SampleType::U16,
            (2, 16) => SampleType::I16,
            (1, 32) => SampleType::U32,
            (2, 32) => SampleType::I32,
            (3, 32) => SampleType::F32,
            (3, 64) => SampleType::F64,
            _ => {
                let kind = match format {
                    1 => "unsigned integer",
                    2 => "signed integer",
                    3 => "floating-point",
                    4 => "undefined",
                    5 => "complex integer",
                    6 => "complex floating-point",
                    _ => "unknown",
                };
                return Err(format!(
                    "unsupported sample type: {bits}-bit {kind} (SampleFormat {format}); elevations \
                     are read from int8, uint8, int16, uint16, int32, uint32, float32 or float64"
                ));
            }
        })
    }
}

/// The most decoded bytes one stored byte can give, for the compression codes the `tiff` crate
/// decodes with the features this crate enables, rounded up (PackBits: 128 bytes from 2;
/// Deflate: about 1,032; LZW with 12-bit codes: about 2,730). A file that declares more pixels
/// than its size allows this way is corrupt, and is refused before the grid is allocated.
fn max_expansion(code: u16) -> Result<u64, String> {
    match code {
        1 => Ok(1),
        32773 => Ok(64),
        8 | 32946 => Ok(1100),
        5 => Ok(4096),
        _ => {
            let name = match code {
                2 => "CCITT Huffman",
                3 => "CCITT fax 3",
                4 => "CCITT fax 4",
                6 | 7 => "JPEG",
                34887 => "LERC",
                34925 => "LZMA",
                50000 => "ZSTD",
                50001 => "WebP",
                50002 => "JPEG XL",
                _ => "unknown",
            };
            Err(format!(
                "compression {code} ({name}) is not supported; this reader decodes uncompressed, \
                 LZW, Deflate and PackBits data"
            ))
        }
    }
}

fn decode<R: Read + Seek>(reader: R, file_len: u64, path: &Path) -> Result<DemGrid, Fail> {
    let mut dec = Decoder::new(reader).map_err(tiff_fail("reading the first TIFF directory"))?;
    let tag_fail = tiff_fail("reading the TIFF tags");

    let (w, h) = dec.dimensions().map_err(&tag_fail)?;
    if w == 0 || h == 0 {
        return Err(format!("zero-size image ({w} × {h} pixels)").into());
    }

    let samples = dec
        .find_tag_unsigned::<u16>(Tag::SamplesPerPixel)
        .map_err(&tag_fail)?
        .unwrap_or(1);
    if samples != 1 {
        return Err(format!(
            "{samples} samples per pixel (bands); only single-band elevation grids are read"
        )
        .into());
    }
    let bits = first_unsigned(&mut dec, Tag::BitsPerSample)?.unwrap_or(1);
    let format = first_unsigned(&mut dec, Tag::SampleFormat)?.unwrap_or(1);
    let sample_type = SampleType::from_tags(format, bits)?;
    if let Some(0) = first_unsigned(&mut dec, Tag::PhotometricInterpretation)? {
        let why = "photometric interpretation WhiteIsZero: the decoder would invert the values";
        return Err(why.into());
    }
    let compression = first_unsigned(&mut dec, Tag::Compression)?.unwrap_or(1);
    let expansion = max_expansion(compression)?;
    let predictor = first_unsigned(&mut dec, Tag::Predictor)?.unwrap_or(1);
    match (predictor, sample_type) {
        (1 | 2, _) | (3, SampleType::F32 | SampleType::F64) => {}
        (3, t) => {
            return Err(format!(
                "the floating-point predictor (3) on {} samples is invalid",
                t.name()
            )
            .into())
        }
        (p, _) => return Err(format!("predictor {p} is not supported (only 1, 2 and 3)").into()),
    }

    let raster_to_model = georeferencing(&mut dec)?;
    let keys = match dec.find_tag(Tag::GeoKeyDirectoryTag).map_err(&tag_fail)? {
        Some(v) => {
            let dir = to_u16s(v).ok_or("GeoKeyDirectoryTag is not a list of SHORTs")?;
            let doubles = match dec.find_tag(Tag::GeoDoubleParamsTag).map_err(&tag_fail)? {
                Some(v) => to_f64s(v).ok_or("GeoDoubleParamsTag is not a list of numbers")?,
                None => Vec::new(),
            };
            // Only citations are ASCII keys, and nothing here depends on them: a file whose
            // ASCII parameters cannot be decoded (not UTF-8) is still read.
            let ascii = dec
                .find_tag(Tag::GeoAsciiParamsTag)
                .ok()
                .flatten()
                .and_then(|v| v.into_string().ok())
                .unwrap_or_default();
            GeoKeys::parse(&dir, &doubles, &ascii)?
        }
        None => GeoKeys::default(),
    };
    let pixel_is = match keys.short(GT_RASTER_TYPE)? {
        None | Some(1) => PixelIs::Area,
        Some(2) => PixelIs::Point,
        Some(n) => {
            return Err(format!(
                "GTRasterTypeGeoKey is {n}, neither 1 (PixelIsArea) nor 2 (PixelIsPoint)"
            )
            .into())
        }
    };
    let crs = crs_of(&keys)?;
    let metres_per_unit = match keys.short(VERTICAL_UNITS)? {
        None | Some(9001) | Some(32767) => 1.0,
        Some(9002) => 0.3048,
        Some(9003) => 1200.0 / 3937.0,
        Some(n) => {
            return Err(format!(
                "VerticalUnitsGeoKey {n} is not a unit of length this reader knows \
                 (9001 metre, 9002 foot, 9003 US survey foot)"
            )
            .into())
        }
    };

    let nodata = match dec.find_tag(Tag::GdalNodata).map_err(&tag_fail)? {
        None => None,
        Some(Value::Ascii(s)) => {
            let t = s.trim().trim_end_matches('\0').trim();
            if t.is_empty() {
                None
            } else {
                Some(
                    t.parse::<f64>()
                        .map_err(|_| format!("GDAL_NODATA {t:?} is not a number"))?,
                )
            }
        }
        Some(_) => return Err("GDAL_NODATA is not ASCII text".into()),
    };

    // Sample (col, row) is at raster position (col + ½, row + ½) in a pixel-is-area file,
    // (col, row) in a pixel-is-point one.
    let half = match pixel_is {
        PixelIs::Area => 0.5,
        PixelIs::Point => 0.0,
    };
    let m = raster_to_model;
    let transform = [
        m[0] + half * (m[1] + m[2]),
        m[1],
        m[2],
        m[3] + half * (m[4] + m[5]),
        m[4],
        m[5],
    ];

    // Refuse what cannot be read before allocating the grid: chunks that end past the file's
    // end, or more pixels than the file can hold.
    let (width, height) = (w as usize, h as usize);
    let chunk_type = dec.get_chunk_type();
    check_chunks(&mut dec, chunk_type, file_len)?;
    let count = u64::from(w) * u64::from(h);
    let raw_bytes = count * sample_type.bytes();
    if raw_bytes > file_len.saturating_mul(expansion) {
        return Err(format!(
            "the file declares {w} × {h} {} samples ({raw_bytes} bytes), more than its {file_len} \
             bytes can hold: it is corrupt",
            sample_type.name()
        )
        .into());
    }
    let mut values: Vec<f64> = Vec::new();
    let n = usize::try_from(count).map_err(|_| "the grid is too large for this platform")?;
    values
        .try_reserve_exact(n)
        .map_err(|_| format!("cannot allocate {w} × {h} samples"))?;
    values.resize(n, f64::NAN);

    let (cw, ch) = dec.chunk_dimensions();
    let (cw, ch) = (cw as usize, ch as usize);
    if cw == 0 || ch == 0 {
        return Err(format!("zero-size chunks ({cw} × {ch})").into());
    }
    let across = match chunk_type {
        ChunkType::Strip => 1,
        ChunkType::Tile => width.div_ceil(cw),
    };
    let chunks = across * height.div_ceil(ch);
    let nodata_match = NodataMatch::new(nodata);
    let chunk_fail = tiff_fail("decoding the pixels");
    for i in 0..chunks {
        let (x0, y0) = ((i % across) * cw, (i / across) * ch);
        let data = dec.read_chunk(i as u32).map_err(&chunk_fail)?;
        let (dw, dh) = ((width - x0).min(cw), (height - y0).min(ch));
        place(
            &data,
            sample_type,
            &nodata_match,
            [x0, y0, dw, dh],
            width,
            &mut values,
        )
        .map_err(|e| format!("chunk {i}: {e}"))?;
    }

    let mut nodata_count = 0;
    for v in &mut values {
        if v.is_nan() {
            nodata_count += 1;
        } else {
            *v *= metres_per_unit;
        }
    }

    Ok(DemGrid {
        source: path.to_path_buf(),
        width,
        height,
        values,
        transform,
        crs,
        pixel_is,
        nodata,
        nodata_count,
        sample_type: sample_type.name().to_string(),
        layout: match chunk_type {
            ChunkType::Strip => "strips",
            ChunkType::Tile => "tiles",
        },
    })
}

/// The first value of an unsigned tag (`BitsPerSample` has one value per sample).
fn first_unsigned<R: Read + Seek>(dec: &mut Decoder<R>, tag: Tag) -> Result<Option<u16>, Fail> {
    let v = dec
        .find_tag_unsigned_vec::<u16>(tag)
        .map_err(tiff_fail("reading the TIFF tags"))?;
    match v {
        None => Ok(None),
        Some(v) => match v.first() {
            Some(&x) => Ok(Some(x)),
            None => Err(format!("tag {tag:?} has no value").into()),
        },
    }
}

/// Every chunk (strip or tile) must lie inside the file: one that ends past its end means the
/// file was cut short.
fn check_chunks<R: Read + Seek>(
    dec: &mut Decoder<R>,
    chunk_type: ChunkType,
    file_len: u64,
) -> Result<(), Fail> {
    let (off_tag, len_tag, what) = match chunk_type {
        ChunkType::Strip => (Tag::StripOffsets, Tag::StripByteCounts, "strip"),
        ChunkType::Tile => (Tag::TileOffsets, Tag::TileByteCounts, "tile"),
    };
    let f = tiff_fail("reading the chunk offsets");
    let offsets = dec.find_tag_unsigned_vec::<u64>(off_tag).map_err(&f)?;
    let lens = dec.find_tag_unsigned_vec::<u64>(len_tag).map_err(&f)?;
    let (Some(offsets), Some(lens)) = (offsets, lens) else {
        return Err(format!("the {what} offsets or byte counts are missing").into());
    };
    for (i, (&o, &n)) in offsets.iter().zip(&lens).enumerate() {
        if o.checked_add(n).is_none_or(|end| end > file_len) {
            return Err(format!(
                "truncated: {what} {i} ({n} bytes at offset {o}) ends past the end of the \
                 {file_len}-byte file"
            )
            .into());
        }
    }
    Ok(())
}

/// The nodata value converted to each sample type (`None` where it cannot occur in that type).
struct NodataMatch {
    i64: Option<i64>,
    f32: Option<f32>,
    f64: Option<f64>,
}

impl NodataMatch {
    fn new(nodata: Option<f64>) -> NodataMatch {
        let Some(v) = nodata.filter(|v| !v.is_nan()) else {
            return NodataMatch {
                i64: None,
                f32: None,
                f64: None,
            };
        };
        let int = (v.fract() == 0.0 && v.abs() < 9.0e18).then_some(v as i64);
        NodataMatch {
            i64: int,
            f32: Some(v as f32),
            f64: Some(v),
        }
    }
}

/// Copies one decoded chunk of `dw × dh` samples into the grid at `(x0, y0)`, nodata as `NaN`.
fn place(
    data: &DecodingResult,
    t: SampleType,
    nd: &NodataMatch,
    [x0, y0, dw, dh]: [usize; 4],
    width: usize,
    out: &mut [f64],
) -> Result<(), String> {
    fn copy<T: Copy + Into<f64>>(
        src: &[T],
        is_nodata: impl Fn(T) -> bool,
        [x0, y0, dw, dh]: [usize; 4],
        width: usize,
        out: &mut [f64],
    ) -> Result<(), String> {
        if src.len() < dw * dh {
            return Err(format!(
                "decoded {} samples where {dw} × {dh} were expected",
                src.len()
            ));
        }
        // A strip or tile's rows are `dw` samples long here (the decoder drops the padding).
        for (r, row) in src.chunks_exact(dw).take(dh).enumerate() {
            let start = (y0 + r) * width + x0;
            for (o, &s) in out[start..start + dw].iter_mut().zip(row) {
                let v: f64 = s.into();
                *o = if is_nodata(s) || !v.is_finite() {
                    f64::NAN
                } else {
                    v
                };
            }
        }
        Ok(())
    }
    let at = [x0, y0, dw, dh];
    let int = |s: i64| Some(s) == nd.i64;
    match (data, t) {
        (DecodingResult::I8(v), SampleType::I8) => copy(v, |s| int(s.into()), at, width, out),
        (DecodingResult::U8(v), SampleType::U8) => copy(v, |s| int(s.into()), at, width, out),
        (DecodingResult::I16(v), SampleType::I16) => copy(v, |s| int(s.into()), at, width, out),
        (DecodingResult::U16(v), SampleType::U16) => copy(v, |s| int(s.into()), at, width, out),
        (DecodingResult::I32(v), SampleType::I32) => copy(v, |s| int(s.into()), at, width, out),
        (DecodingResult::U32(v), SampleType::U32) => copy(v, |s| int(s.into()), at, width, out),
        (DecodingResult::F32(v), SampleType::F32) => copy(v, |s| Some(s) == nd.f32, at, width, out),
        (DecodingResult::F64(v), SampleType::F64) => copy(v, |s| Some(s) == nd.f64, at, width, out),
        _ => Err(format!(
            "the decoder returned samples of another type than the file's {}",
            t.name()
        )),
    }
}

/// The raster-to-model affine map `[x0, dx/dcol, dx/drow, y0, dy/dcol, dy/drow]` in raster
/// space (pixel corners for pixel-is-area, samples for pixel-is-point), from the pixel scale
/// and first tie point, else the model transformation.
fn georeferencing<R: Read + Seek>(dec: &mut Decoder<R>) -> Result<[f64; 6], Fail> {
    let f = tiff_fail("reading the georeferencing tags");
    let scale = dec.find_tag(Tag::ModelPixelScaleTag).map_err(&f)?;
    let ties = dec.find_tag(Tag::ModelTiepointTag).map_err(&f)?;
    let matrix = dec.find_tag(Tag::ModelTransformationTag).map_err(&f)?;
    let numbers = |v: Value, name: &str, min: usize| -> Result<Vec<f64>, String> {
        let v = to_f64s(v).ok_or(format!("{name} is not a list of numbers"))?;
        if v.len() < min {
            return Err(format!("{name} has {} values, fewer than {min}", v.len()));
        }
        if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!("{name} holds a value that is not finite ({bad})"));
        }
        Ok(v)
    };
    let m = match (scale, ties, matrix) {
        (Some(scale), Some(ties), _) => {
            let s = numbers(scale, "ModelPixelScaleTag", 2)?;
            let t = numbers(ties, "ModelTiepointTag", 6)?;
            if s[0] == 0.0 || s[1] == 0.0 {
                return Err(format!(
                    "ModelPixelScaleTag has a zero pixel size ({} × {})",
                    s[0], s[1]
                )
                .into());
            }
            // X = tx + (i - I)·sx, Y = ty - (j - J)·sy: raster rows go down, model y up.
            let (i, j, tx, ty) = (t[0], t[1], t[3], t[4]);
            [tx - i * s[0], s[0], 0.0, ty + j * s[1], 0.0, -s[1]]
        }
        (_, _, Some(matrix)) => {
            let a = numbers(matrix, "ModelTransformationTag", 16)?;
            // Row-major 4 × 4: X = a0·i + a1·j + a2·k + a3, Y = a4·i + a5·j + a6·k + a7.
            let (sx, rx, ox, ry, sy, oy) = (a[0], a[1], a[3], a[4], a[5], a[7]);
            let tol = 1e-10 * sx.abs().max(sy.abs());
            if rx.abs() > tol || ry.abs() > tol {
                return Err(format!(
                    "ModelTransformationTag is rotated or sheared (x per row {rx}, y per column \
                     {ry}): rotated grids are not supported"
                )
                .into());
            }
            if sx == 0.0 || sy == 0.0 {
                return Err(
                    format!("ModelTransformationTag has a zero pixel size ({sx} × {sy})").into(),
                );
            }
            // Terms within the tolerance are rounding noise of a north-up writer; kept as they
            // are, the affine map stays exact.
            [ox, sx, rx, oy, ry, sy]
        }
        (None, Some(ties), None) => {
            let n = to_f64s(ties).map_or(0, |t| t.len() / 6);
            return Err(if n > 1 {
                format!(
                    "georeferenced by {n} ground control points only (no ModelPixelScaleTag): \
                     warped grids are not supported"
                )
            } else {
                "ModelTiepointTag without ModelPixelScaleTag: the pixel size is unknown".into()
            }
            .into());
        }
        (Some(_), None, None) => {
            return Err(
                "ModelPixelScaleTag without ModelTiepointTag: the grid's origin is unknown".into(),
            )
        }
        (None, None, None) => {
            return Err(
                "no georeferencing: none of ModelPixelScaleTag + ModelTiepointTag \
                        or ModelTransformationTag (is it a plain TIFF, or a GeoTIFF with a \
                        .tfw world file? world files are not read)"
                    .into(),
            )
        }
    };
    Ok(m)
}

/// A tag's value as numbers (any numeric TIFF type), `None` for text.
fn to_f64s(v: Value) -> Option<Vec<f64>> {
    fn one(v: Value, out: &mut Vec<f64>) -> Option<()> {
        let x = match v {
            Value::Byte(x) => f64::from(x),
            Value::Short(x) => f64::from(x),
            Value::SignedByte(x) => f64::from(x),
            Value::SignedShort(x) => f64::from(x),
            Value::Signed(x) => f64::from(x),
            Value::SignedBig(x) => x as f64,
            Value::Unsigned(x) => f64::from(x),
            Value::UnsignedBig(x) => x as f64,
            Value::Float(x) => f64::from(x),
            Value::Double(x) => x,
            Value::Rational(n, d) => f64::from(n) / f64::from(d),
            Value::SRational(n, d) => f64::from(n) / f64::from(d),
            Value::List(l) => {
                for v in l {
                    one(v, out)?;
                }
                return Some(());
            }
            _ => return None,
        };
        out.push(x);
        Some(())
    }
    let mut out = Vec::new();
    one(v, &mut out)?;
    Some(out)
}

/// A tag's value as SHORTs (BYTE and SHORT values), `None` otherwise.
fn to_u16s(v: Value) -> Option<Vec<u16>> {
    match v {
        Value::Short(x) => Some(vec![x]),
        Value::Byte(x) => Some(vec![x.into()]),
        Value::List(l) => l
            .into_iter()
            .map(|v| match v {
                Value::Short(x) => Some(x),
                Value::Byte(x) => Some(x.into()),
                _ => None,
            })
            .collect(),
        _ => None,
    }
}

const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
const GEOGRAPHIC_TYPE: u16 = 2048;
const PROJECTED_CS_TYPE: u16 = 3072;
const VERTICAL_UNITS: u16 = 4099;
/// The GeoTIFF code of a user-defined CRS or unit.
const USER_DEFINED: u16 = 32767;

/// One GeoKey's value.
#[derive(Clone, Debug)]
enum KeyValue {
    /// SHORTs (stored in the directory itself).
    Shorts(Vec<u16>),
    /// DOUBLEs in `GeoDoubleParamsTag` (their place checked; no key read here needs them).
    Doubles,
    /// Text in `GeoAsciiParamsTag` (its place checked; only citations are text).
    Ascii,
    /// A key whose value lies outside its parameter tag, or in a tag that does not exist.
    Bad(String),
}

/// The GeoKey directory, resolved against its parameter tags.
#[derive(Default, Debug)]
struct GeoKeys {
    keys: Vec<(u16, KeyValue)>,
}

impl GeoKeys {
    /// Parses `GeoKeyDirectoryTag`: a header `[version, revision, minor, count]` and `count`
    /// entries `[key, location, count, value or index]`, where location 0 means the value is
    /// the SHORT itself, 34735 SHORTs further in the directory, 34736 DOUBLEs in
    /// `GeoDoubleParamsTag`, 34737 characters in `GeoAsciiParamsTag`.
    fn parse(dir: &[u16], doubles: &[f64], ascii: &str) -> Result<GeoKeys, String> {
        if dir.len() < 4 {
            return Err(format!(
                "GeoKeyDirectoryTag has {} values, fewer than its 4-value header",
                dir.len()
            ));
        }
        let n = usize::from(dir[3]);
        let entries = dir
            .get(4..4 + 4 * n)
            .ok_or_else(|| {
                format!(
                    "GeoKeyDirectoryTag declares {n} keys but holds {} values",
                    dir.len()
                )
            })?
            .chunks_exact(4);
        let mut keys = Vec::with_capacity(n);
        for e in entries {
            let (id, loc, count, at) = (e[0], e[1], usize::from(e[2]), usize::from(e[3]));
            let range = at..at + count;
            let value = match loc {
                0 => KeyValue::Shorts(vec![e[3]]),
                34735 => dir
                    .get(range)
                    .map(|s| KeyValue::Shorts(s.to_vec()))
                    .unwrap_or_else(|| {
                        KeyValue::Bad(format!("its {count} SHORTs at {at} are outside the directory"))
                    }),
                34736 => doubles
                    .get(range)
                    .map(|_| KeyValue::Doubles)
                    .unwrap_or_else(|| {
                        KeyValue::Bad(format!(
                            "its {count} DOUBLEs at {at} are outside GeoDoubleParamsTag ({} values)",
                            doubles.len()
                        ))
                    }),
                34737 => ascii
                    .get(range)
                    .map(|_| KeyValue::Ascii)
                    .unwrap_or_else(|| {
                        KeyValue::Bad(format!("its text at {at} is outside GeoAsciiParamsTag"))
                    }),
                other => KeyValue::Bad(format!("its value is in tag {other}, not a GeoTIFF tag")),
            };
            keys.push((id, value));
        }
        Ok(GeoKeys { keys })
    }

    /// The SHORT value of key `id`, `None` when the key is absent.
    fn short(&self, id: u16) -> Result<Option<u16>, String> {
        match self.keys.iter().find(|(k, _)| *k == id) {
            None => Ok(None),
            Some((_, KeyValue::Shorts(s))) if s.len() == 1 => Ok(Some(s[0])),
            Some((_, v)) => {
                let what = match v {
                    KeyValue::Bad(why) => why.clone(),
                    KeyValue::Shorts(s) => format!("it has {} values instead of one", s.len()),
                    KeyValue::Doubles => "it is a DOUBLE, not a SHORT".into(),
                    KeyValue::Ascii => "it is text, not a SHORT".into(),
                };
                Err(format!("GeoKey {id} cannot be read: {what}"))
            }
        }
    }
}

/// The CRS the keys name (see [`read_dem`]).
fn crs_of(keys: &GeoKeys) -> Result<Crs, String> {
    let projected = keys.short(PROJECTED_CS_TYPE)?;
    let geographic = keys.short(GEOGRAPHIC_TYPE)?;
    let chosen = match keys.short(GT_MODEL_TYPE)? {
        Some(1) => projected.map(|c| (c, "ProjectedCSTypeGeoKey")),
        Some(2) => geographic.map(|c| (c, "GeographicTypeGeoKey")),
        _ => projected
            .map(|c| (c, "ProjectedCSTypeGeoKey"))
            .or(geographic.map(|c| (c, "GeographicTypeGeoKey"))),
    };
    match chosen {
        None | Some((0 | USER_DEFINED, _)) => Ok(Crs::Unknown),
        Some((code, key)) => Crs::from_epsg(code.into()).map_err(|e| format!("{key} {code}: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(transform: [f64; 6], width: usize, height: usize) -> DemGrid {
        DemGrid {
            source: PathBuf::new(),
            width,
            height,
            values: (0..width * height).map(|i| i as f64).collect(),
            transform,
            crs: Crs::Unknown,
            pixel_is: PixelIs::Area,
            nodata: None,
            nodata_count: 0,
            sample_type: "float64".into(),
            layout: "strips",
        }
    }

    #[test]
    fn fractional_index_inverts_position() {
        // Sheared on purpose: the inverse must hold for any invertible affine map.
        let g = grid([1000.0, 2.0, 0.5, 5000.0, -0.25, -3.0], 4, 3);
        for (c, r) in [(0.0, 0.0), (3.0, 2.0), (-1.5, 7.25), (0.5, 0.5)] {
            let [x, y] = g.position(c, r);
            let [c2, r2] = g.fractional_index(x, y).unwrap();
            assert!(
                (c2 - c).abs() < 1e-9 && (r2 - r).abs() < 1e-9,
                "{c},{r} → {c2},{r2}"
            );
        }
        assert!(grid([0.0, 1.0, 2.0, 0.0, 2.0, 4.0], 2, 2)
            .fractional_index(1.0, 1.0)
            .is_none());
    }

    #[test]
    fn bounds_value_and_stats() {
        let mut g = grid([10.0, 2.0, 0.0, 100.0, 0.0, -5.0], 3, 2);
        assert_eq!(g.bounds(), [10.0, 95.0, 14.0, 100.0]);
        assert_eq!(g.value(2, 1), 5.0);
        assert_eq!(g.stats(), (0.0, 5.0));
        g.values[0] = f64::NAN;
        g.values[5] = f64::NAN;
        assert_eq!(g.stats(), (1.0, 4.0));
        g.values.iter_mut().for_each(|v| *v = f64::NAN);
        let (lo, hi) = g.stats();
        assert!(lo.is_nan() && hi.is_nan());
    }

    #[test]
    fn geokeys_resolve_their_parameter_tags() {
        let dir = [
            1, 1, 0, 4, //
            1024, 0, 1, 1, //
            1026, 34737, 6, 0, //
            2057, 34736, 1, 1, //
            3072, 0, 1, 32645,
        ];
        let k = GeoKeys::parse(&dir, &[1.0, 298.25], "UTM 45|WGS|").unwrap();
        assert_eq!(k.short(3072).unwrap(), Some(32645));
        assert_eq!(k.short(1025).unwrap(), None);
        assert!(matches!(&k.keys[1].1, KeyValue::Ascii));
        assert!(matches!(&k.keys[2].1, KeyValue::Doubles));
        assert!(k.short(2057).unwrap_err().contains("DOUBLE"));
        assert!(k.short(1026).unwrap_err().contains("text"));
        // Parameters that are not there.
        let k = GeoKeys::parse(&dir, &[1.0], "UTM").unwrap();
        assert!(matches!(&k.keys[1].1, KeyValue::Bad(_)));
        assert!(matches!(&k.keys[2].1, KeyValue::Bad(_)));
        // Too few entries for the count, and a key pointing past its parameters.
        assert!(GeoKeys::parse(&[1, 1, 0, 2, 1024, 0, 1, 1], &[], "").is_err());
        let k = GeoKeys::parse(&[1, 1, 0, 1, 3072, 34735, 1, 99], &[], "").unwrap();
        assert!(k.short(3072).unwrap_err().contains("outside the directory"));
    }

    #[test]
    fn nodata_is_matched_in_the_sample_type() {
        let nd = NodataMatch::new(Some(-3.402_823e38));
        assert_eq!(nd.f32, Some(-3.402_823e38_f32));
        assert_eq!(nd.i64, None);
        let nd = NodataMatch::new(Some(-32767.0));
        assert_eq!(nd.i64, Some(-32767));
        assert_eq!(NodataMatch::new(Some(1.5)).i64, None);
        assert_eq!(NodataMatch::new(Some(f64::NAN)).f64, None);
    }
}
