//! Opening the files a run keeps for itself (cache entries, the lock, manifests) so that a link
//! or a special file planted in their place is seen, never followed or waited on.
//!
//! Every open refuses a symbolic link as its last component (`O_NOFOLLOW`) and never blocks
//! on a pipe (`O_NONBLOCK`); the handle's own metadata then says whether it is a regular file,
//! so a pipe, a device or a folder is reported instead of read. Reads are bounded by the
//! caller's cap and by the length the handle reports.

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Why a file kept by a run could not be used; each maps to a sentence for the user.
#[derive(Debug)]
pub enum Refused {
    /// Nothing is there.
    Missing,
    /// A symbolic link stands where a file was expected.
    Link,
    /// A pipe, a device, a socket or a folder stands where a file was expected.
    Special,
    /// The file is longer than the cap.
    TooLarge(u64),
    /// Any other failure of the machine.
    Io(std::io::Error),
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::Missing => f.write_str("it does not exist"),
            Refused::Link => f.write_str("it is a symbolic link"),
            Refused::Special => f.write_str("it is not a regular file (a pipe, a device or a folder)"),
            Refused::TooLarge(n) => write!(f, "it is larger than the {} MiB limit", n / (1024 * 1024)),
            Refused::Io(e) => write!(f, "{e}"),
        }
    }
}

#[cfg(unix)]
fn with_flags(o: &mut std::fs::OpenOptions) -> &mut std::fs::OpenOptions {
    use std::os::unix::fs::OpenOptionsExt;
    o.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
}

#[cfg(not(unix))]
fn with_flags(o: &mut std::fs::OpenOptions) -> &mut std::fs::OpenOptions {
    o
}

fn refused(e: std::io::Error, path: &Path) -> Refused {
    match e.kind() {
        std::io::ErrorKind::NotFound => Refused::Missing,
        _ if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) => Refused::Link,
        // A pipe opened for writing with no reader, or a device that refuses the flags.
        _ if std::fs::symlink_metadata(path).is_ok_and(|m| !m.is_file()) => Refused::Special,
        _ => Refused::Io(e),
    }
}

/// Opens `path` with `options` (plus no-follow and non-blocking) and checks that the handle is
/// a regular file.
pub fn open_regular(path: &Path, options: &mut std::fs::OpenOptions) -> Result<File, Refused> {
    // Without the flags a link would be followed (Windows), so check the name first too.
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        return Err(Refused::Link);
    }
    let f = with_flags(options).open(path).map_err(|e| refused(e, path))?;
    let meta = f.metadata().map_err(Refused::Io)?;
    if !meta.is_file() {
        return Err(Refused::Special);
    }
    Ok(f)
}

/// Reads a regular file of at most `cap` bytes whole; the allocation grows with what is
/// actually read, never with a length the file claims.
pub fn read_regular(path: &Path, cap: u64) -> Result<Vec<u8>, Refused> {
    read_capped(open_regular(path, std::fs::OpenOptions::new().read(true))?, cap)
}

/// As [`read_regular`], for a file the user names (a plugin's component): a link is followed
/// to a regular file, but a pipe or a device is still refused, never waited on.
pub fn read_regular_via_links(path: &Path, cap: u64) -> Result<Vec<u8>, Refused> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut o, libc::O_NONBLOCK);
    let f = o.open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Refused::Missing,
        _ => Refused::Io(e),
    })?;
    if !f.metadata().map_err(Refused::Io)?.is_file() {
        return Err(Refused::Special);
    }
    read_capped(f, cap)
}

fn read_capped(f: File, cap: u64) -> Result<Vec<u8>, Refused> {
    let len = f.metadata().map_err(Refused::Io)?.len();
    if len > cap {
        return Err(Refused::TooLarge(cap));
    }
    let mut bytes = Vec::new();
    f.take(cap + 1).read_to_end(&mut bytes).map_err(Refused::Io)?;
    if bytes.len() as u64 > cap {
        return Err(Refused::TooLarge(cap));
    }
    Ok(bytes)
}

/// Whether `path` itself (not what it points to) is a symbolic link.
pub fn is_link(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink())
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn links_pipes_and_devices_are_refused_without_waiting_or_reading() {
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("f");
        std::fs::write(&file, b"abc").unwrap();
        assert_eq!(read_regular(&file, 10).unwrap(), b"abc");
        assert!(matches!(read_regular(&file, 2), Err(Refused::TooLarge(2))));

        let link = tmp.path().join("l");
        std::os::unix::fs::symlink(&file, &link).unwrap();
        assert!(matches!(read_regular(&link, 10), Err(Refused::Link)));

        let zero = tmp.path().join("z");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        assert!(matches!(read_regular(&zero, 10), Err(Refused::Link)));
        assert!(matches!(read_regular(Path::new("/dev/zero"), 10), Err(Refused::Special)));

        let fifo = tmp.path().join("p");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo only creates the node.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        assert!(matches!(read_regular(&fifo, 10), Err(Refused::Special)));
        let mut w = std::fs::OpenOptions::new();
        w.write(true);
        assert!(matches!(open_regular(&fifo, &mut w), Err(Refused::Special)));
        assert!(matches!(read_regular(&tmp.path().join("none"), 10), Err(Refused::Missing)));
        assert_eq!(read_regular_via_links(&link, 10).unwrap(), b"abc");
        assert!(matches!(read_regular_via_links(&zero, 10), Err(Refused::Special)));
        assert!(matches!(read_regular_via_links(&fifo, 10), Err(Refused::Special)));
    }
}
