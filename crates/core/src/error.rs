//! Error types, one `#[non_exhaustive]` enum per library area. Every variant carries what a
//! user needs to find the problem: file, line, column, material, expected vs found.

use std::path::PathBuf;

/// Characters of a material name shown in messages; longer names are cut.
pub const NAME_CHARS: usize = 60;

/// A field name of a binary header (RGL `tensor_file`) as messages show it: every
/// character outside printable ASCII escaped, cut to [`NAME_CHARS`] characters followed
/// by `... (N characters)`, so that a corrupt header (a name of 60,000 random bytes) is
/// not echoed as raw bytes.
pub(crate) fn field_name(name: &str) -> String {
    let esc: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_graphic() || c == ' ' {
                c.to_string()
            } else {
                c.escape_default().to_string()
            }
        })
        .collect();
    match esc.char_indices().nth(NAME_CHARS) {
        None => esc,
        Some((cut, _)) => format!("{}... ({} characters)", &esc[..cut], esc.len()),
    }
}

/// A material name as messages show it: control characters escaped, and a name longer
/// than [`NAME_CHARS`] characters cut to its first [`NAME_CHARS`] followed by
/// `... (N bytes)`, so that a 10 MB name is not echoed by every message. Use it
/// wherever a message formats a name: `format!("material `{}`", short_name(name))`.
pub fn short_name(name: &str) -> ShortName<'_> {
    ShortName(name)
}

/// `"1 sample"`, `"3 samples"`: `n` and the noun `one` or `many` as `n` is 1 or not.
pub fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// `": line N"`, or nothing for line 0 (an error about a whole file, not one of its lines).
pub(crate) fn at_line(line: u64) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(": line {line}")
    }
}

/// See [`short_name`].
#[derive(Clone, Copy, Debug)]
pub struct ShortName<'a>(pub &'a str);

