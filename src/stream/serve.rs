//! A small HTTP/1.1 file server for a tiled city: `GET` and `HEAD` of the files under one
//! folder, with single byte ranges (`Range: bytes=a-b`, `a-`, `-n`; RFC 9110 §14) answered
//! `206 Partial Content`. Paths that leave the folder are refused. It serves the tests and
//! `blockwalk serve`; any static server with range support (nginx, Caddy, S3) serves the same
//! folder.
//!
//! Given a 3D Tiles archive (`.3tz`, [`crate::tiles::archive`]) instead of a folder, it serves
//! the archive's entries by path, each found through the archive's index and decompressed: a
//! viewer loads `http://ADDR/tileset.json` as from the folder the archive was made of (CesiumJS
//! reads no `.3tz` itself). Every answer allows any origin (`Access-Control-Allow-Origin: *`),
//! so a web viewer served from elsewhere may load the tiles.

use crate::tiles::archive::Archive;
use std::io::{Read, Seek};
use std::net::SocketAddr;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// What a running server has answered.
#[derive(Debug, Default)]
pub struct ServeCounts {
    /// Requests answered.
    pub requests: AtomicU64,
    /// Of these, range requests answered `206`.
    pub ranges: AtomicU64,
    /// Body bytes sent.
    pub bytes: AtomicU64,
    /// Requests answered `404`.
    pub missing: AtomicU64,
}

/// A server running on its own threads until dropped (or [`Server::stop`]).
pub struct Server {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    server: Arc<tiny_http::Server>,
    threads: Vec<JoinHandle<()>>,
    counts: Arc<ServeCounts>,
}

impl std::fmt::Debug for Server {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Server").field("addr", &self.addr).finish()
    }
}

/// A single byte range of a file of `len` bytes, inclusive ends, or `None` when `spec` is not
/// one satisfiable range.
fn parse_range(spec: &str, len: u64) -> Option<(u64, u64)> {
    let r = spec.trim().strip_prefix("bytes=")?;
    if r.contains(',') || len == 0 {
        return None;
    }
    let (a, b) = r.split_once('-')?;
    let (a, b) = (a.trim(), b.trim());
    let (start, end) = if a.is_empty() {
        let n: u64 = b.parse().ok()?;
        if n == 0 {
            return None;
        }
        (len.saturating_sub(n), len - 1)
    } else {
        let s: u64 = a.parse().ok()?;
        let e: u64 = if b.is_empty() {
            len - 1
        } else {
            b.parse::<u64>().ok()?.min(len - 1)
        };
        (s, e)
    };
    (start <= end && start < len).then_some((start, end))
}

/// The file under `root` a request path names, or `None` when it leaves `root`.
fn resolve(root: &Path, url: &str) -> Option<PathBuf> {
    let path = url.split(['?', '#']).next().unwrap_or("");
    let mut out = root.to_path_buf();
    for part in path.split('/').filter(|p| !p.is_empty()) {
        let decoded = percent_encoding::percent_decode_str(part)
            .decode_utf8()
            .ok()?;
        let c = Path::new(decoded.as_ref());
        match c.components().next() {
            Some(Component::Normal(n)) if c.components().count() == 1 => out.push(n),
            _ => return None,
        }
    }
    Some(out)
}

/// What is served: a folder's files, or an archive's entries.
#[derive(Debug)]
enum Store {
    Dir(PathBuf),
    Archive(Archive),
}

/// A body to send: its reader (positioned at 0) and length.
type Body = (Box<dyn ReadSeek>, u64);

trait ReadSeek: Read + Seek + Send {}
impl<T: Read + Seek + Send> ReadSeek for T {}

/// What a request path finds.
enum Found {
    Body(Body),
    Forbidden,
    Missing,
    Broken,
}

