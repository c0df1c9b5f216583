//! Crash-safe outputs: every file blockwalk writes goes to a temporary name in the folder it is
//! written to and is renamed over the final name only when it is complete, so a killed process,
//! a full disk or an unwritable folder never leaves a truncated file under the final name, and a
//! file that was there before is replaced only on success.
//!
//! - [`AtomicFile`]: one file. Written through to the device when the path names one
//!   (`/dev/stdout`, a FIFO): nothing is renamed over, or removed from, a path that is not a
//!   regular file. A symbolic link is followed: the file it points to is replaced, the link kept.
//! - [`write_bytes`], [`write_with`]: the one-call forms.
//! - [`StagedDir`]: a whole folder (a tileset, a set of BlockMaps, a generated city) written under
//!   a temporary name beside the final one and swapped in when complete. An existing folder is
//!   replaced only if everything in it is of the kind this output writes: a folder holding
//!   anything else is refused before any work is done.
//!
//! The rename is atomic on one file system (POSIX `rename(2)`; `MoveFileEx` on Windows), which is
//! why the temporary name lives in the same folder. A folder swap is two renames: a crash between
//! them leaves the previous folder under `.NAME.old-*` beside the final name, nothing lost.

use std::ffi::OsStr;
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// What went wrong writing an output.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The file system refused a write, a rename or a folder.
    #[error("cannot write {}: {source}{}", path.display(), hint(source))]
    Io {
        /// The final path of the output.
        path: PathBuf,
        /// The system's error.
        source: io::Error,
    },
    /// The output folder holds entries this output does not write; replacing it would lose them.
    #[error(
        "{} holds {} that blockwalk does not write there ({}): give a new or empty folder, or one \
         that holds only a previous {what}",
        path.display(),
        if entries.len() == 1 { "an entry" } else { "entries" },
        entries.join(", ")
    )]
    Foreign {
        /// The output folder.
        path: PathBuf,
        /// What the folder is meant to hold (`a tileset`, ...).
        what: String,
        /// Up to eight of the entries that are not of that kind.
        entries: Vec<String>,
    },
    /// The output path names something that is not a folder where a folder is written, or a
    /// folder where a file is written.
    #[error("cannot write {}: it is {is}, not {wanted}", path.display())]
    WrongKind {
        /// The path.
        path: PathBuf,
        /// What it is.
        is: &'static str,
        /// What was to be written.
        wanted: &'static str,
    },
}

impl OutputError {
    /// The output path the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. } | Self::Foreign { path, .. } | Self::WrongKind { path, .. } => {
                path
            }
        }
    }

    /// The error as an [`io::Error`] of the same kind, its message with the hint (for writers
    /// whose errors carry an `io::Error` and name the path themselves).
    pub fn into_io(self) -> io::Error {
        match self {
            Self::Io { source, .. } => {
                let h = hint(&source);
                if h.is_empty() {
                    source
                } else {
                    io::Error::new(source.kind(), format!("{source}{h}"))
                }
            }
            other => io::Error::other(other.to_string()),
        }
    }
}

fn hint(e: &io::Error) -> &'static str {
    match e.kind() {
        io::ErrorKind::StorageFull | io::ErrorKind::QuotaExceeded => {
            " (the disk is full: nothing was written under this name, and what was there is kept)"
        }
        io::ErrorKind::ReadOnlyFilesystem => " (the file system is mounted read-only)",
        io::ErrorKind::PermissionDenied => " (no permission to write there)",
        _ => "",
    }
}

fn io_at(path: &Path) -> impl Fn(io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The folder a path's file lives in (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Follows symbolic links to the path that is really written (a dangling link's target too).
fn resolve_links(path: &Path) -> io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let t = std::fs::read_link(&p)?;
                p = if t.is_absolute() {
                    t
                } else {
                    parent_of(&p).join(t)
                };
            }
            _ => return Ok(p),
        }
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

enum Sink {
    /// A temporary file beside the final name, renamed over it on commit.
    Temp(BufWriter<tempfile::NamedTempFile>),
    /// The path names a device or a FIFO: written through, never renamed over or removed.
    Direct(BufWriter<File>),
}

/// One output file, written under a temporary name and renamed over its final name by
/// [`AtomicFile::commit`]. Dropped without a commit, it removes its temporary file and leaves the
/// final name as it was.
pub struct AtomicFile {
    /// The path given (reported in errors).
    path: PathBuf,
    /// The path really replaced (links followed).
    target: PathBuf,
    sink: Sink,
    written: u64,
}

