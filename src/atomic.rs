//! Atomic file writing: readers of `path` see either the old file or the complete new
//! one, never a partial write. Only regular files are ever replaced: a symlink is
//! followed (its target is replaced atomically), character devices and FIFOs
//! (`/dev/stdout`, a named pipe) are written through, and `-` is standard output.

use std::fs::{self, File, OpenOptions, Permissions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Where a write to a path goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Destination {
    /// `-`: standard output.
    Stdout,
    /// An existing character device or FIFO, written through in place.
    Stream(PathBuf),
    /// A regular file (existing or not), replaced atomically; symlinks already followed.
    File(PathBuf),
}

impl Destination {
    /// Whether the output is a stream (standard output, a device, a FIFO) rather than a
    /// file: such outputs have no extension to choose a format by.
    pub fn is_stream(&self) -> bool {
        !matches!(self, Destination::File(_))
    }
}

/// Classifies `path`: `-`, a device or FIFO to write through, or the regular file a
/// write replaces (following symlinks, dangling ones included). Directories, block
/// devices and sockets are refused with [`io::ErrorKind::InvalidInput`].
pub fn destination(path: &Path) -> io::Result<Destination> {
    if path.as_os_str() == "-" {
        return Ok(Destination::Stdout);
    }
    let target = follow_symlinks(path)?;
    let Ok(meta) = fs::metadata(&target) else {
        return Ok(Destination::File(target));
    };
    let refuse = |what: &str| {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("the target path is {what}; expected a file path"),
        ))
    };
    if meta.is_file() {
        Ok(Destination::File(target))
    } else if meta.is_dir() {
        refuse("an existing directory")
    } else if is_char_device_or_fifo(&meta) {
        Ok(Destination::Stream(target))
    } else {
        refuse("a block device or socket, which is never written")
    }
}

/// The path a chain of symlinks at `path` ends at (`path` itself when it is none);
/// relative links are resolved against their own folder.
fn follow_symlinks(path: &Path) -> io::Result<PathBuf> {
    let mut current = path.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&current) {
            Ok(meta) if meta.file_type().is_symlink() => {
                let link = fs::read_link(&current)?;
                current = parent_dir(&current).join(link);
            }
            _ => return Ok(current),
        }
    }
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        "too many levels of symbolic links",
    ))
}

#[cfg(unix)]
fn is_char_device_or_fifo(meta: &fs::Metadata) -> bool {
    use std::os::unix::fs::FileTypeExt;
    meta.file_type().is_char_device() || meta.file_type().is_fifo()
}

#[cfg(not(unix))]
fn is_char_device_or_fifo(_: &fs::Metadata) -> bool {
    false
}

/// Writes a file atomically.
///
/// `write` receives a buffered writer on a temporary file created in the directory of
/// the file (after following symlinks). When it succeeds the data is flushed and fsynced
/// and the temporary file is renamed over the file. On any error the temporary file is
/// removed and the file is left untouched. An existing file keeps its permission bits;
/// a new one gets the usual `0o666` minus the umask on Unix (not the `0o600` of a bare
/// temporary file). Devices, FIFOs and `-` are written through (see [`destination`]).
///
/// Fails with [`io::ErrorKind::InvalidInput`] when `path` is an existing directory.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    match destination(path)? {
        Destination::Stdout => write_through(io::stdout().lock(), write),
        Destination::Stream(device) => {
            write_through(OpenOptions::new().write(true).open(device)?, write)
        }
        Destination::File(file) => replace_file(&file, |w| write(w)),
    }
}

/// [`write_atomic`] for writers that seek as they write (a TIFF encoder): only a
/// regular file can take them, so `-`, devices and FIFOs are refused with
/// [`io::ErrorKind::InvalidInput`].
pub fn write_atomic_seekable(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> io::Result<()>,
) -> io::Result<()> {
    match destination(path)? {
        Destination::File(file) => replace_file(&file, write),
        _ => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "this output seeks while it is written: name a regular file",
        )),
    }
}

/// Writes to a stream through a buffer and flushes it.
fn write_through(
    stream: impl Write,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    let mut writer = BufWriter::new(stream);
    write(&mut writer)?;
    writer.flush()
}

/// The temporary-file-and-rename write of a regular file.
fn replace_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> io::Result<()>,
) -> io::Result<()> {
    let mut out = AtomicFile::replacing(path)?;
    {
        let mut writer = BufWriter::new(out.file());
        write(&mut writer)?;
        writer.flush()?;
    }
    out.commit()
}

/// A regular file written a piece at a time, across calls, under a temporary name beside
/// its destination: [`AtomicFile::commit`] renames it into place; dropping it uncommitted
/// removes it and leaves the destination untouched. The handle form of
/// [`write_atomic_seekable`], for writers that outlive one closure.
pub struct AtomicFile {
    temp: tempfile::NamedTempFile,
    path: PathBuf,
}