impl std::fmt::Display for ShortName<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = self.0;
        match name.char_indices().nth(NAME_CHARS) {
            None => write!(f, "{}", name.escape_debug()),
            Some((cut, _)) => write!(
                f,
                "{}... ({} bytes)",
                name[..cut].escape_debug(),
                name.len()
            ),
        }
    }
}

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
    /// A column name appears twice in the header (which one holds the value?).
    #[error("{path}: line 1: column `{column}` appears twice (columns {first} and {second}); each column may appear once")]
    DuplicateColumn {
        /// File.
        path: PathBuf,
        /// The column name.
        column: String,
        /// 1-based position of its first occurrence.
        first: usize,
        /// 1-based position of the second.
        second: usize,
    },
    /// A row is malformed (wrong number of fields, bad quoting).
    #[error("{path}{}: malformed row: {message}", at_line(*.line))]
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
        "{path}: line {line}, column `{column}` (material `{}`): {message}: `{}`", short_name(.material), short_name(.value)
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
    #[error("{path}{}: duplicate material name `{}` (first seen in {first})", at_line(*.line), short_name(.material))]
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
    #[error("no material named `{}` in the collection{}", short_name(.name), suggest(.suggestions))]
    UnknownMaterial {
        /// The name asked for.
        name: String,
        /// Close names in the collection.
        suggestions: Vec<String>,
    },
    /// A measured file could not be read.
    #[error(transparent)]
    Merl(#[from] MerlError),
    /// An RGL-EPFL `.bsdf` file could not be read.
    #[error(transparent)]
    Rgl(#[from] RglError),
    /// A directory given as a collection holds no material file.
    #[error("{path}: a directory with no MERL .binary file, RGL-EPFL .bsdf file or neural BRDF set in it (a collection is an analytic .csv file, a MERL .binary file, an RGL-EPFL .bsdf file, or a directory of .binary and .bsdf files and neural BRDF sets NAME_fc1.npy ... NAME_b3.npy)")]
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
    #[error("{path}: material name `{}`: {message}", short_name(.name))]
    BadName {
        /// The measured file whose stem is the name.
        path: PathBuf,
        /// The name.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// A file of a neural BRDF set is missing, unreadable, misshapen or holds a
    /// non-finite value, or a `.npy` file belongs to no set.
    #[error("{path}: {message}")]
    Neural {
        /// The file.
        path: PathBuf,
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
    #[error("{path}: not a collection (expected an analytic .csv, a MERL .binary file, an RGL-EPFL .bsdf file or a directory of .binary and .bsdf files)")]
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
                .map(|x| format!("`{}`", short_name(x)))
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// Errors reading RGL-EPFL `.bsdf` files (the `tensor_file` container and its fields).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RglError {
    /// I/O failure.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The path is a FIFO, a device, a directory or another non-regular file.
    #[error("{path}: is {kind}, not a regular RGL-EPFL .bsdf file")]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// The file is larger than any `.bsdf` file read.
    #[error("{path}: {bytes} bytes, larger than the {max} bytes accepted for a .bsdf file")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        max: u64,
    },
    /// The file does not start with `tensor_file\0`.
    #[error("{path}: not an RGL-EPFL .bsdf file (it does not start with the magic bytes `tensor_file\\0` of Mitsuba's tensor_file container)")]
    Magic {
        /// File.
        path: PathBuf,
    },
    /// The container's major version is not 1.
    #[error("{path}: tensor_file version {major}.{minor}; only version 1.x is read")]
    Version {
        /// File.
        path: PathBuf,
        /// Major version found.
        major: u8,
        /// Minor version found.
        minor: u8,
    },
    /// The header ends before a value it must hold.
    #[error("{path}: truncated: the header ends before {what} (it needs {needed} bytes, the file has {len})")]
    Truncated {
        /// File.
        path: PathBuf,
        /// What is missing, in words.
        what: String,
        /// Bytes the header needs up to the end of the missing value.
        needed: u64,
        /// Bytes in the file.
        len: u64,
    },
    /// A field's dtype code is not one of the container's types.
    #[error("{path}: field `{}`: unknown dtype code {code} (float32 is 10, uint8 is 1)", field_name(.field))]
    UnknownDtype {
        /// File.
        path: PathBuf,
        /// Field name.
        field: String,
        /// The code found.
        code: u8,
    },
    /// A field's element count or byte size does not fit in 64 bits.
    #[error("{path}: field `{}`: shape {shape:?} overflows (its size in bytes does not fit in 64 bits)", field_name(.field))]
    Overflow {
        /// File.
        path: PathBuf,
        /// Field name.
        field: String,
        /// The shape.
        shape: Vec<u64>,
    },
    /// A field's data runs past the end of the file.
    #[error("{path}: field `{}`: its data ({size} bytes at offset {offset}) runs past the end of the file ({len} bytes): truncated file or wrong shape", field_name(.field))]
    PastEnd {
        /// File.
        path: PathBuf,
        /// Field name.
        field: String,
        /// Offset of the data.
        offset: u64,
        /// Size of the data in bytes.
        size: u64,
        /// Bytes in the file.
        len: u64,
    },
    /// Two fields share a name.
    #[error("{path}: field `{}` appears twice", field_name(.field))]
    DuplicateField {
        /// File.
        path: PathBuf,
        /// Field name.
        field: String,
    },
    /// A field the evaluation needs is absent.
    #[error("{path}: missing field `{field}` (an RGL-EPFL measured BSDF has description, phi_i, theta_i, sigma, ndf, vndf, luminance, rgb and jacobian)")]
    MissingField {
        /// File.
        path: PathBuf,
        /// Field name.
        field: &'static str,
    },
    /// A field has the wrong element type.
    #[error("{path}: field `{field}` is {found}, expected {expected}")]
    WrongDtype {
        /// File.
        path: PathBuf,
        /// Field name.
        field: &'static str,
        /// Type expected.
        expected: &'static str,
        /// Type found.
        found: &'static str,
    },
    /// A field's shape disagrees with the format or with the other fields.
    #[error("{path}: field `{field}` has shape {found:?}, expected {expected}")]
    Shape {
        /// File.
        path: PathBuf,
        /// Field name.
        field: &'static str,
        /// The shape expected, in words.
        expected: String,
        /// The shape found.
        found: Vec<u64>,
    },
    /// A value is not finite or out of its range.
    #[error("{path}: field `{field}`, value {index}: {value:e}: {message}")]
    BadValue {
        /// File.
        path: PathBuf,
        /// Field name.
        field: &'static str,
        /// 0-based index of the value in the field (last dimension fastest).
        index: u64,
        /// The value.
        value: f64,
        /// What is wrong.
        message: String,
    },
    /// The reflectance the file gives, tabulated on the MERL grid, is beyond the f32
    /// range of the table.
    #[error("{path}: field `rgb`: the reflectance it gives reaches {value:.3e} at {at} (a cell of the MERL grid): a value beyond the f32 range (largest 3.40e38) that the table holds")]
    OutOfRange {
        /// File.
        path: PathBuf,
        /// The value (f64).
        value: f64,
        /// The cell's directions, in words.
        at: String,
    },
    /// An anisotropic file (more than one `phi_i` slice).
    #[error("{path}: anisotropic material ({count} phi_i slices): only isotropic RGL-EPFL files (one phi_i slice) are supported for now")]
    Anisotropic {
        /// File.
        path: PathBuf,
        /// Number of `phi_i` entries.
        count: u64,
    },
    /// A spectral file without an `rgb` table.
    #[error("{path}: spectral-only file (a `spectra` field and no `rgb` field): only the RGB files of the RGL-EPFL database (`*_rgb.bsdf`) are supported for now")]
    SpectralOnly {
        /// File.
        path: PathBuf,
    },
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
    /// A value is NaN, infinite, or a reflectance beyond the f32 range the grid
    /// computations use.
    #[error(
        "{path}: value {index} (channel {}, theta_h row {}, theta_d row {}, phi_d column {}) is {value:e}: {}",
        ["R", "G", "B"][*.channel % 3], .cell[0], .cell[1], .cell[2],
        if .value.is_finite() {
            "too large (times the channel scale it exceeds the f32 range, 3.4e38, that the grid computations use)"
        } else {
            "not a finite number"
        }
    )]
    BadValue {
        /// File.
        path: PathBuf,
        /// 0-based index of the value among the file's 3 x 1,458,000 float64 (after the
        /// 12-byte header).
        index: usize,
        /// Channel (0 = R, 1 = G, 2 = B).
        channel: usize,
        /// Grid cell `(theta_h, theta_d, phi_d)` row indices.
        cell: [usize; 3],
        /// The value.
        value: f64,
    },
    /// The file changed (size or modification time) while it was read.
    #[error("{path}: changed while it was read (its size or modification time differs after reading); what was read may mix two versions, so it is refused: read it again once nothing writes to it")]
    Changed {
        /// File.
        path: PathBuf,
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
    #[error("invalid distance {value} between `{}` and `{}`", short_name(.row), short_name(.col))]
    BadEntry {
        /// Row material.
        row: String,
        /// Column material.
        col: String,
        /// The value.
        value: f64,
    },
    /// `D[i][j] != D[j][i]`.
    #[error("distance matrix is not symmetric at (`{}`, `{}`)", short_name(.row), short_name(.col))]
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
    #[error("the euclidean metric needs (F0, n) parameters, but `{}` is a measured material; use --metric brdf-it", short_name(.0))]
    NoParameters(String),
    /// The specular lobe asked for a measured material.
    #[error("the specular lobe is defined for analytic materials only, but `{}` is measured; use --lobe full", short_name(.0))]
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
    /// More tiles asked for than the matrix has rows.
    #[error("{count} tiles asked for, but the collection has {materials} material{}: use at most {materials} tile{}", if *.materials == 1 { "" } else { "s" }, if *.materials == 1 { "" } else { "s" })]
    TooManyTiles {
        /// Tiles asked for.
        count: usize,
        /// Materials (rows of the matrix).
        materials: usize,
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

/// A command's request (`brdf_basis::run`) refused before any work: a setting out of its
/// range, settings that do not go together, a setting the method does not use, or
/// settings that do not fit the collection. One variant per kind of rule, each naming the
/// setting by its command-line flag (Python's keyword arguments are the same names with
/// underscores), so that a caller can match on which rule failed; every front door
/// reports it with the same wording (its `Display`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Refusal {
    /// A setting given that the chosen method, criterion or objective does not use:
    /// `{setting}[ {value}] applies to {applies_to}, not to {not_to}[: {why}]`.
    #[error(
        "{setting}{} applies to {applies_to}, not to {not_to}{}",
        .value.as_ref().map(|v| format!(" {v}")).unwrap_or_default(),
        .why.as_ref().map(|w| format!(": {w}")).unwrap_or_default()
    )]
    NotApplicable {
        /// The flag given (`--objective`, `--runs`, ...).
        setting: &'static str,
        /// Its value, where the message shows it.
        value: Option<String>,
        /// What uses it (`kmedoids and gcuk`, `--objective relative`, ...).
        applies_to: String,
        /// What was chosen (`--method greedy`, `--criterion random`, ...).
        not_to: String,
        /// Why, and what to give instead.
        why: Option<String>,
    },
    /// Settings given that a mode of the command would ignore:
    /// `{shown} does (do) not apply {context}{why}`.
    #[error(
        "{shown} {} not apply {context}{why}",
        if .settings.len() == 1 { "does" } else { "do" }
    )]
    DoesNotApply {
        /// The flags given, in the order the message lists them.
        settings: Vec<&'static str>,
        /// The flags as the message shows them (with a value where it matters).
        shown: String,
        /// The mode that ignores them (`with --samples`, `to --method gcuk`, ...).
        context: String,
        /// Why, and what to give instead, with its leading punctuation.
        why: String,
    },
    /// A setting given for a part of the command that another setting leaves out:
    /// `{setting} {value} applies to {part}, which {left_out_by} leaves out: {hint}`.
    #[error("{setting} {value} applies to {part}, which {left_out_by} leaves out: {hint}")]
    LeftOut {
        /// The flag given.
        setting: &'static str,
        /// Its value.
        value: String,
        /// The part of the work that uses it.
        part: String,
        /// The settings that leave that part out.
        left_out_by: String,
        /// What to give instead.
        hint: String,
    },
    /// A value outside the setting's range: `{setting}[ {value}]: {rule}`.
    #[error(
        "{setting}{}: {rule}",
        .value.as_ref().map(|v| format!(" {v}")).unwrap_or_default()
    )]
    OutOfRange {
        /// The flag.
        setting: &'static str,
        /// The value given, where the message shows it beside the flag.
        value: Option<String>,
        /// The rule, in words (with the value when `value` is `None`).
        rule: String,
    },
    /// A value the command does not offer: `{setting} {value}: {why}`.
    #[error("{setting} {value}: {why}")]
    NotOffered {
        /// The flag.
        setting: &'static str,
        /// The value given.
        value: String,
        /// Why, and what the command offers instead.
        why: String,
    },
    /// Two settings of which one may be given: `give either {a} or {b}, not both`.
    #[error("give either {a} or {b}, not both")]
    Conflict {
        /// The first.
        a: &'static str,
        /// The second.
        b: &'static str,
    },
    /// A setting needed and not given (or given empty); the message names it.
    #[error("{message}")]
    Missing {
        /// The flag.
        setting: &'static str,
        /// What to give, in words.
        message: String,
    },
    /// A value listed twice: `{setting}: {what} {value} is listed twice; give each once`.
    #[error("{setting}: {what} {value} is listed twice; give each once")]
    Duplicate {
        /// The flag.
        setting: &'static str,
        /// What the values are (`plan`, `sample count`, ...).
        what: &'static str,
        /// The value, as the message shows it.
        value: String,
    },
    /// A target of a plan with a basis material's values (the basis fits it exactly from
    /// any sample).
    #[error("target `{target}` has the same values as basis material `{basis}`: the basis fits it exactly from any sample, so a plan would choose samples on a zero score; leave it out of --targets (or give another basis)")]
    SameAsBasis {
        /// The target.
        target: String,
        /// The basis material.
        basis: String,
    },
    /// A setting out of its range, as a stage's own check words it, with the settings to
    /// look at (`hint`).
    #[error("{command}: {cause} ({hint})")]
    Range {
        /// The command.
        command: &'static str,
        /// The stage's message.
        cause: String,
        /// The settings to check (and, where it matters, the collection's size).
        hint: String,
    },
    /// A name that is not a method, criterion or other choice of the command.
    #[error("invalid {what} `{value}` (expected {expected})")]
    Unknown {
        /// What was parsed.
        what: &'static str,
        /// The value given.
        value: String,
        /// The accepted spellings.
        expected: &'static str,
    },
    /// A rule of one setting that fits none of the above; the message names it.
    #[error("{message}")]
    Rule {
        /// The flag.
        setting: &'static str,
        /// The rule, in words.
        message: String,
    },
}

impl Refusal {
    /// The flag this refusal names first (`None` for [`Refusal::Range`], which names the
    /// command, and [`Refusal::Unknown`], a name of a choice).
    pub fn setting(&self) -> Option<&'static str> {
        match self {
            Refusal::NotApplicable { setting, .. }
            | Refusal::LeftOut { setting, .. }
            | Refusal::OutOfRange { setting, .. }
            | Refusal::NotOffered { setting, .. }
            | Refusal::Missing { setting, .. }
            | Refusal::Duplicate { setting, .. }
            | Refusal::Rule { setting, .. } => Some(setting),
            Refusal::DoesNotApply { settings, .. } => settings.first().copied(),
            Refusal::Conflict { a, .. } => Some(a),
            Refusal::SameAsBasis { .. } => Some("--targets"),
            Refusal::Range { .. } | Refusal::Unknown { .. } => None,
        }
    }
}

/// The former name of [`Refusal`].
pub type RequestError = Refusal;