impl std::fmt::Debug for AtomicFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AtomicFile")
            .field("path", &self.path)
            .field("written", &self.written)
            .finish()
    }
}

/// Buffer of the writers: large enough that a `.glb` streams in few system calls.
const BUFFER: usize = 1 << 20;

impl AtomicFile {
    /// Starts writing `path`.
    ///
    /// # Errors
    /// [`OutputError::Io`] when the folder cannot take a new file (missing, read-only, no
    /// permission), [`OutputError::WrongKind`] when `path` is a folder.
    pub fn create(path: &Path) -> Result<Self, OutputError> {
        let target = resolve_links(path).map_err(io_at(path))?;
        let sink = match std::fs::metadata(&target) {
            Ok(m) if m.is_dir() => {
                return Err(OutputError::WrongKind {
                    path: path.to_path_buf(),
                    is: "a folder",
                    wanted: "a file",
                })
            }
            Ok(m) if !m.is_file() => {
                let f = OpenOptions::new()
                    .write(true)
                    .open(&target)
                    .map_err(io_at(path))?;
                Sink::Direct(BufWriter::with_capacity(BUFFER, f))
            }
            _ => {
                let name = target
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "output".into());
                let prefix = format!(".{name}.");
                let mut b = tempfile::Builder::new();
                b.prefix(&prefix).suffix(".part");
                #[cfg(unix)]
                {
                    use std::os::unix::fs::PermissionsExt;
                    // The mode a plain `File::create` gives (the umask applies), not 0600.
                    b.permissions(std::fs::Permissions::from_mode(0o666));
                }
                let t = b.tempfile_in(parent_of(&target)).map_err(io_at(path))?;
                Sink::Temp(BufWriter::with_capacity(BUFFER, t))
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            target,
            sink,
            written: 0,
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Bytes written so far.
    pub fn written(&self) -> u64 {
        self.written
    }

    /// Flushes the file to disk and renames it over the final name; returns the bytes written.
    ///
    /// # Errors
    /// [`OutputError::Io`] (a full disk shows here, at the latest); the final name is then
    /// untouched and the temporary file removed.
    pub fn commit(self) -> Result<u64, OutputError> {
        let err = io_at(&self.path);
        match self.sink {
            Sink::Direct(mut w) => {
                w.flush().map_err(&err)?;
            }
            Sink::Temp(w) => {
                let t = w.into_inner().map_err(|e| err(e.into_error()))?;
                t.as_file().sync_data().map_err(&err)?;
                if let Ok(m) = std::fs::metadata(&self.target) {
                    // Replacing a file keeps its permissions.
                    let _ = t.as_file().set_permissions(m.permissions());
                }
                t.persist(&self.target).map_err(|e| err(e.error))?;
            }
        }
        Ok(self.written)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = match &mut self.sink {
            Sink::Temp(w) => w.write(buf)?,
            Sink::Direct(w) => w.write(buf)?,
        };
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.sink {
            Sink::Temp(w) => w.flush(),
            Sink::Direct(w) => w.flush(),
        }
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        match &mut self.sink {
            Sink::Temp(w) => w.seek(pos),
            Sink::Direct(w) => w.seek(pos),
        }
    }
}

/// Writes `bytes` to `path` through an [`AtomicFile`]; returns the length.
///
/// # Errors
/// [`OutputError`] naming `path`.
pub fn write_bytes(path: &Path, bytes: impl AsRef<[u8]>) -> Result<u64, OutputError> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes.as_ref()).map_err(io_at(path))?;
    f.commit()
}

/// Writes `path` with `write` through an [`AtomicFile`], committed only when `write` succeeds.
/// Returns what `write` returns and the bytes written.
///
/// # Errors
/// `write`'s error (the final name untouched), or [`OutputError`] converted into `E`.
pub fn write_with<T, E: From<OutputError>>(
    path: &Path,
    write: impl FnOnce(&mut AtomicFile) -> Result<T, E>,
) -> Result<(T, u64), E> {
    let mut f = AtomicFile::create(path)?;
    let t = write(&mut f)?;
    let n = f.commit()?;
    Ok((t, n))
}

