//! The one error type of the library. Every message a user can see names the file
//! (and line where known) and what was expected.
//!
//! Messages are always one clean line: `Display` passes every file name and message
//! through `clean`, which escapes control characters (`\n`, `\x1b`, ...), shortens any
//! run of more than [`MAX_TOKEN_CHARS`] non-blank characters (a 10 MB token from a file)
//! and caps the whole text at [`MAX_MESSAGE_CHARS`]. Loaders can therefore quote file
//! content as it is (docs/limits.md).

use std::borrow::Cow;
use std::fmt::{self, Display};
use std::path::{Path, PathBuf};

/// Everything that can go wrong in arbor, from reading a scene to running a kernel.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    /// (`cause` is deliberately not a `#[source]`: the message already carries it,
    /// and error chains would print it twice.)
    #[error("{}: {}", clean_path(path), clean(cause))]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// A file's content is malformed at a known line (1-based).
    #[error("{}:{line}: {}", clean_path(path), clean(msg))]
    Parse {
        /// The file.
        path: PathBuf,
        /// The line (1-based).
        line: usize,
        /// What is wrong and what was expected.
        msg: String,
    },
    /// A file's content is wrong, with no single line to blame.
    #[error("{}: {}", clean_path(path), clean(msg))]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        msg: String,
    },
    /// The scene as a whole is unusable (empty, bad camera, unknown material, ...).
    #[error("scene {}: {}", clean(scene), clean(msg))]
    Scene {
        /// The scene's name (its source).
        scene: String,
        /// What is wrong.
        msg: String,
    },
    /// A command-line value (or its library twin, a setting) is out of range, malformed
    /// or contradicts another: the `arbor` binary exits with status 2.
    #[error("{}", clean(.0))]
    Usage(String),
    /// What was asked could not be done: a limit of the device or host, inputs that do
    /// not fit together, drawing or encoding an output (exit status 1).
    #[error("{}", clean(.0))]
    Failed(String),
    /// No usable Vulkan device, or the requested one does not exist.
    #[error("no Vulkan device: {0}")]
    NoDevice(String),
    /// A Vulkan call failed. `result` is the driver's VkResult name.
    #[error("Vulkan: {what} failed: {result}")]
    Vulkan {
        /// The call and its object.
        what: String,
        /// The driver's answer.
        result: String,
    },
    /// A buffer exceeds what the device allows for the way it is bound.
    #[error(
        "buffer '{name}' needs {size} bytes but the device allows at most {limit} bytes {per}; the scene is too large for this device"
    )]
    BufferTooLarge {
        /// The buffer's label.
        name: String,
        /// Bytes it needs.
        size: u64,
        /// Bytes the device allows.
        limit: u64,
        /// Which limit: "per storage buffer (maxStorageBufferRange)" and the like.
        per: &'static str,
    },
    /// A pipeline would bind more storage buffers per stage than the project allows.
    #[error("pipeline '{name}' binds {count} storage buffers; at most {limit} per stage are allowed")]
    TooManyStorageBuffers {
        /// The pipeline's label.
        name: String,
        /// Storage buffers it binds.
        count: usize,
        /// The most allowed.
        limit: usize,
    },
    /// A ray of a batch cannot be traced: its index in the batch, and why.
    #[error("ray {index}: {reason}")]
    BadRay {
        /// The ray's index in the batch.
        index: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The request is valid but arbor does not do it (for example a ray batch over an
    /// instanced scene); the message says what to do instead.
    #[error("{}", clean(.0))]
    Unsupported(String),
    /// The Khronos validation layer reported errors.
    #[error("Vulkan validation reported {count} error(s); first: {first}")]
    Validation {
        /// Error messages reported.
        count: usize,
        /// The first of them.
        first: String,
    },
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

/// Longest run of non-blank characters a message shows whole; longer runs keep their
/// start and end around `...`.
pub const MAX_TOKEN_CHARS: usize = 80;
/// Longest message (after escaping) `clean` returns; longer ones end in `...`.
pub const MAX_MESSAGE_CHARS: usize = 400;

/// `path` as [`clean`] text.
fn clean_path(path: &Path) -> Clean<String> {
    Clean(path.display().to_string())
}

/// `value` as one printable line: see [`clean_text`].
fn clean<T: Display>(value: T) -> Clean<T> {
    Clean(value)
}

/// Displays its content through [`clean_text`].
struct Clean<T>(T);

impl<T: Display> Display for Clean<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&clean_text(&self.0.to_string()))
    }
}

