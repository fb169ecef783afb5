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
    /// The detected feature points are not to be trusted (low face-likeness, a profile, guessed
    /// points): a batch step lists the scan as suspect instead of using them.
    #[error(
        "landmarks: suspect feature points: {}; correct them in the editor and give them as a \
         landmarks file",
        reasons.join("; ")
    )]
    SuspectLandmarks { reasons: Vec<String> },
    /// The finite-element face model is ill-posed or its inputs are invalid.
    #[error("fem: {0}")]
    Fem(FemError),
    /// A pipeline step failed on a given scan (the batch failure list shows these).
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<Error>,
    },
}

impl Error {
    /// Names the file a step failed on, unless the error names one already.
    pub fn in_file(self, path: &std::path::Path) -> Error {
        match self {
            e @ (Error::Io { .. }
            | Error::Syntax { .. }
            | Error::InvalidData { .. }
            | Error::UnknownFormat { .. }
            | Error::InFile { .. }) => e,
            e => Error::InFile {
                path: path.to_path_buf(),
                source: Box::new(e),
            },
        }
    }
}

/// The step of the pipeline an error comes from: what the batch failure lists (augment's
/// `failures.json`) and the editor show beside the message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// The file could not be opened, read or written.
    Io,
    /// The file is not a usable mesh (syntax, counts, indices, limits).
    Input,
    Denoise,
    Curvature,
    /// Feature points (e.g. no nose tip found).
    Landmarks,
    /// Registration of the generic face (e.g. degenerate or diverged fit).
    Registration,
    /// The finite-element model (e.g. singular system, inverted elements).
    Fem,
    /// Range images and Fisherfaces.
    Recognition,
}

impl Error {
    /// Whether the innermost error is [`Error::SuspectLandmarks`].
    pub fn is_suspect(&self) -> bool {
        match self {
            Error::SuspectLandmarks { .. } => true,
            Error::InFile { source, .. } => source.is_suspect(),
            _ => false,
        }
    }

    /// Which step failed (the innermost error decides).
    pub fn stage(&self) -> Stage {
        match self {
            Error::Io { .. } => Stage::Io,
            Error::Syntax { .. } | Error::InvalidData { .. } | Error::UnknownFormat { .. } => {
                Stage::Input
            }
            Error::InvalidMesh(_) => Stage::Input,
            Error::SuspectLandmarks { .. } => Stage::Landmarks,
            Error::Fem(_) => Stage::Fem,
            Error::InFile { source, .. } => source.stage(),
            Error::Algorithm { step, .. } => {
                let first = step.split(':').next().unwrap_or(step);
                match first {
                    "denoise" => Stage::Denoise,
                    "curvature" => Stage::Curvature,
                    "landmarks" => Stage::Landmarks,
                    "registration" | "horn" | "warp" => Stage::Registration,
                    _ => Stage::Recognition, // "range image", "pose", "fisherfaces"
                }
            }
        }
    }
}

impl From<FemError> for Error {
    fn from(e: FemError) -> Self {
        Error::Fem(e)
    }
}

/// Why the finite-element model (src/fem) cannot be built or solved. Each variant says what to
/// change; none of them lets NaN displacements out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FemError {
    /// Without fixed nodes the stiffness matrix is singular (rigid-body motion).
    #[error("no fixed nodes: fix at least the cranium layer, or the system is singular")]
    NoFixedNodes,
    /// Some parts of the mesh are held by fewer than three non-collinear fixed nodes, so they
    /// can move rigidly.
    #[error(
        "{free_nodes} free nodes belong to parts of the mesh held by fewer than three non-collinear fixed nodes (singular system); fix more nodes in every connected part"
    )]
    FloatingPart { free_nodes: usize },
    /// A layer's Young's modulus is not finite and > 0, or its Poisson ratio not in (−1, 0.5).
    #[error(
        "layer `{layer}`: invalid material (young_modulus_pa = {young_modulus_pa}, poisson_ratio = {poisson_ratio}); need E > 0 and -1 < nu < 0.5"
    )]
    InvalidMaterial {
        layer: String,
        young_modulus_pa: f64,
        poisson_ratio: f64,
    },
    /// An element's Jacobian determinant is ≤ 0 at a Gauss point (inverted or flat element);
    /// thinner layers or smoother normals usually fix it.
    #[error(
        "element {element} is inverted or flat (min Jacobian determinant {min_jacobian_det:.3e} mm^3); reduce the layer thickness"
    )]
    InvertedElement {
        element: usize,
        min_jacobian_det: f64,
    },
    /// An element too distorted to trust (scaled Jacobian at or below `limit`, the FEM's
    /// `layers::MIN_SCALED_JACOBIAN`) that local thinning could not mend.
    #[error(
        "element {element} is too distorted (scaled Jacobian {scaled_jacobian:.3}, at most {limit}); the surface there is creased or its quads skewed"
    )]
    PoorElement {
        element: usize,
        scaled_jacobian: f64,
        limit: f64,
    },
    /// The sparse Cholesky factorization failed (matrix not positive definite).
    #[error("stiffness matrix is not positive definite: {0}")]
    NotPositiveDefinite(String),
    /// The surface has a face the layer builder cannot extrude.
    #[error("face {face} has {corners} corners; only triangles and quads can be extruded")]
    UnsupportedPolygon { face: usize, corners: usize },
    /// A muscle, expression or parameter is malformed or names something unknown.
    #[error("{0}")]
    Definition(String),
    /// A computed result was not finite (reported instead of writing NaNs).
    #[error("{0} is not finite")]
    NonFinite(&'static str),
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
            message: one_line(message.into()),
        }
    }

    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        Error::InvalidData {
            path: path.to_path_buf(),
            message: one_line(message.into()),
        }
    }

    pub fn algorithm(step: &'static str, message: impl Into<String>) -> Self {
        Error::Algorithm {
            step,
            message: message.into(),
        }
    }
}

/// Messages quote the file's own text (a name, a token), which may hold line breaks: they are
/// shown escaped so every error stays one line (found by fuzzing the preset parser).
fn one_line(message: String) -> String {
    if message.contains(['\n', '\r']) {
        message.replace('\n', "\\n").replace('\r', "\\r")
    } else {
        message
    }
}
