//! A tiled city walked without holding it: the tiles `jobs` writes (meshes per block in a pack,
//! BlockMaps per node), read from a folder or a web server (HTTP range requests), fetched on
//! demand by priority on worker threads, decoded off the render thread, kept under a memory
//! budget, and drawn with coarser stand-ins where content has not arrived (Di Benedetto,
//! *Multiresolution techniques for real-time visualization of urban environments and
//! terrains*, §4.4).
//!
//! - [`source`]: a folder or a URL, and a link limited to a bandwidth and a latency;
//! - [`serve`]: a small HTTP file server with range requests;
//! - [`city`]: [`StreamCity`], the index and the hierarchies (what a client holds);
//! - [`loader`]: the worker threads and the least-recently-used cache;
//! - [`play`](mod@play): the walk (`Streamer`, frame by frame), its stand-ins and measures;
//! - [`job`]: a streamed walk as one call; [`sweep`]: the far field against its time over tiles.

pub mod city;
pub mod job;
pub mod loader;
pub mod play;
pub mod serve;
pub mod source;
pub mod sweep;

pub use city::{Content, ContentId, ContentKind, StreamCity};
pub use play::{play, Mode, StreamFrame, StreamOptions, StreamRun, StreamSummary};
pub use source::{FetchError, LinkSpec, Source};

/// Why a streamed walk could not start.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// A file could not be fetched.
    #[error(transparent)]
    Fetch(#[from] FetchError),
    /// A file is not what it should be.
    #[error("{file}: {why}")]
    Format {
        /// The file.
        file: String,
        /// What is wrong.
        why: String,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    Bad(String),
}

/// True when `location` names a tiled city (`jobs merge`'s output): a URL, a folder holding
/// `index.json` (or a `jobs plan` folder not merged yet), or a file named `index.json`.
pub fn is_tiled_city(location: &str) -> bool {
    if location.starts_with("http://") || location.starts_with("https://") {
        return true;
    }
    let p = std::path::Path::new(location);
    if p.is_dir() {
        // `jobs plan`'s folder counts too, so that one not merged yet is named as such.
        return (p.join("index.json").is_file() || p.join("plan.json").is_file())
            && !p.join("buildings.shp").exists();
    }
    p.file_name().is_some_and(|n| n == "index.json")
}

/// `768MiB`, `1GiB`, `500MB`, `64k` or a plain number of bytes.
///
/// # Errors
/// Text that is none of these, or 0.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim().to_ascii_lowercase().replace(' ', "");
    let units: [(&str, f64); 10] = [
        ("gib", 1073741824.0),
        ("mib", 1048576.0),
        ("kib", 1024.0),
        ("gb", 1e9),
        ("mb", 1e6),
        ("kb", 1e3),
        ("g", 1073741824.0),
        ("m", 1048576.0),
        ("k", 1024.0),
        ("b", 1.0),
    ];
    let (num, mult) = units
        .iter()
        .find_map(|(s, m)| t.strip_suffix(s).map(|n| (n.to_string(), *m)))
        .unwrap_or((t.clone(), 1.0));
    match num.parse::<f64>() {
        Ok(v) if v.is_finite() && v * mult >= 1.0 => Ok((v * mult) as u64),
        _ => Err(format!("{text:?}: expected a size such as 768MiB or 1GiB")),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn sizes_parse_with_their_units() {
        assert_eq!(super::parse_bytes("768MiB").unwrap(), 768 << 20);
        assert_eq!(super::parse_bytes("1GiB").unwrap(), 1 << 30);
        assert_eq!(super::parse_bytes("500MB").unwrap(), 500_000_000);
        assert_eq!(super::parse_bytes("4096").unwrap(), 4096);
        assert!(super::parse_bytes("0").is_err());
        assert!(super::parse_bytes("lots").is_err());
    }
}
