//! Content fetched and decoded on worker threads, by priority, and kept in a cache under a byte
//! budget, least recently used first out.

use std::collections::{HashMap, HashSet};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use crate::blockmap::BlockMap;
use crate::city::Mesh;

use super::city::{Content, ContentId, ContentKind};
use super::source::{FetchError, Link, Source};

/// Decoded content, ready to draw.
#[derive(Debug)]
pub enum Resident {
    /// A block's mesh.
    Mesh(Mesh),
    /// A node's map.
    Map(BlockMap),
}

impl Resident {
    /// Bytes it holds.
    pub fn bytes(&self) -> u64 {
        match self {
            Resident::Mesh(m) => {
                (m.positions.len() * 24
                    + m.indices.len() * 4
                    + m.appearance.len() * 8
                    + m.styles.len()
                        * std::mem::size_of::<crate::city::appearance::BuildingStyle>()
                    + std::mem::size_of::<Mesh>()) as u64
            }
            Resident::Map(m) => (m.bytes() + std::mem::size_of::<BlockMap>()) as u64,
        }
    }
}

/// Why a piece of content could not be made resident.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum LoadError {
    /// The file is missing.
    Missing(String),
    /// The bytes came but are not what the hierarchy says (size, CRC-32) or do not decode.
    Refused(String),
    /// The fetch failed (I/O, connection).
    Failed(String),
}

impl std::fmt::Display for LoadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LoadError::Missing(s) => write!(f, "missing: {s}"),
            LoadError::Refused(s) => write!(f, "refused: {s}"),
            LoadError::Failed(s) => write!(f, "failed: {s}"),
        }
    }
}

/// Fetches, checks and decodes one piece of content from `source` over `link` (when given).
/// Returns the bytes fetched with the result.
pub fn load(
    source: &Source,
    link: Option<&Link>,
    c: &Content,
) -> (u64, Result<Resident, LoadError>) {
    let bytes = match source.fetch(&c.file, c.range) {
        Ok(b) => b,
        Err(FetchError::Missing(f)) => return (0, Err(LoadError::Missing(f))),
        Err(e) => return (0, Err(LoadError::Failed(e.to_string()))),
    };
    let n = bytes.len() as u64;
    if let Some(l) = link {
        l.transfer(n);
    }
    let name = || match c.range {
        Some((o, l)) => format!("{} bytes {o}..{}", source.name_of(&c.file), o + l),
        None => source.name_of(&c.file),
    };
    let crc = crate::jobs::pack::crc32_hex(&bytes);
    if n != c.bytes || crc != c.crc32 {
        return (
            n,
            Err(LoadError::Refused(format!(
                "{}: {n} bytes, CRC-32 {crc}; the hierarchy says {} bytes, {}",
                name(),
                c.bytes,
                c.crc32
            ))),
        );
    }
    let r = match &c.kind {
        ContentKind::Mesh { zlib, inflated, .. } => {
            crate::jobs::pack::decode_record(&bytes, zlib.then_some("zlib"), *inflated)
                .map(Resident::Mesh)
                .map_err(|e| LoadError::Refused(format!("{}: {e}", name())))
        }
        ContentKind::Map(_, meta) => {
            BlockMap::decode_png((**meta).clone(), &bytes, std::path::Path::new(&name()))
                .map(Resident::Map)
                .map_err(|e| LoadError::Refused(e.to_string()))
        }
    };
    (n, r)
}

/// A request's priority: lower first (class, then order within the class).
pub type Priority = (u8, u32);

/// One finished load.
#[derive(Debug)]
pub struct Loaded {
    /// The content.
    pub id: ContentId,
    /// Bytes fetched.
    pub bytes: u64,
    /// Seconds from the worker taking it to the result.
    pub seconds: f64,
    /// The decoded content, or why not.
    pub result: Result<Resident, LoadError>,
}