/// Writes an image as PNG through an [`AtomicFile`]; returns the bytes written.
///
/// # Errors
/// What `image` says; a refused write is its `IoError`, the message naming the reason.
pub fn write_png<P, C>(
    path: &Path,
    img: &image::ImageBuffer<P, C>,
) -> Result<u64, image::ImageError>
where
    P: image::Pixel + image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let io = |e: OutputError| image::ImageError::IoError(e.into_io());
    let mut f = AtomicFile::create(path).map_err(io)?;
    img.write_to(&mut f, image::ImageFormat::Png)?;
    f.commit().map_err(io)
}

/// An output folder written under a temporary name beside its final path and swapped in by
/// [`StagedDir::commit`]. Dropped without a commit, it removes the staging folder; the final
/// folder is as it was.
#[derive(Debug)]
pub struct StagedDir {
    target: PathBuf,
    staging: Option<tempfile::TempDir>,
    owns: fn(&OsStr) -> bool,
    what: String,
}

impl StagedDir {
    /// Starts writing the folder `target`. An existing `target` must be a folder whose entries
    /// all satisfy `owns` (the names this kind of output writes); it is checked now and again at
    /// the commit. `what` names the output in errors (`a tileset`).
    ///
    /// # Errors
    /// [`OutputError::Foreign`] for a folder holding anything else, [`OutputError::WrongKind`]
    /// for a file, [`OutputError::Io`] when the parent folder cannot be created or written.
    pub fn create(
        target: &Path,
        what: &str,
        owns: fn(&OsStr) -> bool,
    ) -> Result<Self, OutputError> {
        let s = Self {
            target: target.to_path_buf(),
            staging: None,
            owns,
            what: what.to_string(),
        };
        s.check_target()?;
        let parent = parent_of(target);
        std::fs::create_dir_all(parent).map_err(io_at(target))?;
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "output".into());
        let dir = tempfile::Builder::new()
            .prefix(&format!(".{name}.new-"))
            .tempdir_in(parent)
            .map_err(io_at(target))?;
        Ok(Self {
            staging: Some(dir),
            ..s
        })
    }

    fn check_target(&self) -> Result<(), OutputError> {
        let meta = match std::fs::symlink_metadata(&self.target) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(io_at(&self.target)(e)),
        };
        if !meta.is_dir() {
            return Err(OutputError::WrongKind {
                path: self.target.clone(),
                is: if meta.file_type().is_symlink() {
                    "a symbolic link"
                } else {
                    "a file"
                },
                wanted: "a folder",
            });
        }
        let mut foreign = Vec::new();
        for e in std::fs::read_dir(&self.target).map_err(io_at(&self.target))? {
            let e = e.map_err(io_at(&self.target))?;
            if !(self.owns)(&e.file_name()) {
                foreign.push(e.file_name().to_string_lossy().into_owned());
            }
        }
        if foreign.is_empty() {
            return Ok(());
        }
        foreign.sort();
        foreign.truncate(8);
        Err(OutputError::Foreign {
            path: self.target.clone(),
            what: self.what.clone(),
            entries: foreign,
        })
    }

    /// The folder to write into (the staging folder).
    pub fn path(&self) -> &Path {
        self.staging.as_ref().map_or(&self.target, |d| d.path())
    }

    /// The final folder.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Swaps the written folder in: the previous folder, if any, is moved aside and removed.
    ///
    /// # Errors
    /// [`OutputError`]: the final folder is then as it was.
    pub fn commit(mut self) -> Result<(), OutputError> {
        self.check_target()?;
        let staging = self
            .staging
            .take()
            .expect("a staged folder has its staging folder");
        let err = io_at(&self.target);
        if std::fs::symlink_metadata(&self.target).is_err() {
            let from = staging.keep();
            return std::fs::rename(&from, &self.target).map_err(|e| {
                let _ = std::fs::remove_dir_all(&from);
                err(e)
            });
        }
        let name = self
            .target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "output".into());
        // A free name for the previous folder, beside it.
        let old = tempfile::Builder::new()
            .prefix(&format!(".{name}.old-"))
            .tempdir_in(parent_of(&self.target))
            .map_err(&err)?
            .keep();
        std::fs::remove_dir(&old).map_err(&err)?;
        std::fs::rename(&self.target, &old).map_err(&err)?;
        let from = staging.keep();
        if let Err(e) = std::fs::rename(&from, &self.target) {
            let _ = std::fs::rename(&old, &self.target);
            let _ = std::fs::remove_dir_all(&from);
            return Err(err(e));
        }
        std::fs::remove_dir_all(&old).map_err(&err)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_committed_file_replaces_the_old_one_and_leaves_no_temporary() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.txt");
        std::fs::write(&p, "old").unwrap();
        assert_eq!(write_bytes(&p, b"new").unwrap(), 3);
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "new");
        assert_eq!(names(d.path()), vec!["a.txt"]);
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_removes_the_temporary() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.txt");
        std::fs::write(&p, "old").unwrap();
        let r: Result<((), u64), OutputError> = write_with(&p, |f| {
            f.write_all(b"half").unwrap();
            assert_eq!(
                names(d.path()).len(),
                2,
                "the temporary sits beside the file"
            );
            Err(io_at(&p)(io::Error::other("stopped")))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "old");
        assert_eq!(names(d.path()), vec!["a.txt"]);
    }

    #[test]
    fn an_uncommitted_file_leaves_no_final_name() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("b.glb");
        let mut f = AtomicFile::create(&p).unwrap();
        f.write_all(&[0; 1000]).unwrap();
        drop(f);
        assert!(names(d.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn a_link_is_followed_and_kept_and_a_device_is_written_through() {
        let d = tempfile::tempdir().unwrap();
        let real = d.path().join("real.txt");
        std::fs::write(&real, "old").unwrap();
        let link = d.path().join("link.txt");
        std::os::unix::fs::symlink("real.txt", &link).unwrap();
        write_bytes(&link, "new").unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "new");
        // A device: written through, and still there after a write.
        write_bytes(Path::new("/dev/null"), "x").unwrap();
        assert!(Path::new("/dev/null").exists());
        // /dev/full refuses the bytes: the error names the path and the device stays.
        if Path::new("/dev/full").exists() {
            let e = write_bytes(Path::new("/dev/full"), vec![0u8; 4 << 20]).unwrap_err();
            assert!(e.to_string().contains("/dev/full"), "{e}");
            assert!(Path::new("/dev/full").exists());
        }
    }

    #[test]
    fn a_folder_is_not_a_file() {
        let d = tempfile::tempdir().unwrap();
        let e = write_bytes(d.path(), "x").unwrap_err();
        assert!(matches!(e, OutputError::WrongKind { .. }), "{e}");
    }

    fn tileset_names(n: &OsStr) -> bool {
        n == "tileset.json" || n == "tiles"
    }

    #[test]
    fn a_staged_folder_swaps_in_whole_and_replaces_only_its_own_kind() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("tiles");
        // New folder.
        let s = StagedDir::create(&out, "a tileset", tileset_names).unwrap();
        std::fs::write(s.path().join("tileset.json"), "1").unwrap();
        assert!(
            !out.exists(),
            "nothing under the final name before the commit"
        );
        s.commit().unwrap();
        assert_eq!(
            std::fs::read_to_string(out.join("tileset.json")).unwrap(),
            "1"
        );
        // Replaced: the old content is gone, the new one complete.
        std::fs::create_dir(out.join("tiles")).unwrap();
        std::fs::write(out.join("tiles/old.glb"), "old").unwrap();
        let s = StagedDir::create(&out, "a tileset", tileset_names).unwrap();
        std::fs::write(s.path().join("tileset.json"), "2").unwrap();
        s.commit().unwrap();
        assert_eq!(names(&out), vec!["tileset.json"]);
        assert_eq!(
            names(d.path()),
            vec!["tiles"],
            "no staging or old folder left"
        );
        // Dropped: the final folder stays as it was, the staging folder goes.
        let s = StagedDir::create(&out, "a tileset", tileset_names).unwrap();
        std::fs::write(s.path().join("tileset.json"), "3").unwrap();
        drop(s);
        assert_eq!(
            std::fs::read_to_string(out.join("tileset.json")).unwrap(),
            "2"
        );
        assert_eq!(names(d.path()), vec!["tiles"]);
        // A folder with anything else is refused before any work.
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        let e = StagedDir::create(&out, "a tileset", tileset_names).unwrap_err();
        assert!(matches!(e, OutputError::Foreign { .. }), "{e}");
        assert!(e.to_string().contains("notes.txt"), "{e}");
        assert!(out.join("notes.txt").exists());
        // A file where a folder goes.
        let e = StagedDir::create(&out.join("notes.txt"), "a tileset", tileset_names).unwrap_err();
        assert!(matches!(e, OutputError::WrongKind { .. }), "{e}");
    }
}
