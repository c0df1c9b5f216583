//! One-file tilesets: the 3D Tiles archive (`.3tz`) as 3d-tiles-tools and other 3D Tiles
//! servers read it: a ZIP archive (PKWARE APPNOTE 6.3) of the tileset folder's files under their
//! relative paths (`/` separators, no leading slash), and as its last entry `@3dtilesIndex1@`,
//! stored uncompressed: one 24-byte record per other entry, the MD5 hash of the entry's path (16
//! bytes) then the offset of its local file header (u64, little-endian), sorted by the hash read
//! as two little-endian u64 (bytes 0..8 first, then 8..16). A reader finds an entry by hashing the
//! path and searching the index, without reading the central directory.
//!
//! Entries are deflated (the index is stored: readers take it raw), dated 1980-01-01 and written
//! in a fixed order (`tileset.json` first, then by path), so the same folder gives the same bytes.
//! [`Archive`] reads entries back through the index (what `blockwalk serve` does with a `.3tz`).

use crate::output::{AtomicFile, OutputError, StagedDir};
use md5::{Digest, Md5};
use rayon::prelude::*;
use std::cell::Cell;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// The name of the index entry.
pub const INDEX_ENTRY: &str = "@3dtilesIndex1@";

/// What went wrong while writing or reading an archive.
#[derive(Debug, thiserror::Error)]
pub enum ArchiveError {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The ZIP layer failed.
    #[error("{}: {source}", path.display())]
    Zip {
        /// The archive.
        path: PathBuf,
        /// Why.
        #[source]
        source: zip::result::ZipError,
    },
    /// The archive is not a 3D Tiles archive as described in the module documentation.
    #[error("{}: not a 3D Tiles archive (.3tz): {what}", path.display())]
    Format {
        /// The archive.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
}

/// The MD5 hash of an entry path, as the index keys it.
pub fn path_hash(path: &str) -> [u8; 16] {
    Md5::digest(path.as_bytes()).into()
}

/// The order of the index: the hash as two little-endian u64, the first 8 bytes first.
pub fn hash_order(h: &[u8; 16]) -> (u64, u64) {
    let lo = u64::from_le_bytes(h[..8].try_into().expect("8 bytes"));
    let hi = u64::from_le_bytes(h[8..].try_into().expect("8 bytes"));
    (lo, hi)
}

/// The bytes of the index entry for `(path, local header offset)` pairs.
pub fn index_bytes(entries: &[(String, u64)]) -> Vec<u8> {
    let mut rows: Vec<([u8; 16], u64)> = entries.iter().map(|(p, o)| (path_hash(p), *o)).collect();
    rows.sort_by_key(|(h, _)| hash_order(h));
    let mut out = Vec::with_capacity(rows.len() * 24);
    for (h, o) in rows {
        out.extend_from_slice(&h);
        out.extend_from_slice(&o.to_le_bytes());
    }
    out
}

/// A writer that knows its position (the ZIP writer writes a local header where the stream
/// stands when an entry starts).
struct Tracked<W> {
    inner: W,
    pos: Rc<Cell<u64>>,
}

impl<W: Write> Write for Tracked<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.pos.set(self.pos.get() + n as u64);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Seek> Seek for Tracked<W> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let p = self.inner.seek(to)?;
        self.pos.set(p);
        Ok(p)
    }
}

/// The files under `dir`, as entry paths (`/` separators) with their file paths: `tileset.json`
/// first, then by path.
fn entries_of(dir: &Path) -> Result<Vec<(String, PathBuf)>, ArchiveError> {
    let mut out = Vec::new();
    let mut stack = vec![(String::new(), dir.to_path_buf())];
    while let Some((prefix, d)) = stack.pop() {
        let io = |source| ArchiveError::Io {
            path: d.clone(),
            source,
        };
        for e in std::fs::read_dir(&d).map_err(io)? {
            let e = e.map_err(io)?;
            let name = e.file_name().to_string_lossy().into_owned();
            let rel = if prefix.is_empty() {
                name
            } else {
                format!("{prefix}/{name}")
            };
            if e.file_type().map_err(io)?.is_dir() {
                stack.push((rel, e.path()));
            } else {
                out.push((rel, e.path()));
            }
        }
    }
    out.sort_by(|a, b| (a.0 != "tileset.json", &a.0).cmp(&(b.0 != "tileset.json", &b.0)));
    Ok(out)
}

