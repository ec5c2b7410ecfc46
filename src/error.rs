//! The one error type of the library. Every message a user can see names the file
//! (and line where known) and what was expected.

use std::path::PathBuf;

/// Everything that can go wrong in arbor, from reading a scene to running a kernel.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    /// (`cause` is deliberately not a `#[source]`: the message already carries it,
    /// and error chains would print it twice.)
    #[error("{path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    /// A file's content is malformed at a known line (1-based).
    #[error("{path}:{line}: {msg}")]
    Parse { path: PathBuf, line: usize, msg: String },
    /// A file's content is wrong, with no single line to blame.
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
    /// The scene as a whole is unusable (empty, bad camera, unknown material, ...).
    #[error("scene {scene}: {msg}")]
    Scene { scene: String, msg: String },
    /// A command-line value is out of range or malformed.
    #[error("{0}")]
    Usage(String),
    /// No usable Vulkan device, or the requested one does not exist.
    #[error("no Vulkan device: {0}")]
    NoDevice(String),
    /// A Vulkan call failed. `result` is the driver's VkResult name.
    #[error("Vulkan: {what} failed: {result}")]
    Vulkan { what: String, result: String },
    /// A storage buffer exceeds the device's maxStorageBufferRange.
    #[error(
        "buffer '{name}' needs {size} bytes but the device allows at most {limit} bytes per storage buffer (maxStorageBufferRange); the scene is too large for this device"
    )]
    BufferTooLarge { name: String, size: u64, limit: u64 },
    /// A pipeline would bind more storage buffers per stage than the project allows.
    #[error("pipeline '{name}' binds {count} storage buffers; at most {limit} per stage are allowed")]
    TooManyStorageBuffers { name: String, count: usize, limit: usize },
    /// The Khronos validation layer reported errors.
    #[error("Vulkan validation reported {count} error(s); first: {first}")]
    Validation { count: usize, first: String },
}

/// Shorthand used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), cause: source }
    }
    /// A parse error at `line` (1-based) of `path`.
    pub fn parse(path: impl Into<PathBuf>, line: usize, msg: impl Into<String>) -> Self {
        Error::Parse { path: path.into(), line, msg: msg.into() }
    }
    /// Invalid content in `path` with no line to blame.
    pub fn invalid(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Invalid { path: path.into(), msg: msg.into() }
    }
    /// A whole-scene problem.
    pub fn scene(scene: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Scene { scene: scene.into(), msg: msg.into() }
    }
}