impl Store {
    fn find(&self, url: &str) -> Found {
        match self {
            Store::Dir(root) => {
                let Some(path) = resolve(root, url) else {
                    return Found::Forbidden;
                };
                match std::fs::File::open(&path) {
                    Ok(f) if f.metadata().is_ok_and(|m| m.is_file()) => {
                        let len = f.metadata().map(|m| m.len()).unwrap_or(0);
                        Found::Body((Box::new(f), len))
                    }
                    _ => Found::Missing,
                }
            }
            Store::Archive(a) => {
                // The entry path: the request path, decoded, without its leading slash.
                let Some(rel) = resolve(Path::new(""), url) else {
                    return Found::Forbidden;
                };
                let Some(rel) = rel.to_str().map(|r| r.replace('\\', "/")) else {
                    return Found::Missing;
                };
                match a.read(&rel) {
                    Ok(Some(bytes)) => {
                        let len = bytes.len() as u64;
                        Found::Body((Box::new(std::io::Cursor::new(bytes)), len))
                    }
                    Ok(None) => Found::Missing,
                    Err(_) => Found::Broken,
                }
            }
        }
    }
}

/// The media type of a served path, by its extension.
fn content_type(url: &str) -> &'static str {
    let path = url.split(['?', '#']).next().unwrap_or("");
    match path.rsplit_once('.').map(|(_, e)| e) {
        Some("json") => "application/json",
        Some("glb") => "model/gltf-binary",
        _ => "application/octet-stream",
    }
}

fn answer(store: &Store, req: tiny_http::Request, counts: &ServeCounts) {
    counts.requests.fetch_add(1, Ordering::Relaxed);
    let head = *req.method() == tiny_http::Method::Head;
    if !head && *req.method() != tiny_http::Method::Get {
        let _ = req.respond(tiny_http::Response::empty(405));
        return;
    }
    let cors = || {
        tiny_http::Header::from_bytes(&b"Access-Control-Allow-Origin"[..], &b"*"[..])
            .expect("an ASCII header")
    };
    let (file, len) = match store.find(req.url()) {
        Found::Body(b) => b,
        Found::Forbidden => {
            let _ = req.respond(tiny_http::Response::empty(403).with_header(cors()));
            return;
        }
        Found::Missing => {
            counts.missing.fetch_add(1, Ordering::Relaxed);
            let _ = req.respond(tiny_http::Response::empty(404).with_header(cors()));
            return;
        }
        Found::Broken => {
            let _ = req.respond(tiny_http::Response::empty(500).with_header(cors()));
            return;
        }
    };
    let kind = content_type(req.url());
    let range = req
        .headers()
        .iter()
        .find(|h| h.field.equiv("Range"))
        .map(|h| h.value.as_str().to_string());
    let header = |k: &str, v: String| {
        tiny_http::Header::from_bytes(k.as_bytes(), v.as_bytes()).expect("an ASCII header")
    };
    let (status, start, count) = match range.as_deref() {
        None => (200, 0, len),
        Some(spec) => match parse_range(spec, len) {
            Some((s, e)) => (206, s, e - s + 1),
            None => {
                let r = tiny_http::Response::empty(416)
                    .with_header(header("Content-Range", format!("bytes */{len}")));
                let _ = req.respond(r);
                return;
            }
        },
    };
    let mut file = file;
    if file.seek(std::io::SeekFrom::Start(start)).is_err() {
        let _ = req.respond(tiny_http::Response::empty(500));
        return;
    }
    let mut resp = tiny_http::Response::new(
        tiny_http::StatusCode(status),
        vec![
            header("Accept-Ranges", "bytes".into()),
            header("Content-Type", kind.into()),
            cors(),
        ],
        Box::new(file.take(if head { 0 } else { count })) as Box<dyn Read + Send>,
        Some(count as usize),
        None,
    );
    if status == 206 {
        counts.ranges.fetch_add(1, Ordering::Relaxed);
        resp = resp.with_header(header(
            "Content-Range",
            format!("bytes {start}-{}/{len}", start + count - 1),
        ));
    }
    if !head {
        counts.bytes.fetch_add(count, Ordering::Relaxed);
    }
    let _ = req.respond(resp);
}