/// One printable line: control characters escaped (`\n`, `\r`, `\t`, `\x1b`, `\u{85}`),
/// runs of more than [`MAX_TOKEN_CHARS`] non-blank characters (counted after escaping)
/// shortened to their start and end around `...`, and at most [`MAX_MESSAGE_CHARS`]
/// characters in all (ending in `...` when cut). Linear in the length of `text`.
pub fn clean_text(text: &str) -> String {
    let mut out = String::new();
    let mut shown = 0usize;
    for (i, word) in text.split(' ').enumerate() {
        if shown > MAX_MESSAGE_CHARS {
            break;
        }
        if i > 0 {
            out.push(' ');
            shown += 1;
        }
        shown += push_word(&mut out, word);
    }
    if shown > MAX_MESSAGE_CHARS {
        out = out.chars().take(MAX_MESSAGE_CHARS - 3).collect();
        out.push_str("...");
    }
    out
}

/// The printable form of one character.
fn escape(c: char) -> Cow<'static, str> {
    match c {
        '\n' => Cow::Borrowed("\\n"),
        '\r' => Cow::Borrowed("\\r"),
        '\t' => Cow::Borrowed("\\t"),
        c if c.is_control() || matches!(c, '\u{2028}' | '\u{2029}') => {
            let code = u32::from(c);
            Cow::Owned(if code < 0x80 { format!("\\x{code:02x}") } else { format!("\\u{{{code:x}}}") })
        }
        c => Cow::Owned(c.to_string()),
    }
}

/// Appends `word` escaped, shortened when longer than [`MAX_TOKEN_CHARS`]; returns the
/// number of characters appended.
fn push_word(out: &mut String, word: &str) -> usize {
    let width = |c: char| escape(c).chars().count();
    let total: usize = word.chars().map(width).sum();
    if total <= MAX_TOKEN_CHARS {
        word.chars().for_each(|c| out.push_str(&escape(c)));
        return total;
    }
    let keep = (MAX_TOKEN_CHARS - 3) / 2;
    let mut head = 0;
    for c in word.chars() {
        let e = escape(c);
        head += e.chars().count();
        if head > keep {
            break;
        }
        out.push_str(&e);
    }
    out.push_str("...");
    let mut tail: Vec<Cow<'static, str>> = Vec::new();
    let mut tail_len = 0;
    for c in word.chars().rev() {
        let e = escape(c);
        tail_len += e.chars().count();
        if tail_len > keep {
            break;
        }
        tail.push(e);
    }
    tail.iter().rev().for_each(|e| out.push_str(e));
    MAX_TOKEN_CHARS
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clean_text_is_one_short_printable_line() {
        assert_eq!(clean_text("unknown material 'x\ny'"), "unknown material 'x\\ny'");
        assert_eq!(clean_text("found '\x1b[2J\x1b]0;pwned\x07OFF'"), "found '\\x1b[2J\\x1b]0;pwned\\x07OFF'");
        assert_eq!(clean_text("a\u{85}b\tc\r"), "a\\u{85}b\\tc\\r");
        let long = format!("token '{}' is bad", "a".repeat(10_000_000));
        let c = clean_text(&long);
        assert!(c.len() < 120 && c.starts_with("token 'aaa") && c.ends_with("aaa' is bad"), "{c}");
        let spaced = "word ".repeat(1000);
        let c = clean_text(&spaced);
        assert_eq!(c.chars().count(), MAX_MESSAGE_CHARS);
        assert!(c.ends_with("..."));
        let e = Error::parse("dir/a\nb.toml", 3, "unknown material 'x\ny'");
        assert_eq!(e.to_string(), "dir/a\\nb.toml:3: unknown material 'x\\ny'");
    }
}
