//! Where a tiled city's files come from: a folder, or a web server asked with HTTP range
//! requests; and the link they come over, optionally limited to a bandwidth and a latency.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Why a fetch failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FetchError {
    /// The file does not exist (a missing file, HTTP 404).
    #[error("{0}: missing")]
    Missing(String),
    /// Anything else: I/O, a refused connection, a short read, an unexpected HTTP status.
    #[error("{file}: {why}")]
    Failed {
        /// The file (path or URL).
        file: String,
        /// What went wrong.
        why: String,
    },
}

/// A folder or a base URL that holds `index.json` and the `tiles/` it names.
#[derive(Debug)]
pub enum Source {
    /// A local folder.
    Dir(PathBuf),
    /// A base URL (ends with `/`) and the HTTP agent asking it.
    Http {
        /// The URL of the folder.
        base: String,
        /// The client.
        agent: ureq::Agent,
    },
}

impl Source {
    /// The source of `location`: a URL (`http://` or `https://`) of `index.json` or of its
    /// folder, or a local `index.json` or its folder. Returns the source and the index's name.
    pub fn parse(location: &str) -> (Source, String) {
        if location.starts_with("http://") || location.starts_with("https://") {
            let (base, name) = match location.rsplit_once('/') {
                Some((b, n)) if n.ends_with(".json") => (format!("{b}/"), n.to_string()),
                _ => (
                    format!("{}/", location.trim_end_matches('/')),
                    "index.json".to_string(),
                ),
            };
            let agent: ureq::Agent = ureq::Agent::config_builder()
                .timeout_global(Some(Duration::from_secs(60)))
                .http_status_as_error(false)
                .build()
                .into();
            return (Source::Http { base, agent }, name);
        }
        let p = Path::new(location);
        if p.extension().is_some_and(|e| e == "json") && !p.is_dir() {
            let dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "index.json".into());
            let dir = if dir.as_os_str().is_empty() {
                PathBuf::from(".")
            } else {
                dir
            };
            (Source::Dir(dir), name)
        } else {
            (Source::Dir(p.to_path_buf()), "index.json".into())
        }
    }

    /// The file `rel` (a path relative to the folder) as a path or URL, for messages.
    pub fn name_of(&self, rel: &str) -> String {
        match self {
            Source::Dir(d) => d.join(rel).display().to_string(),
            Source::Http { base, .. } => format!("{base}{rel}"),
        }
    }

    /// What the source is, in words.
    pub fn describe(&self) -> String {
        match self {
            Source::Dir(d) => format!("folder {}", d.display()),
            Source::Http { base, .. } => format!("HTTP {base}"),
        }
    }

    /// The bytes of `rel`, whole or the byte range `(offset, length)`. A range is read with an
    /// HTTP `Range` request (a server answering `200` with the whole file is accepted, and the
    /// range cut from it); fewer bytes than asked for is an error, never a short result.
    ///
    /// # Errors
    /// [`FetchError::Missing`] for a file that does not exist, [`FetchError::Failed`] otherwise.
    pub fn fetch(&self, rel: &str, range: Option<(u64, u64)>) -> Result<Vec<u8>, FetchError> {
        let name = self.name_of(rel);
        let failed = |why: String| FetchError::Failed {
            file: name.clone(),
            why,
        };
        match self {
            Source::Dir(d) => {
                let path = d.join(rel);
                let mut f = match std::fs::File::open(&path) {
                    Ok(f) => f,
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                        return Err(FetchError::Missing(name))
                    }
                    Err(e) => return Err(failed(e.to_string())),
                };
                match range {
                    None => {
                        let mut v = Vec::new();
                        f.read_to_end(&mut v).map_err(|e| failed(e.to_string()))?;
                        Ok(v)
                    }
                    Some((offset, len)) => {
                        use std::io::Seek;
                        f.seek(std::io::SeekFrom::Start(offset))
                            .map_err(|e| failed(e.to_string()))?;
                        let mut v = Vec::with_capacity(len as usize);
                        f.take(len)
                            .read_to_end(&mut v)
                            .map_err(|e| failed(e.to_string()))?;
                        if (v.len() as u64) < len {
                            return Err(failed(format!(
                                "bytes {offset}..{} asked for, the file ends after {} of them",
                                offset + len,
                                v.len()
                            )));
                        }
                        Ok(v)
                    }
                }
            }
            Source::Http { base, agent } => {
                let url = format!("{base}{rel}");
                let mut req = agent.get(&url);
                if let Some((offset, len)) = range {
                    req = req.header("Range", &format!("bytes={offset}-{}", offset + len - 1));
                }
                let resp = req.call().map_err(|e| failed(e.to_string()))?;
                let status = resp.status().as_u16();
                if status == 404 {
                    return Err(FetchError::Missing(name));
                }
                if status != 200 && status != 206 {
                    return Err(failed(format!("HTTP status {status}")));
                }
                let mut body = Vec::new();
                resp.into_body()
                    .into_reader()
                    .read_to_end(&mut body)
                    .map_err(|e| failed(e.to_string()))?;
                match (range, status) {
                    (Some((offset, len)), 200) => {
                        let end = offset + len;
                        if (body.len() as u64) < end {
                            return Err(failed(format!(
                                "bytes {offset}..{end} asked for, the file has {}",
                                body.len()
                            )));
                        }
                        Ok(body[offset as usize..end as usize].to_vec())
                    }
                    (Some((_, len)), _) if body.len() as u64 != len => Err(failed(format!(
                        "{len} bytes asked for, {} came",
                        body.len()
                    ))),
                    _ => Ok(body),
                }
            }
        }
    }
}

