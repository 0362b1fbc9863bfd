//! Error types, one `#[non_exhaustive]` enum per library area. Every variant carries what a
//! user needs to find the problem: file, line, column, material, expected vs found.

use std::path::PathBuf;

/// Errors while reading or validating a collection of materials.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CollectionError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// File that failed.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The CSV file holds no header or no material row.
    #[error("{path}: empty collection (no material rows)")]
    Empty {
        /// File that is empty.
        path: PathBuf,
    },
    /// A required column is absent from the header.
    #[error("{path}: line 1: missing required column `{column}` (required: material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n)")]
    MissingColumn {
        /// File.
        path: PathBuf,
        /// Name of the missing column.
        column: String,
    },
    /// A row is malformed (wrong number of fields, bad quoting).
    #[error("{path}: line {line}: malformed row: {message}")]
    Malformed {
        /// File.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// A value is not a finite number or violates the model's constraints.
    #[error(
        "{path}: line {line}, column `{column}` (material `{material}`): {message}: `{value}`"
    )]
    BadValue {
        /// File.
        path: PathBuf,
        /// 1-based line number.
        line: u64,
        /// Column name.
        column: String,
        /// Material name on that row.
        material: String,
        /// The text found.
        value: String,
        /// What is wrong with it.
        message: String,
    },
    /// Two materials share one name.
    #[error("{path}: line {line}: duplicate material name `{material}` (first seen in {first})")]
    Duplicate {
        /// File where the duplicate was found.
        path: PathBuf,
        /// 1-based line of the second occurrence (0 when not from a CSV).
        line: u64,
        /// The name.
        material: String,
        /// Where the first one came from.
        first: String,
    },
    /// A material name was asked for that the collection does not hold.
    #[error("no material named `{name}` in the collection{}", suggest(.suggestions))]
    UnknownMaterial {
        /// The name asked for.
        name: String,
        /// Close names in the collection.
        suggestions: Vec<String>,
    },
    /// A measured file could not be read.
    #[error(transparent)]
    Merl(#[from] MerlError),
    /// A directory given as a collection holds no `.binary` file.
    #[error("{path}: a directory with no MERL .binary file in it (a collection is an analytic .csv file, a .binary file or a directory of .binary files)")]
    EmptyDir {
        /// The directory.
        path: PathBuf,
    },
    /// The path is a FIFO, a device or another non-regular file.
    #[error("{path}: is {kind}, not a regular file; a collection is read from a regular .csv or .binary file or a directory of .binary files")]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// The file is larger than any collection file of its kind.
    #[error("{path}: {bytes} bytes, larger than the {max} bytes accepted for this kind of file")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        max: u64,
    },
    /// A material name that cannot be used.
    #[error("{path}: material name `{}`: {message}", .name.escape_debug())]
    BadName {
        /// The measured file whose stem is the name.
        path: PathBuf,
        /// The name.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// The same collection file or directory is given twice.
    #[error("{path}: this collection is given twice")]
    GivenTwice {
        /// The path given the second time.
        path: PathBuf,
    },
    /// An empty material name was asked for (e.g. `--basis ""` or `--basis a,,b`).
    #[error("empty material name (a name list such as --basis takes names separated by single commas, e.g. `--basis a,b`)")]
    EmptyName,
    /// The path is neither a CSV, a `.binary` file nor a directory.
    #[error("{path}: not a collection (expected an analytic .csv, a MERL .binary file or a directory of .binary files)")]
    UnknownKind {
        /// The path.
        path: PathBuf,
    },
}