impl AtomicFile {
    /// Starts replacing `path` (symlinks followed). Like [`write_atomic_seekable`], only a
    /// regular file can take a writer that seeks: `-`, devices and FIFOs are refused with
    /// [`io::ErrorKind::InvalidInput`], and so are directories.
    pub fn create(path: &Path) -> io::Result<AtomicFile> {
        match destination(path)? {
            Destination::File(file) => AtomicFile::replacing(&file),
            _ => Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "this output seeks while it is written: name a regular file",
            )),
        }
    }

    /// The temporary file for the regular file `path` (already resolved).
    fn replacing(path: &Path) -> io::Result<AtomicFile> {
        let mut builder = tempfile::Builder::new();
        builder.prefix(".wavemesh-tmp-");
        if let Some(permissions) = target_permissions(path) {
            builder.permissions(permissions);
        }
        Ok(AtomicFile {
            temp: builder.tempfile_in(parent_dir(path))?,
            path: path.to_path_buf(),
        })
    }

    /// The temporary file, to write (and seek) in.
    pub fn file(&mut self) -> &mut File {
        self.temp.as_file_mut()
    }

    /// Syncs the temporary file and renames it over the destination.
    pub fn commit(self) -> io::Result<()> {
        self.temp.as_file().sync_all()?;
        self.temp.persist(&self.path).map_err(|e| e.error)?;
        sync_dir(&parent_dir(&self.path));
        Ok(())
    }
}

/// The directory holding `path` (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Permissions for the new file: those of the file being replaced, else the platform
/// default for a newly created file.
fn target_permissions(path: &Path) -> Option<Permissions> {
    match fs::metadata(path) {
        Ok(meta) => Some(meta.permissions()),
        Err(_) => default_permissions(),
    }
}

#[cfg(unix)]
fn default_permissions() -> Option<Permissions> {
    use std::os::unix::fs::PermissionsExt;
    // Passed to open(2), so the process umask still applies.
    Some(Permissions::from_mode(0o666))
}

#[cfg(not(unix))]
fn default_permissions() -> Option<Permissions> {
    None
}

/// Makes the rename durable (best effort: not every platform can fsync a directory).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = fs::File::open(dir) {
        // Ignored on purpose: the data itself is already synced and renamed.
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leftovers(dir: &Path) -> Vec<String> {
        fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".wavemesh-tmp-"))
            .collect()
    }

    #[test]
    fn writes_new_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        write_atomic(&path, |w| w.write_all(b"hello")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"hello");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn replaces_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        fs::write(&path, b"old contents").unwrap();
        write_atomic(&path, |w| w.write_all(b"new")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
    }

    #[test]
    fn error_leaves_target_untouched_and_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        fs::write(&path, b"old").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("boom"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "boom");
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn atomic_file_commits_or_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        fs::write(&path, b"old").unwrap();
        let mut abandoned = AtomicFile::create(&path).unwrap();
        abandoned.file().write_all(b"partial").unwrap();
        drop(abandoned);
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert!(leftovers(dir.path()).is_empty());
        let mut out = AtomicFile::create(&path).unwrap();
        out.file().write_all(b"new").unwrap();
        out.commit().unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert!(leftovers(dir.path()).is_empty());
        let err = AtomicFile::create(Path::new("-")).err().unwrap();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn refuses_directory() {
        let dir = tempfile::tempdir().unwrap();
        let err = write_atomic(dir.path(), |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("directory"));
    }

    #[test]
    fn missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/out.bin");
        assert!(write_atomic(&path, |w| w.write_all(b"x")).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn follows_a_symlink_and_replaces_its_target() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("real.bin");
        fs::write(&target, b"old").unwrap();
        let link = dir.path().join("link.bin");
        std::os::unix::fs::symlink("real.bin", &link).unwrap();
        write_atomic(&link, |w| w.write_all(b"new")).unwrap();
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read(&target).unwrap(), b"new");
        // A dangling link creates its target.
        let dangling = dir.path().join("dangling.bin");
        std::os::unix::fs::symlink("created.bin", &dangling).unwrap();
        write_atomic(&dangling, |w| w.write_all(b"made")).unwrap();
        assert_eq!(fs::read(dir.path().join("created.bin")).unwrap(), b"made");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn writes_through_devices_and_never_replaces_them() {
        use std::os::unix::fs::FileTypeExt;
        let null = Path::new("/dev/null");
        assert_eq!(
            destination(null).unwrap(),
            Destination::Stream(null.to_path_buf())
        );
        write_atomic(null, |w| w.write_all(b"discarded")).unwrap();
        assert!(fs::metadata(null).unwrap().file_type().is_char_device());
        assert_eq!(destination(Path::new("-")).unwrap(), Destination::Stdout);
    }

    #[cfg(unix)]
    #[test]
    fn symlink_loops_are_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a");
        std::os::unix::fs::symlink("b", &a).unwrap();
        std::os::unix::fs::symlink("a", dir.path().join("b")).unwrap();
        assert!(write_atomic(&a, |w| w.write_all(b"x")).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn keeps_permissions_of_replaced_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        fs::write(&path, b"old").unwrap();
        fs::set_permissions(&path, Permissions::from_mode(0o640)).unwrap();
        write_atomic(&path, |w| w.write_all(b"new")).unwrap();
        let mode = fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o640);
    }
}