/// Writes the files under `dir` as a 3D Tiles archive into `out` (see the module
/// documentation); `name` names the archive in errors. Returns `out`.
///
/// # Errors
/// [`ArchiveError`] naming the file that could not be read or the archive.
pub fn write_archive<W: Write + Seek>(dir: &Path, out: W, name: &Path) -> Result<W, ArchiveError> {
    let zip_err = |source| ArchiveError::Zip {
        path: name.to_path_buf(),
        source,
    };
    let io_err = |source| ArchiveError::Io {
        path: name.to_path_buf(),
        source,
    };
    let pos = Rc::new(Cell::new(0u64));
    let mut zip = zip::ZipWriter::new(Tracked {
        inner: out,
        pos: pos.clone(),
    });
    let opts = |method, len: u64| {
        zip::write::SimpleFileOptions::default()
            .compression_method(method)
            .last_modified_time(zip::DateTime::default())
            .unix_permissions(0o644)
            .large_file(len >= u32::MAX as u64)
    };
    let mut offsets = Vec::new();
    let entries = entries_of(dir)?;
    // Compressed in parallel a batch at a time, added in order: an entry added whole (header,
    // data, header patched) starts where the stream stands.
    for batch in entries.chunks(64) {
        let prepared: Vec<Result<zip::PreparedZipFile, ArchiveError>> = batch
            .par_iter()
            .map(|(rel, file)| {
                let bytes = std::fs::read(file).map_err(|source| ArchiveError::Io {
                    path: file.clone(),
                    source,
                })?;
                zip::PreparedZipFile::from_data(
                    rel,
                    opts(zip::CompressionMethod::Deflated, bytes.len() as u64),
                    &bytes,
                )
                .map_err(zip_err)
            })
            .collect();
        for ((rel, _), p) in batch.iter().zip(prepared) {
            offsets.push((rel.clone(), pos.get()));
            zip.add_prepared_file(p?).map_err(zip_err)?;
        }
    }
    let index = index_bytes(&offsets);
    zip.start_file(
        INDEX_ENTRY,
        opts(zip::CompressionMethod::Stored, index.len() as u64),
    )
    .map_err(zip_err)?;
    zip.write_all(&index).map_err(io_err)?;
    let t = zip.finish().map_err(zip_err)?;
    Ok(t.inner)
}

/// A 3D Tiles archive opened for reading through its index.
#[derive(Debug)]
pub struct Archive {
    path: PathBuf,
    /// (hash, local header offset), sorted by [`hash_order`].
    index: Vec<([u8; 16], u64)>,
}