fn suggest(s: &[String]) -> String {
    if s.is_empty() {
        String::new()
    } else {
        format!(
            "; did you mean {}?",
            s.iter()
                .map(|x| format!("`{x}`"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// Errors reading or writing MERL `.binary` files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MerlError {
    /// I/O failure.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The file does not have the size of a 90 x 90 x 180 MERL table.
    #[error("{path}: wrong size: {found} bytes, a MERL .binary file has {expected}")]
    Size {
        /// File.
        path: PathBuf,
        /// Bytes expected.
        expected: u64,
        /// Bytes found.
        found: u64,
    },
    /// The header dimensions are not (90, 90, 180).
    #[error("{path}: header dimensions ({0}, {1}, {2}) are not (90, 90, 180)", .dims[0], .dims[1], .dims[2])]
    Dims {
        /// File.
        path: PathBuf,
        /// Dimensions read.
        dims: [i32; 3],
    },
    /// A value is NaN or infinite.
    #[error("{path}: non-finite value {value} in channel {channel} at cell {cell}")]
    NonFinite {
        /// File.
        path: PathBuf,
        /// Channel (0 = R, 1 = G, 2 = B).
        channel: usize,
        /// Flat cell index.
        cell: usize,
        /// The value.
        value: f64,
    },
    /// The path is a FIFO, a device, a directory or another non-regular file.
    #[error("{path}: is {kind}, not a regular MERL .binary file")]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// No cell of the file holds a valid (non-negative, above-horizon) value.
    #[error("{path}: no valid cell (every cell is negative or below the horizon)")]
    NoValidCell {
        /// File.
        path: PathBuf,
    },
}

/// Errors of the GPU back-end.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GpuError {
    /// No adapter could be found.
    #[error("no GPU adapter found (install a Vulkan driver, e.g. Debian/Ubuntu: apt-get install mesa-vulkan-drivers libvulkan1): {0}")]
    NoAdapter(String),
    /// The device could not be opened.
    #[error("cannot open the GPU device: {0}")]
    Device(String),
    /// A wgpu validation or out-of-memory error.
    #[error("GPU error in {context}: {message}")]
    Wgpu {
        /// What was being done.
        context: String,
        /// wgpu's message.
        message: String,
    },
    /// Mapping a buffer for readback failed.
    #[error("GPU readback failed: {0}")]
    Map(String),
    /// The problem does not fit in the device's limits.
    #[error("{0}")]
    Limits(String),
}

/// Errors building or using distance matrices.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DistanceError {
    /// Data of the wrong length.
    #[error("distance data has {found} entries, expected {expected}")]
    Shape {
        /// Expected length.
        expected: usize,
        /// Found length.
        found: usize,
    },
    /// A negative, non-finite or non-zero-diagonal entry.
    #[error("invalid distance {value} between `{row}` and `{col}`")]
    BadEntry {
        /// Row material.
        row: String,
        /// Column material.
        col: String,
        /// The value.
        value: f64,
    },
    /// `D[i][j] != D[j][i]`.
    #[error("distance matrix is not symmetric at (`{row}`, `{col}`)")]
    Asymmetric {
        /// Row material.
        row: String,
        /// Column material.
        col: String,
    },
    /// Fewer than two materials.
    #[error("a distance matrix needs at least 2 materials, the collection has {0}")]
    TooFew(usize),
    /// Euclidean (F0, n) distance asked for a material without parameters.
    #[error("the euclidean metric needs (F0, n) parameters, but `{0}` is a measured material; use --metric brdf-it")]
    NoParameters(String),
    /// The specular lobe asked for a measured material.
    #[error("the specular lobe is defined for analytic materials only, but `{0}` is measured; use --lobe full")]
    SpecularOfMeasured(String),
    /// An unknown metric, weighting, mask or lobe name.
    #[error("unknown {what} `{found}` (expected one of: {expected})")]
    UnknownOption {
        /// Which option.
        what: &'static str,
        /// Value given.
        found: String,
        /// Accepted values.
        expected: &'static str,
    },
    /// Back-end failure.
    #[error(transparent)]
    Backend(#[from] BackendError),
}

/// Errors from a compute back-end.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BackendError {
    /// GPU failure.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// Invalid input to a back-end call.
    #[error("{0}")]
    Invalid(String),
}

/// Errors writing output files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// I/O failure on the named file.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Encoding failure (EXR, PNG, JSON).
    #[error("{path}: {message}")]
    Encode {
        /// File.
        path: PathBuf,
        /// Message.
        message: String,
    },
}