#[derive(Default)]
struct Queue {
    /// Best last.
    pending: Vec<(Priority, ContentId)>,
    in_flight: HashSet<ContentId>,
    stop: bool,
}

/// Worker threads fetching and decoding content by priority (see the module doc).
pub struct Loader {
    shared: Arc<(Mutex<Queue>, Condvar)>,
    rx: Receiver<Loaded>,
    threads: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for Loader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Loader")
            .field("threads", &self.threads.len())
            .finish()
    }
}

fn worker(
    shared: Arc<(Mutex<Queue>, Condvar)>,
    contents: Arc<Vec<Content>>,
    source: Arc<Source>,
    link: Arc<Link>,
    tx: Sender<Loaded>,
) {
    let (lock, cv) = &*shared;
    loop {
        let id = {
            let mut q = lock.lock().unwrap_or_else(|p| p.into_inner());
            loop {
                if q.stop {
                    return;
                }
                if let Some((_, id)) = q.pending.pop() {
                    q.in_flight.insert(id);
                    break id;
                }
                q = cv.wait(q).unwrap_or_else(|p| p.into_inner());
            }
        };
        let t = Instant::now();
        let c = &contents[id as usize];
        // A decoder that panics on hostile bytes refuses the item; the worker lives on.
        let (bytes, result) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            load(&source, Some(&link), c)
        }))
        .unwrap_or_else(|_| {
            (
                0,
                Err(LoadError::Refused(format!(
                    "{}: the decoder failed on its bytes",
                    source.name_of(&c.file)
                ))),
            )
        });
        let done = Loaded {
            id,
            bytes,
            seconds: t.elapsed().as_secs_f64(),
            result,
        };
        // Out of the in-flight set before it is sent: once the render thread has it (and may
        // have evicted it again), a new request for it is never dropped as "in flight". A
        // request in between fetches it twice, which costs bytes, never a frame.
        lock.lock()
            .unwrap_or_else(|p| p.into_inner())
            .in_flight
            .remove(&id);
        if tx.send(done).is_err() {
            return;
        }
    }
}

impl Loader {
    /// `workers` threads fetching `contents` from `source` over `link`.
    pub fn start(
        contents: Arc<Vec<Content>>,
        source: Arc<Source>,
        link: Arc<Link>,
        workers: usize,
    ) -> Self {
        let shared = Arc::new((Mutex::new(Queue::default()), Condvar::new()));
        let (tx, rx) = channel();
        let threads = (0..workers.max(1))
            .map(|_| {
                let (s, c, so, l, tx) = (
                    shared.clone(),
                    contents.clone(),
                    source.clone(),
                    link.clone(),
                    tx.clone(),
                );
                std::thread::spawn(move || worker(s, c, so, l, tx))
            })
            .collect();
        Self {
            shared,
            rx,
            threads,
        }
    }

    /// Replaces the requests not yet started with `wanted` (any order; lower priority first),
    /// leaving out what is in flight. Returns how many are now queued.
    pub fn request(&self, wanted: &[(Priority, ContentId)]) -> usize {
        let (lock, cv) = &*self.shared;
        let mut q = lock.lock().unwrap_or_else(|p| p.into_inner());
        let mut seen = HashSet::with_capacity(wanted.len());
        let mut v: Vec<(Priority, ContentId)> = wanted
            .iter()
            .filter(|(_, id)| !q.in_flight.contains(id) && seen.insert(*id))
            .copied()
            .collect();
        v.sort_by(|a, b| b.cmp(a));
        q.pending = v;
        let n = q.pending.len();
        drop(q);
        cv.notify_all();
        n
    }

    /// Requests in flight (taken by a worker, not yet received).
    pub fn in_flight(&self) -> usize {
        self.shared
            .0
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .in_flight
            .len()
    }

    /// A finished load, without waiting.
    pub fn try_take(&self) -> Option<Loaded> {
        self.rx.try_recv().ok()
    }

