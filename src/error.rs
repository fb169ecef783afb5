use std::path::{Path, PathBuf};

/// Library result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in the library. Each message is one line that names the file
/// (where there is one) and the problem.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read or write a file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file's text or bytes do not follow its format.
    #[error("{}: line {line}: {message}", path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// The file parsed, but what it describes is not a usable mesh (empty, NaN, bad index …).
    #[error("{}: {message}", path.display())]
    InvalidData { path: PathBuf, message: String },
    /// The extension names no format we read or write.
    #[error(
        "{}: unknown mesh format (expected .wrl/.vrml, .obj, .ply, .xyz/.txt)",
        path.display()
    )]
    UnknownFormat { path: PathBuf },
    /// A mesh handed to an algorithm does not meet its preconditions.
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// An algorithm could not produce a result (e.g. no nose tip found, singular system).
    #[error("{step}: {message}")]
    Algorithm { step: &'static str, message: String },
}

impl Error {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub fn syntax(path: &Path, line: usize, message: impl Into<String>) -> Self {
        Error::Syntax {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }

    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        Error::InvalidData {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub fn algorithm(step: &'static str, message: impl Into<String>) -> Self {
        Error::Algorithm {
            step,
            message: message.into(),
        }
    }
}
