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
use std::io::{BufRead, BufReader, Read, Seek, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

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
    accept: Option<JoinHandle<()>>,
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

/// A request as far as the server reads it: GET and HEAD have no body.
struct Request {
    method: String,
    target: String,
    range: Option<String>,
    /// The client keeps the connection for another request (HTTP/1.1 unless `Connection:
    /// close`; HTTP/1.0 only with `Connection: keep-alive`).
    keep_alive: bool,
}

/// Longest request line or header line read, bytes; most header lines read.
const MAX_LINE: u64 = 8 * 1024;
const MAX_HEADERS: usize = 100;

/// One line of the request head without its CRLF, `None` at the end of the stream (or a
/// timeout), `Err` for a line too long.
fn read_line(r: &mut impl BufRead) -> Result<Option<String>, ()> {
    let mut line = Vec::new();
    let n = r
        .by_ref()
        .take(MAX_LINE + 1)
        .read_until(b'\n', &mut line)
        .unwrap_or(0);
    if n == 0 {
        return Ok(None);
    }
    if !line.ends_with(b"\n") {
        return Err(());
    }
    while matches!(line.last(), Some(b'\n' | b'\r')) {
        line.pop();
    }
    Ok(Some(String::from_utf8_lossy(&line).into_owned()))
}

/// The next request on a connection: `Ok(None)` when the client has closed it or stayed idle
/// past the read timeout, `Err` for a request that cannot be read (answered 400).
fn read_request(r: &mut impl BufRead) -> Result<Option<Request>, ()> {
    let Some(first) = read_line(r)? else {
        return Ok(None);
    };
    let mut parts = first.split_whitespace();
    let (Some(method), Some(target), Some(version)) = (parts.next(), parts.next(), parts.next())
    else {
        return Err(());
    };
    let mut req = Request {
        method: method.to_string(),
        target: target.to_string(),
        range: None,
        keep_alive: version == "HTTP/1.1",
    };
    let mut body = false;
    for _ in 0..=MAX_HEADERS {
        let Some(line) = read_line(r)? else {
            return Err(());
        };
        if line.is_empty() {
            // A request with a body is answered, and its connection closed.
            req.keep_alive &= !body;
            return Ok(Some(req));
        }
        let Some((name, value)) = line.split_once(':') else {
            return Err(());
        };
        let value = value.trim();
        if name.eq_ignore_ascii_case("range") {
            req.range = Some(value.to_string());
        } else if name.eq_ignore_ascii_case("connection") {
            let v = value.to_ascii_lowercase();
            if v.contains("close") {
                req.keep_alive = false;
            } else if v.contains("keep-alive") {
                req.keep_alive = true;
            }
        } else if (name.eq_ignore_ascii_case("content-length") && value != "0")
            || name.eq_ignore_ascii_case("transfer-encoding")
        {
            body = true;
        }
    }
    Err(())
}

/// Writes one answer: the status line, the headers (with `Content-Length` and the CORS
/// header), and `count` bytes of `body` unless the request was `HEAD`.
fn write_answer(
    w: &mut impl Write,
    status: u16,
    headers: &[(&str, String)],
    body: Option<(&mut dyn Read, u64)>,
    head: bool,
    keep_alive: bool,
) -> std::io::Result<()> {
    let reason = match status {
        200 => "OK",
        206 => "Partial Content",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        416 => "Range Not Satisfiable",
        _ => "Internal Server Error",
    };
    let len = body.as_ref().map_or(0, |b| b.1);
    let mut text = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Length: {len}\r\nAccess-Control-Allow-Origin: *\r\n"
    );
    for (k, v) in headers {
        text.push_str(&format!("{k}: {v}\r\n"));
    }
    text.push_str(if keep_alive {
        "Connection: keep-alive\r\n\r\n"
    } else {
        "Connection: close\r\n\r\n"
    });
    w.write_all(text.as_bytes())?;
    if let (Some((r, n)), false) = (body, head) {
        let copied = std::io::copy(&mut r.take(n), w)?;
        if copied != n {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the file ended before its length",
            ));
        }
    }
    w.flush()
}