impl Server {
    /// Serves `root` on `addr` (e.g. `127.0.0.1:0` for any free port) with `threads` threads:
    /// a folder's files, or a `.3tz` archive's entries (see the module documentation).
    ///
    /// # Errors
    /// The address cannot be bound, or `root` is neither a folder nor a 3D Tiles archive.
    pub fn start(root: &Path, addr: &str, threads: usize) -> Result<Self, String> {
        let store = Arc::new(if root.is_dir() {
            Store::Dir(root.to_path_buf())
        } else if root.is_file() {
            Store::Archive(Archive::open(root).map_err(|e| e.to_string())?)
        } else {
            return Err(format!(
                "{}: neither a folder nor a .3tz archive",
                root.display()
            ));
        });
        let server = Arc::new(
            tiny_http::Server::http(addr).map_err(|e| format!("listening on {addr}: {e}"))?,
        );
        let local = server
            .server_addr()
            .to_ip()
            .ok_or_else(|| format!("{addr}: not an IP address"))?;
        let stop = Arc::new(AtomicBool::new(false));
        let counts = Arc::new(ServeCounts::default());
        let threads = (0..threads.max(1))
            .map(|_| {
                let (server, stop, counts) = (server.clone(), stop.clone(), counts.clone());
                let store = store.clone();
                std::thread::spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        match server.recv_timeout(std::time::Duration::from_millis(100)) {
                            Ok(Some(req)) => answer(&store, req, &counts),
                            Ok(None) => {}
                            Err(_) => break,
                        }
                    }
                })
            })
            .collect();
        Ok(Self {
            addr: local,
            stop,
            server,
            threads,
            counts,
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// `http://ADDR/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// What it has answered so far.
    pub fn counts(&self) -> &ServeCounts {
        &self.counts
    }

    /// Stops the threads and closes the socket.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.server.unblock();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_follow_rfc_9110() {
        assert_eq!(parse_range("bytes=0-9", 100), Some((0, 9)));
        assert_eq!(parse_range("bytes=90-", 100), Some((90, 99)));
        assert_eq!(parse_range("bytes=-10", 100), Some((90, 99)));
        assert_eq!(parse_range("bytes=95-200", 100), Some((95, 99)));
        assert_eq!(parse_range("bytes=100-", 100), None);
        assert_eq!(parse_range("bytes=5-2", 100), None);
        assert_eq!(parse_range("bytes=0-1,5-6", 100), None);
        assert_eq!(parse_range("items=0-1", 100), None);
    }

    #[test]
    fn paths_never_leave_the_folder() {
        let root = Path::new("/srv/city");
        assert_eq!(
            resolve(root, "/tiles/tile_00001.pack?x=1"),
            Some(root.join("tiles/tile_00001.pack"))
        );
        assert_eq!(resolve(root, "/tiles/../../etc/passwd"), None);
        assert_eq!(resolve(root, "/tiles/%2e%2e/x"), None);
        assert_eq!(resolve(root, "/a%2fb"), None);
    }

    #[test]
    fn a_file_is_served_whole_and_in_ranges() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..5000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(dir.path().join("f.bin"), &data).unwrap();
        let s = Server::start(dir.path(), "127.0.0.1:0", 2).unwrap();
        let (src, _) = super::super::Source::parse(&format!("{}index.json", s.url()));
        assert_eq!(src.fetch("f.bin", None).unwrap(), data);
        assert_eq!(
            src.fetch("f.bin", Some((1000, 300))).unwrap(),
            &data[1000..1300]
        );
        assert!(matches!(
            src.fetch("nope.bin", None),
            Err(super::super::FetchError::Missing(_))
        ));
        // The server sends the 100 bytes the file has (206, as RFC 9110 asks); the client
        // refuses a short range.
        let e = src
            .fetch("f.bin", Some((4900, 200)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("200 bytes asked for, 100 came"), "{e}");
        assert_eq!(s.counts().ranges.load(Ordering::Relaxed), 2);
        assert_eq!(s.counts().missing.load(Ordering::Relaxed), 1);
    }
}
