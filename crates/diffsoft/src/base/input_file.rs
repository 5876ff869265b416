//! Input text files read one way everywhere (scenes, meshes): what the path really is is
//! checked first (a device or directory is refused by name instead of read until memory runs
//! out), and a UTF-8 byte-order mark, invisible in editors, is dropped instead of becoming part
//! of the first token.

use std::path::Path;

/// What a file that is not a regular one is, in words, for error messages.
pub(crate) fn kind_of(t: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt as _;
    if t.is_file() {
        "a regular file"
    } else if t.is_dir() {
        "a directory"
    } else if t.is_symlink() {
        "a symbolic link"
    } else if t.is_fifo() {
        "a named pipe (FIFO)"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// The text of input file `path` (links followed): a regular file or a pipe (`<(...)`, a FIFO),
/// UTF-8, a leading byte-order mark removed. A directory, device or socket is an error saying
/// what it is; errors do not repeat the path (callers name it).
pub fn read_text(path: &Path) -> std::io::Result<String> {
    if path.as_os_str().is_empty() {
        // The system's "No such file or directory" after an empty name says nothing.
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the file name is empty",
        ));
    }
    let meta = std::fs::metadata(path)?;
    let t = meta.file_type();
    #[cfg(unix)]
    let readable = t.is_file() || std::os::unix::fs::FileTypeExt::is_fifo(&t);
    #[cfg(not(unix))]
    let readable = t.is_file();
    if !readable {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("is {}, not a file to read", kind_of(&t)),
        ));
    }
    let bytes = std::fs::read(path)?;
    text_of(&bytes).map(str::to_owned)
}

/// The text of an input file's `bytes` read as [`read_text`] reads a file's (for contents
/// carried in memory): UTF-8, a leading byte-order mark removed; other bytes are an
/// [`InvalidData`](std::io::ErrorKind::InvalidData) error that does not name the file.
pub(crate) fn text_of(bytes: &[u8]) -> std::io::Result<&str> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (binary files are not supported): {e}"),
        )
    })?;
    Ok(text.strip_prefix('\u{feff}').unwrap_or(text))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_directories_are_refused_and_a_byte_order_mark_dropped() {
        let e = read_text(Path::new("/dev/zero")).unwrap_err();
        assert!(
            e.to_string().contains("is a character device, not a file to read"),
            "{e}"
        );
        let e = read_text(Path::new("/")).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        let e = read_text(Path::new("")).unwrap_err();
        assert_eq!(e.to_string(), "the file name is empty");
        let dir = std::env::temp_dir().join(format!("diffsoft-input-text-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("bom.obj");
        std::fs::write(&p, "\u{feff}v 0 0 0\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "v 0 0 0\n");
        std::fs::write(&p, [0x76, 0xff, 0x0a]).unwrap();
        assert!(read_text(&p).unwrap_err().to_string().contains("not UTF-8"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bytes_in_memory_read_as_a_files_text() {
        assert_eq!(text_of(b"\xef\xbb\xbfv 1 2 3\n").unwrap(), "v 1 2 3\n");
        assert_eq!(text_of(b"t 0 1 2 3").unwrap(), "t 0 1 2 3");
        let e = text_of(&[0x76, 0xff, 0x0a]).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        assert!(e.to_string().starts_with("not UTF-8 text"), "{e}");
    }
}