/// Answers one request on `w`.
fn answer(
    store: &Store,
    req: &Request,
    counts: &ServeCounts,
    w: &mut impl Write,
) -> std::io::Result<()> {
    counts.requests.fetch_add(1, Ordering::Relaxed);
    let keep = req.keep_alive;
    let head = req.method == "HEAD";
    if !head && req.method != "GET" {
        return write_answer(w, 405, &[("Allow", "GET, HEAD".into())], None, head, keep);
    }
    let (mut file, len) = match store.find(&req.target) {
        Found::Body(b) => b,
        Found::Forbidden => return write_answer(w, 403, &[], None, head, keep),
        Found::Missing => {
            counts.missing.fetch_add(1, Ordering::Relaxed);
            return write_answer(w, 404, &[], None, head, keep);
        }
        Found::Broken => return write_answer(w, 500, &[], None, head, keep),
    };
    let kind = content_type(&req.target);
    let (status, start, count) = match req.range.as_deref() {
        None => (200, 0, len),
        Some(spec) => match parse_range(spec, len) {
            Some((s, e)) => (206, s, e - s + 1),
            None => {
                let h = [("Content-Range", format!("bytes */{len}"))];
                return write_answer(w, 416, &h, None, head, keep);
            }
        },
    };
    if file.seek(std::io::SeekFrom::Start(start)).is_err() {
        return write_answer(w, 500, &[], None, head, keep);
    }
    let mut headers = vec![
        ("Accept-Ranges", "bytes".to_string()),
        ("Content-Type", kind.to_string()),
    ];
    if status == 206 {
        counts.ranges.fetch_add(1, Ordering::Relaxed);
        headers.push((
            "Content-Range",
            format!("bytes {start}-{}/{len}", start + count - 1),
        ));
    }
    if !head {
        counts.bytes.fetch_add(count, Ordering::Relaxed);
    }
    write_answer(w, status, &headers, Some((&mut file, count)), head, keep)
}

/// How long a connection may stay idle between requests before the server closes it.
const IDLE: Duration = Duration::from_secs(2);

/// Serves the requests of one connection until the client closes it, stays idle past
/// [`IDLE`], asks to close, or a request cannot be read.
fn serve_connection(store: &Store, counts: &ServeCounts, stream: TcpStream) {
    let _ = stream.set_read_timeout(Some(IDLE));
    let _ = stream.set_nodelay(true);
    let Ok(read) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(read);
    let mut writer = std::io::BufWriter::new(stream);
    loop {
        match read_request(&mut reader) {
            Ok(Some(req)) => {
                if answer(store, &req, counts, &mut writer).is_err() || !req.keep_alive {
                    return;
                }
            }
            Ok(None) => return,
            Err(()) => {
                let _ = write_answer(&mut writer, 400, &[], None, false, false);
                return;
            }
        }
    }
}

