//! A file a rebuilt paper scene carries in memory ([`CarriedFile`]): its contents and the path
//! its messages name.

use std::path::{Path, PathBuf};

/// A file a paper scene names, carried in memory (a scene rebuilt elsewhere from the files it
/// read, such as a pickled one): its bytes, and the path that messages, notes and
/// [`MeshInfo::path`](crate::mesh::MeshInfo::path) name for it (the file it was read from, or
/// the name the scene gives it). No file is read or written at that path.
///
/// ```
/// use diffsoft::scene::paper::CarriedFile;
///
/// let f = CarriedFile::new("/data/fish/fish.obj", b"v 0 0 0\n".to_vec());
/// assert_eq!(f.shown(), std::path::Path::new("/data/fish/fish.obj"));
/// assert_eq!(f.bytes(), b"v 0 0 0\n");
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CarriedFile {
    shown: PathBuf,
    bytes: Vec<u8>,
}

impl CarriedFile {
    /// The file with contents `bytes`, named `shown` in messages.
    ///
    /// ```
    /// use diffsoft::scene::paper::CarriedFile;
    ///
    /// let f = CarriedFile::new("muscles/octopus.muscle", "0 0 0 0 0\n");
    /// assert_eq!(f.bytes().len(), 10);
    /// ```
    pub fn new(shown: impl Into<PathBuf>, bytes: impl Into<Vec<u8>>) -> Self {
        Self {
            shown: shown.into(),
            bytes: bytes.into(),
        }
    }

    /// The path messages name for the file.
    pub fn shown(&self) -> &Path {
        &self.shown
    }

    /// The file's contents.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The contents as text, as a file's text is read from disk (UTF-8, a leading byte-order
    /// mark removed); other bytes are an error that does not name the file.
    pub(super) fn text(&self) -> std::io::Result<&str> {
        crate::base::input_file::text_of(&self.bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_drops_a_byte_order_mark_and_refuses_bytes_that_are_not_utf8() {
        let f = CarriedFile::new("a.obj", b"\xef\xbb\xbfv 0 0 0\n".to_vec());
        assert_eq!(f.text().unwrap(), "v 0 0 0\n");
        let bad = CarriedFile::new("a.obj", vec![b'v', 0xff]);
        let e = bad.text().unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("not UTF-8"), "{e}");
    }
}