impl Archive {
    /// Opens `path` and reads its index.
    ///
    /// # Errors
    /// [`ArchiveError`]: not a ZIP, no index, or an index of the wrong size or order.
    pub fn open(path: &Path) -> Result<Self, ArchiveError> {
        let file = std::fs::File::open(path).map_err(|source| ArchiveError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut zip = zip::ZipArchive::new(std::io::BufReader::new(file)).map_err(|source| {
            ArchiveError::Zip {
                path: path.to_path_buf(),
                source,
            }
        })?;
        let format = |what: String| ArchiveError::Format {
            path: path.to_path_buf(),
            what,
        };
        let mut bytes = Vec::new();
        zip.by_name(INDEX_ENTRY)
            .map_err(|_| format(format!("no {INDEX_ENTRY} entry")))?
            .read_to_end(&mut bytes)
            .map_err(|source| ArchiveError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        if bytes.len() % 24 != 0 {
            return Err(format(format!(
                "the index holds {} bytes, not a multiple of 24",
                bytes.len()
            )));
        }
        let index: Vec<([u8; 16], u64)> = bytes
            .chunks_exact(24)
            .map(|r| {
                (
                    r[..16].try_into().expect("16 bytes"),
                    u64::from_le_bytes(r[16..].try_into().expect("8 bytes")),
                )
            })
            .collect();
        if index
            .windows(2)
            .any(|w| hash_order(&w[0].0) >= hash_order(&w[1].0))
        {
            return Err(format("the index is not sorted by hash".into()));
        }
        Ok(Self {
            path: path.to_path_buf(),
            index,
        })
    }

    /// Entries in the index.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// True for an archive without entries.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// The local header offset of `entry` (a relative path, `/` separators), found through the
    /// index, or `None`.
    pub fn offset(&self, entry: &str) -> Option<u64> {
        let key = hash_order(&path_hash(entry));
        self.index
            .binary_search_by_key(&key, |(h, _)| hash_order(h))
            .ok()
            .map(|i| self.index[i].1)
    }

    /// The bytes of `entry` (decompressed), or `None` when the index has no such path.
    ///
    /// # Errors
    /// [`ArchiveError`]: the file cannot be read, or the index points at something that is not
    /// that entry's local header.
    pub fn read(&self, entry: &str) -> Result<Option<Vec<u8>>, ArchiveError> {
        let Some(offset) = self.offset(entry) else {
            return Ok(None);
        };
        let io = |source| ArchiveError::Io {
            path: self.path.clone(),
            source,
        };
        let mut f = std::fs::File::open(&self.path).map_err(io)?;
        f.seek(SeekFrom::Start(offset)).map_err(io)?;
        let mut r = std::io::BufReader::new(f);
        let bad = |what: String| ArchiveError::Format {
            path: self.path.clone(),
            what,
        };
        let mut z = zip::read::read_zipfile_from_stream(&mut r)
            .map_err(|e| bad(format!("{entry}: no local header at offset {offset}: {e}")))?
            .ok_or_else(|| bad(format!("{entry}: no local header at offset {offset}")))?;
        let name = z.name().map_err(|e| bad(format!("{entry}: {e}")))?;
        if name != entry {
            return Err(bad(format!(
                "the index sends {entry} to offset {offset}, which holds {name}"
            )));
        }
        let mut out = Vec::with_capacity(z.size() as usize);
        z.read_to_end(&mut out).map_err(io)?;
        Ok(Some(out))
    }
}

/// Where [`super::build_tileset`] writes: a staged folder, or a staging folder packed into an
/// archive file when complete. Either way the final path changes only at [`Staged::commit`].
pub(crate) enum Staged {
    Dir(StagedDir),
    Archive {
        staging: tempfile::TempDir,
        file: AtomicFile,
    },
}

impl Staged {
    /// Starts the output `target`: a tileset folder, or with `archive` a `.3tz` file.
    pub(crate) fn create(target: &Path, archive: bool) -> Result<Self, OutputError> {
        if !archive {
            return Ok(Self::Dir(StagedDir::create(
                target,
                "tileset (tileset.json and tiles/)",
                super::is_tileset_entry,
            )?));
        }
        let file = AtomicFile::create(target)?;
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "tileset".into());
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let staging = tempfile::Builder::new()
            .prefix(&format!(".{name}.new-"))
            .tempdir_in(parent)
            .map_err(|source| OutputError::Io {
                path: target.to_path_buf(),
                source,
            })?;
        Ok(Self::Archive { staging, file })
    }

    /// The folder to write the tileset's files into.
    pub(crate) fn path(&self) -> &Path {
        match self {
            Self::Dir(d) => d.path(),
            Self::Archive { staging, .. } => staging.path(),
        }
    }

    /// Swaps the folder in, or packs it into the archive and renames that into place. Returns
    /// the archive's bytes (`None` for a folder).
    pub(crate) fn commit(self) -> Result<Option<u64>, super::TilesError> {
        match self {
            Self::Dir(d) => {
                d.commit()?;
                Ok(None)
            }
            Self::Archive { staging, file } => {
                let name = file.path().to_path_buf();
                let file = write_archive(staging.path(), file, &name)?;
                file.commit()?;
                // The archive's length (the writer also counts the headers it patched).
                let len = std::fs::metadata(&name).map_err(|source| ArchiveError::Io {
                    path: name.clone(),
                    source,
                })?;
                Ok(Some(len.len()))
            }
        }
    }
}