impl Server {
    /// Serves `root` on `addr` (e.g. `127.0.0.1:0` for any free port), each connection on a
    /// thread of its own, at most `connections` at once (more wait to be accepted; an idle
    /// connection is closed after a few seconds): a folder's files, or a `.3tz` archive's
    /// entries (see the module documentation).
    ///
    /// # Errors
    /// The address cannot be bound, or `root` is neither a folder nor a 3D Tiles archive.
    pub fn start(root: &Path, addr: &str, connections: usize) -> Result<Self, String> {
        let store = Arc::new(if root.is_dir() {
            Store::Dir(root.to_path_buf())
        } else if root.is_file() {
            Store::Archive(Archive::open(root).map_err(|e| e.to_string())?)
        } else if !root.exists() {
            return Err(format!(
                "{}: no such folder or .3tz archive",
                root.display()
            ));
        } else {
            return Err(format!(
                "{}: neither a folder nor a .3tz archive",
                root.display()
            ));
        });
        let listener = TcpListener::bind(addr).map_err(|e| format!("listening on {addr}: {e}"))?;
        let local = listener
            .local_addr()
            .map_err(|e| format!("listening on {addr}: {e}"))?;
        // Accepting polls, so that a stop is seen within a few milliseconds.
        listener
            .set_nonblocking(true)
            .map_err(|e| format!("listening on {addr}: {e}"))?;
        let stop = Arc::new(AtomicBool::new(false));
        let counts = Arc::new(ServeCounts::default());
        let open = Arc::new((Mutex::new(0usize), Condvar::new()));
        let max = connections.max(1);
        let accept = {
            let (stop, counts, open) = (stop.clone(), counts.clone(), open.clone());
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let stream = match listener.accept() {
                        Ok((s, _)) => s,
                        Err(_) => {
                            std::thread::sleep(Duration::from_millis(2));
                            continue;
                        }
                    };
                    if stream.set_nonblocking(false).is_err() {
                        continue;
                    }
                    {
                        let (n, freed) = &*open;
                        let mut n = n.lock().unwrap_or_else(|e| e.into_inner());
                        while *n >= max && !stop.load(Ordering::Relaxed) {
                            n = freed
                                .wait_timeout(n, Duration::from_millis(50))
                                .unwrap_or_else(|e| e.into_inner())
                                .0;
                        }
                        *n += 1;
                    }
                    let (store, counts, open) = (store.clone(), counts.clone(), open.clone());
                    std::thread::spawn(move || {
                        // A panic while answering closes this connection only.
                        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                            serve_connection(&store, &counts, stream)
                        }));
                        let (n, freed) = &*open;
                        *n.lock().unwrap_or_else(|e| e.into_inner()) -= 1;
                        freed.notify_one();
                    });
                }
            })
        };
        Ok(Self {
            addr: local,
            stop,
            accept: Some(accept),
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

    /// Stops accepting and closes the listening socket; connections already open finish
    /// their current request.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.accept.take() {
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
        let s = Server::start(dir.path(), "127.0.0.1:0", 16).unwrap();
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

    #[test]
    fn a_root_that_cannot_be_served_is_named_with_its_problem() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("city.3tz");
        let e = Server::start(&missing, "127.0.0.1:0", 4).err().unwrap();
        assert!(
            e.contains("city.3tz") && e.contains("no such folder"),
            "{e}"
        );
        let not_zip = dir.path().join("bad.3tz");
        std::fs::write(&not_zip, b"not a zip").unwrap();
        let e = Server::start(&not_zip, "127.0.0.1:0", 4).err().unwrap();
        assert!(e.contains("bad.3tz"), "{e}");
    }

    /// Everything the server sends on a connection after `request` until it closes it (or
    /// 3 s pass).
    fn exchange(s: &Server, request: &[u8]) -> String {
        let mut c = TcpStream::connect(s.addr()).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
        c.write_all(request).unwrap();
        let mut out = Vec::new();
        let _ = c.read_to_end(&mut out);
        String::from_utf8_lossy(&out).into_owned()
    }

    #[test]
    fn connections_keep_alive_close_and_refuse_as_http_1_1_says() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.json"), b"{\"a\":1}").unwrap();
        let s = Server::start(dir.path(), "127.0.0.1:0", 4).unwrap();
        // Two requests on one connection: both answered in order, the second closes it.
        let two = exchange(
            &s,
            b"GET /a.json HTTP/1.1\r\nHost: x\r\n\r\nHEAD /a.json HTTP/1.1\r\nConnection: close\r\n\r\n",
        );
        assert_eq!(two.matches("HTTP/1.1 200 OK").count(), 2, "{two}");
        assert_eq!(
            two.matches("{\"a\":1}").count(),
            1,
            "HEAD sends no body: {two}"
        );
        assert!(two.contains("Content-Type: application/json"), "{two}");
        assert!(two.contains("Access-Control-Allow-Origin: *"), "{two}");
        assert!(two.trim_end().ends_with("Connection: close"), "{two}");
        // HTTP/1.0 closes unless asked; another method is refused; a broken request is 400.
        let old = exchange(&s, b"GET /a.json HTTP/1.0\r\n\r\n");
        assert!(old.starts_with("HTTP/1.1 200 OK") && old.contains("Connection: close"));
        let post = exchange(&s, b"POST /a.json HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
        assert!(post.starts_with("HTTP/1.1 405 "), "{post}");
        let bad = exchange(&s, b"GARBAGE\r\n\r\n");
        assert!(bad.starts_with("HTTP/1.1 400 "), "{bad}");
        let mut long = b"GET /".to_vec();
        long.extend(std::iter::repeat_n(b'a', 10_000));
        long.extend(b" HTTP/1.1\r\n\r\n");
        assert!(exchange(&s, &long).starts_with("HTTP/1.1 400 "));
        let range = exchange(
            &s,
            b"GET /a.json HTTP/1.1\r\nRange: bytes=9-\r\nConnection: close\r\n\r\n",
        );
        assert!(range.starts_with("HTTP/1.1 416 "), "{range}");
        assert!(range.contains("Content-Range: bytes */7"), "{range}");
        // An idle connection does not hold its slot: more idle connections than slots, and a
        // request still gets its answer.
        let idle: Vec<TcpStream> = (0..6)
            .map(|_| TcpStream::connect(s.addr()).unwrap())
            .collect();
        let t0 = std::time::Instant::now();
        let late = exchange(&s, b"GET /a.json HTTP/1.1\r\nConnection: close\r\n\r\n");
        assert!(late.starts_with("HTTP/1.1 200 OK"), "{late}");
        assert!(t0.elapsed() < Duration::from_secs(3 * IDLE.as_secs()));
        drop(idle);
    }
}
