//! The library's error type. Every error that comes from input names the file and what was
//! expected, so that a user can fix the input without reading the code.

use std::path::{Path, PathBuf};

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Input data is malformed: `file`, then what is wrong and what was expected.
    #[error("{}: {msg}", file.display())]
    Input { file: PathBuf, msg: String },
    /// A file could not be read or written.
    #[error("{}: {source}", file.display())]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The Vulkan device lacks something Relit needs.
    #[error("{0}")]
    Device(String),
    /// A Vulkan call failed.
    #[error("Vulkan: {what}: {result}")]
    Vk {
        what: &'static str,
        result: ash::vk::Result,
    },
    #[error("{0}")]
    Other(String),
}

impl Error {
    pub fn input(file: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Error::Input {
            file: file.as_ref().to_path_buf(),
            msg: msg.into(),
        }
    }
    pub fn io(file: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            file: file.as_ref().to_path_buf(),
            source,
        }
    }
}

/// Attaches a description to a failed Vulkan call.
pub trait VkContext<T> {
    fn vk(self, what: &'static str) -> Result<T>;
}

impl<T> VkContext<T> for std::result::Result<T, ash::vk::Result> {
    fn vk(self, what: &'static str) -> Result<T> {
        self.map_err(|result| Error::Vk { what, result })
    }
}

impl From<gpu_allocator::AllocationError> for Error {
    fn from(e: gpu_allocator::AllocationError) -> Self {
        Error::Other(format!("GPU memory allocation: {e}"))
    }
}