    /// The next finished load, waiting for it at most `timeout` (deterministic mode only).
    pub fn take(&self, timeout: std::time::Duration) -> Option<Loaded> {
        self.rx.recv_timeout(timeout).ok()
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        {
            let mut q = self.shared.0.lock().unwrap_or_else(|p| p.into_inner());
            q.stop = true;
            q.pending.clear();
        }
        self.shared.1.notify_all();
        // Workers finishing a transfer exit after it; they are not joined, so a slow link
        // never holds the caller.
        self.threads.clear();
    }
}

/// Resident content under a byte budget; the least recently used goes first, never what the
/// current frame uses.
#[derive(Debug)]
pub struct Cache {
    budget: u64,
    used: u64,
    entries: HashMap<ContentId, (Arc<Resident>, u64, u64)>,
    /// Items evicted so far.
    pub evictions: u64,
    /// Items not kept because the frame's own content filled the budget.
    pub over_budget: u64,
}

impl Cache {
    /// An empty cache of `budget` bytes.
    pub fn new(budget: u64) -> Self {
        Self {
            budget,
            used: 0,
            entries: HashMap::new(),
            evictions: 0,
            over_budget: 0,
        }
    }

    /// Bytes held.
    pub fn used(&self) -> u64 {
        self.used
    }

    /// Items held.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when nothing is held.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Whether `id` is resident.
    pub fn contains(&self, id: ContentId) -> bool {
        self.entries.contains_key(&id)
    }

    /// The resident `id`, marked used in `frame`.
    pub fn get(&mut self, id: ContentId, frame: u64) -> Option<Arc<Resident>> {
        self.entries.get_mut(&id).map(|e| {
            e.2 = frame;
            e.0.clone()
        })
    }

    /// Keeps `item` as used in `frame`, evicting the least recently used items of earlier
    /// frames until it fits. Returns false (and keeps nothing) when it cannot fit without
    /// evicting this frame's content.
    pub fn insert(&mut self, id: ContentId, item: Resident, frame: u64) -> bool {
        let bytes = item.bytes();
        if let Some(old) = self.entries.remove(&id) {
            self.used -= old.1;
        }
        while self.used + bytes > self.budget {
            let victim = self
                .entries
                .iter()
                .filter(|(_, e)| e.2 < frame)
                .min_by_key(|(k, e)| (e.2, **k))
                .map(|(k, _)| *k);
            match victim {
                Some(k) => {
                    let e = self.entries.remove(&k).expect("present");
                    self.used -= e.1;
                    self.evictions += 1;
                }
                None => {
                    self.over_budget += 1;
                    return false;
                }
            }
        }
        self.used += bytes;
        self.entries.insert(id, (Arc::new(item), bytes, frame));
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(n: usize) -> Resident {
        Resident::Mesh(Mesh {
            positions: vec![glam::Vec3::ZERO; n],
            normals: vec![glam::Vec3::Z; n],
            ..Mesh::default()
        })
    }

    #[test]
    fn the_cache_keeps_its_budget_and_evicts_the_least_recently_used() {
        let one = mesh(100).bytes();
        let mut c = Cache::new(3 * one);
        assert!(c.insert(1, mesh(100), 0));
        assert!(c.insert(2, mesh(100), 1));
        assert!(c.insert(3, mesh(100), 2));
        assert!(c.get(1, 3).is_some()); // 1 is now the most recent
        assert!(c.insert(4, mesh(100), 4));
        assert!(!c.contains(2), "2 was the least recently used");
        assert!(c.contains(1) && c.contains(3) && c.contains(4));
        assert_eq!(c.evictions, 1);
        assert!(c.used() <= 3 * one);
        // Everything in use this frame: a fourth item does not fit and nothing is evicted.
        for id in [1, 3, 4] {
            c.get(id, 9);
        }
        assert!(!c.insert(5, mesh(100), 9));
        assert_eq!(c.len(), 3);
        assert_eq!(c.over_budget, 1);
    }
}
