//! Reading user files safely: regular files only (a FIFO would block forever, a character
//! device like /dev/zero would be read until memory runs out), with a size limit per kind
//! checked before reading and enforced while reading (a file that grows meanwhile).

use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// What a file holds, and so how large it may be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// JSON and text formats: scene.json, cameras, paths, lights, COLMAP and Bundler text.
    Text,
    /// OBJ and PLY meshes.
    Mesh,
    /// PNG, JPEG, EXR images.
    Image,
    /// Network weights (safetensors).
    Weights,
    /// Binary camera models (COLMAP's cameras.bin, images.bin with their 2D points).
    Binary,
}

impl FileKind {
    /// Bytes at most.
    pub fn limit(self) -> u64 {
        match self {
            FileKind::Text => 256 << 20,
            FileKind::Mesh => 4 << 30,
            FileKind::Image => 2 << 30,
            FileKind::Weights => 4 << 30,
            FileKind::Binary => 2 << 30,
        }
    }

    fn name(self) -> &'static str {
        match self {
            FileKind::Text => "text file",
            FileKind::Mesh => "mesh",
            FileKind::Image => "image",
            FileKind::Weights => "weights file",
            FileKind::Binary => "binary model file",
        }
    }
}

/// What `path` is when it is not a regular file, in words.
fn what_it_is(t: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO (named pipe)"
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

/// Why `path` cannot be opened as what was expected, in words: it does not exist, it is a
/// dangling symlink or a symlink loop, a parent is not a directory, or what it is instead.
pub fn describe_missing(path: &Path) -> String {
    match std::fs::metadata(path) {
        Ok(m) => format!("it is {}", what_it_is(m.file_type())),
        Err(e) if e.raw_os_error() == Some(40) => {
            "it is a symlink loop (too many levels of symbolic links)".into()
        }
        Err(e) if e.raw_os_error() == Some(20) => "a parent in its path is not a directory".into(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if std::fs::symlink_metadata(path).is_ok() {
                "it is a symlink to nothing (a dangling link)".into()
            } else {
                "it does not exist".into()
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => "permission denied".into(),
        Err(e) => e.to_string(),
    }
}

/// Checks that `path` is a regular file (after symlinks) within `kind`'s size limit; returns
/// its size. Errors name the file, what it is instead, or its size against the limit.
pub fn check(path: &Path, kind: FileKind) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|_| {
        Error::input(
            path,
            format!(
                "cannot open the {}: {}",
                kind.name(),
                describe_missing(path)
            ),
        )
    })?;
    if !meta.file_type().is_file() {
        return Err(Error::input(
            path,
            format!(
                "is {}; expected a regular file ({})",
                what_it_is(meta.file_type()),
                kind.name()
            ),
        ));
    }
    if meta.len() > kind.limit() {
        return Err(Error::input(
            path,
            format!(
                "{} is {:.1} MiB; the limit for a {} is {} MiB",
                kind.name(),
                meta.len() as f64 / 1048576.0,
                kind.name(),
                kind.limit() >> 20
            ),
        ));
    }
    Ok(meta.len())
}

/// Reads a whole file after [`check`], never more than the limit.
pub fn read(path: &Path, kind: FileKind) -> Result<Vec<u8>> {
    let size = check(path, kind)?;
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut out = Vec::with_capacity(size as usize);
    f.take(kind.limit() + 1)
        .read_to_end(&mut out)
        .map_err(|e| Error::io(path, e))?;
    if out.len() as u64 > kind.limit() {
        return Err(Error::input(
            path,
            format!(
                "grew past the {} MiB limit while being read",
                kind.limit() >> 20
            ),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::{check, read, FileKind};

    #[test]
    fn devices_directories_and_fifos_are_refused_by_name() {
        let e = read(std::path::Path::new("/dev/zero"), FileKind::Mesh).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let e = check(std::path::Path::new("/tmp"), FileKind::Text).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let dir = std::env::temp_dir().join(format!("relit-fifo-{}", std::process::id()));
        let _ = std::fs::remove_file(&dir);
        let made = std::process::Command::new("mkfifo").arg(&dir).status();
        if made.is_ok_and(|s| s.success()) {
            // Refused without opening it: opening a FIFO blocks until a writer comes.
            let e = read(&dir, FileKind::Image).unwrap_err();
            assert!(e.to_string().contains("FIFO"), "{e}");
            let _ = std::fs::remove_file(&dir);
        }
    }

    #[test]
    fn regular_files_are_read_whole() {
        let p = std::env::temp_dir().join(format!("relit-file-{}", std::process::id()));
        std::fs::write(&p, b"{}").unwrap();
        assert_eq!(read(&p, FileKind::Text).unwrap(), b"{}");
        let _ = std::fs::remove_file(&p);
    }
}