/// A link's limits: bandwidth (bits per second, shared by all transfers) and latency (per
/// request).
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize)]
pub struct LinkSpec {
    /// Bits per second; `None`: as fast as the source delivers.
    pub bits_per_s: Option<f64>,
    /// Seconds from a request to its first byte.
    pub latency_s: f64,
}

impl LinkSpec {
    /// Checks the values.
    ///
    /// # Errors
    /// A bandwidth that is not a finite number > 0, a latency that is not a finite number ≥ 0.
    pub fn new(bits_per_s: Option<f64>, latency_s: f64) -> Result<Self, String> {
        if let Some(b) = bits_per_s {
            if !(b.is_finite() && b > 0.0) {
                return Err(format!("bandwidth {b} bit/s: expected a number > 0"));
            }
        }
        if !(latency_s.is_finite() && latency_s >= 0.0) {
            return Err(format!("latency {latency_s} s: expected a number ≥ 0"));
        }
        Ok(Self {
            bits_per_s,
            latency_s,
        })
    }

    /// `100Mbps`, `4 Mb/s`, `500kbps`, `1Gbps` or a plain number of bits per second.
    ///
    /// # Errors
    /// Text that is none of these.
    pub fn parse_bandwidth(text: &str) -> Result<f64, String> {
        let t = text.trim().to_ascii_lowercase().replace(' ', "");
        let (num, mult) = [
            ("gbps", 1e9),
            ("gb/s", 1e9),
            ("mbps", 1e6),
            ("mb/s", 1e6),
            ("kbps", 1e3),
            ("kb/s", 1e3),
            ("bps", 1.0),
            ("b/s", 1.0),
        ]
        .iter()
        .find_map(|(s, m)| t.strip_suffix(s).map(|n| (n.to_string(), *m)))
        .unwrap_or((t.clone(), 1.0));
        match num.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(v * mult),
            _ => Err(format!(
                "bandwidth {text:?}: expected e.g. 100Mbps, 4Mb/s, 500kbps"
            )),
        }
    }
}

/// A link in use: the limits and the time the shared pipe is busy until.
#[derive(Debug)]
pub struct Link {
    spec: LinkSpec,
    busy_until: Mutex<Instant>,
}

impl Link {
    /// A link with `spec`'s limits, idle.
    pub fn new(spec: LinkSpec) -> Self {
        Self {
            spec,
            busy_until: Mutex::new(Instant::now()),
        }
    }

    /// The limits.
    pub fn spec(&self) -> LinkSpec {
        self.spec
    }

    /// Blocks the calling worker as a transfer of `bytes` over this link would: the latency,
    /// then the bytes at the bandwidth, after the transfers already on the pipe.
    pub fn transfer(&self, bytes: u64) {
        if self.spec.latency_s > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(self.spec.latency_s));
        }
        let Some(bps) = self.spec.bits_per_s else {
            return;
        };
        let done = {
            let mut busy = self.busy_until.lock().unwrap_or_else(|p| p.into_inner());
            let start = (*busy).max(Instant::now());
            *busy = start + Duration::from_secs_f64(bytes as f64 * 8.0 / bps);
            *busy
        };
        let now = Instant::now();
        if done > now {
            std::thread::sleep(done - now);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bandwidths_parse_with_their_units() {
        assert_eq!(LinkSpec::parse_bandwidth("100Mbps").unwrap(), 1e8);
        assert_eq!(LinkSpec::parse_bandwidth("4 Mb/s").unwrap(), 4e6);
        assert_eq!(LinkSpec::parse_bandwidth("500kbps").unwrap(), 5e5);
        assert_eq!(LinkSpec::parse_bandwidth("2500").unwrap(), 2500.0);
        assert!(LinkSpec::parse_bandwidth("fast").is_err());
        assert!(LinkSpec::parse_bandwidth("-4Mbps").is_err());
        assert!(LinkSpec::new(Some(0.0), 0.0).is_err());
        assert!(LinkSpec::new(None, f64::NAN).is_err());
    }

    #[test]
    fn a_throttled_link_takes_the_bytes_time() {
        let link = Link::new(LinkSpec::new(Some(8e6), 0.0).unwrap());
        let t = Instant::now();
        link.transfer(100_000); // 0.1 s at 8 Mb/s
        link.transfer(100_000);
        let s = t.elapsed().as_secs_f64();
        assert!((0.19..1.0).contains(&s), "{s} s");
    }

    #[test]
    fn sources_parse_urls_and_paths() {
        let (s, n) = Source::parse("http://127.0.0.1:8080/city/index.json");
        assert!(
            matches!(s, Source::Http { ref base, .. } if base == "http://127.0.0.1:8080/city/")
        );
        assert_eq!(n, "index.json");
        let (s, n) = Source::parse("http://127.0.0.1:8080/city");
        assert!(
            matches!(s, Source::Http { ref base, .. } if base == "http://127.0.0.1:8080/city/")
        );
        assert_eq!(n, "index.json");
        let (s, n) = Source::parse("out/city/index.json");
        assert!(matches!(s, Source::Dir(ref d) if d == Path::new("out/city")));
        assert_eq!(n, "index.json");
    }
}
