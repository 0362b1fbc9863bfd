//! Collections: ordered lists of uniquely named materials, analytic (Ashikhmin-Shirley
//! rows of a CSV, SPEC 1), measured (MERL `.binary` tables, SPEC 2) or neural (NBRDF
//! sets of six float32 `.npy` files, SPEC 9).

use crate::brdf::NBRDF_PARTS;
use crate::brdf::{AshikhminShirley, Nbrdf, NBRDF_WEIGHTS};
use crate::error::CollectionError;
use crate::merl::{read_binary, MerlTable};
use crate::rgl::RglMaterial;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The embedded default collection, authored by this project (see `crates/core/data/README.md`).
pub const DEFAULT_COLLECTION_CSV: &str = include_str!("../data/default_collection.csv");
/// Name under which the embedded collection reports errors and provenance.
pub const DEFAULT_COLLECTION_NAME: &str = "<embedded default collection>";

/// Required columns of an analytic CSV.
pub const REQUIRED_COLUMNS: [&str; 9] = [
    "material", "d_r", "d_g", "d_b", "s_r", "s_g", "s_b", "F0", "n",
];

/// What a material is made of.
#[derive(Clone, Debug)]
pub enum MaterialData {
    /// Ashikhmin-Shirley parameters.
    Analytic(AshikhminShirley),
    /// A measured table on the MERL grid.
    Measured(Arc<MerlTable>),
    /// An RGL-EPFL measured file: its exact evaluation and its table on the MERL grid.
    Rgl(Arc<RglMaterial>),
    /// A neural BRDF (SPEC 9).
    Neural(Arc<Nbrdf>),
}

impl MaterialData {
    /// The kind, as `info` prints it: `analytic`, `MERL table`, `neural`, `RGL-EPFL`.
    pub fn kind(&self) -> &'static str {
        match self {
            MaterialData::Analytic(_) => "analytic",
            MaterialData::Measured(_) => "MERL table",
            MaterialData::Neural(_) => "neural",
            MaterialData::Rgl(_) => "RGL-EPFL",
        }
    }

    /// RGB reflectance at a direction pair (unit vectors in the local frame, SPEC 9):
    /// analytic and neural materials exactly, RGL files by their own evaluation, MERL tables at the cell of the MERL lookup
    /// (`None` when that cell is invalid in the table). Below the horizon: 0.
    pub fn eval_dirs(&self, wi: [f64; 3], wo: [f64; 3]) -> Option<[f64; 3]> {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return Some([0.0; 3]);
        }
        match self {
            MaterialData::Analytic(a) => Some(a.eval(wi, wo)),
            MaterialData::Neural(n) => Some(n.eval_dirs(wi, wo)),
            MaterialData::Rgl(r) => Some(r.eval_dirs(wi, wo)),
            MaterialData::Measured(t) => {
                let cell = crate::merl::lookup(wi, wo);
                t.is_valid(cell)
                    .then(|| [0, 1, 2].map(|c| t.value(c, cell) as f64))
            }
        }
    }
}

/// One named material.
#[derive(Clone, Debug)]
pub struct Material {
    /// Unique name.
    pub name: String,
    /// Its data.
    pub data: MaterialData,
    /// Where it came from (file and line, for messages).
    pub origin: String,
}

impl Material {
    /// The analytic parameters, if any.
    pub fn analytic(&self) -> Option<&AshikhminShirley> {
        match &self.data {
            MaterialData::Analytic(a) => Some(a),
            MaterialData::Measured(_) | MaterialData::Rgl(_) | MaterialData::Neural(_) => None,
        }
    }
}

/// An ordered collection of uniquely named materials.
#[derive(Clone, Debug, Default)]
pub struct Collection {
    materials: Vec<Material>,
    index: HashMap<String, usize>,
}

impl Collection {
    /// An empty collection.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a material; rejects a duplicate name.
    pub fn push(&mut self, m: Material, path: &Path, line: u64) -> Result<(), CollectionError> {
        if let Some(&i) = self.index.get(&m.name) {
            return Err(CollectionError::Duplicate {
                path: path.to_path_buf(),
                line,
                material: m.name,
                first: self.materials[i].origin.clone(),
            });
        }
        self.index.insert(m.name.clone(), self.materials.len());
        self.materials.push(m);
        Ok(())
    }

    /// The embedded default collection.
    pub fn embedded_default() -> Self {
        parse_csv(
            DEFAULT_COLLECTION_CSV.as_bytes(),
            Path::new(DEFAULT_COLLECTION_NAME),
        )
        .expect("the embedded default collection is valid (checked by tests)")
    }

    /// Loads one COLLECTION argument: an analytic `.csv`, a `.binary` file, or a directory
    /// of `.binary` files (materials sorted by name).
    pub fn load(path: &Path) -> Result<Self, CollectionError> {
        let mut c = Self::new();
        c.extend_from(path)?;
        Ok(c)
    }

    /// Loads several COLLECTION arguments into one collection, in order; an empty list
    /// gives the embedded default.
    pub fn load_many(paths: &[PathBuf]) -> Result<Self, CollectionError> {
        if paths.is_empty() {
            return Ok(Self::embedded_default());
        }
        let mut c = Self::new();
        let mut seen: Vec<PathBuf> = Vec::new();
        for p in paths {
            if let Ok(canon) = p.canonicalize() {
                if seen.contains(&canon) {
                    return Err(CollectionError::GivenTwice { path: p.clone() });
                }
                seen.push(canon);
            }
            c.extend_from(p)?;
        }
        Ok(c)
    }

    /// How many materials [`Self::load_many`] would load from `paths`, without reading the
    /// material files (directories are listed, CSV tables parsed): a command checks its
    /// settings against the count before it loads, which for RGL-EPFL files and neural
    /// BRDFs means tabulating. A file `load_many` would refuse may still count; the load
    /// names it.
    ///
    /// # Errors
    /// An unreadable path, an unknown kind, an empty directory, a malformed CSV table.
    pub fn count_many(paths: &[PathBuf]) -> Result<usize, CollectionError> {
        if paths.is_empty() {
            return Ok(Self::embedded_default().len());
        }
        let mut n = 0;
        for path in paths {
            n += match source_of(path)? {
                Source::Dir => dir_entries(path)?.len(),
                Source::Binary | Source::Rgl => 1,
                Source::Csv => read_csv(path)?.materials.len(),
            };
        }
        Ok(n)
    }

    fn extend_from(&mut self, path: &Path) -> Result<(), CollectionError> {
        match source_of(path)? {
            Source::Dir => self.extend_from_dir(path),
            Source::Binary => self.push_measured(path),
            Source::Rgl => self.push_rgl(path),
            Source::Csv => {
                for (m, line) in read_csv(path)?.materials.into_iter().zip(2u64..) {
                    self.push(m, path, line)?;
                }
                Ok(())
            }
        }
    }

    /// A directory: its `.binary` and `.bsdf` files and NBRDF sets (`NAME_fc1.npy` ... `NAME_b3.npy`),
    /// all sorted by material name; other files are ignored, except a `.npy` that is not
    /// part of a set (an error naming it).
    fn extend_from_dir(&mut self, path: &Path) -> Result<(), CollectionError> {
        let entries = dir_entries(path)?;
        for (name, e) in entries {
            match e {
                Entry::Binary(f) => self.push_measured(&f)?,
                Entry::Rgl(f) => self.push_rgl(&f)?,
                Entry::Neural(f) => {
                    let dir = f.parent().unwrap_or(path);
                    let net = read_nbrdf_set(dir, &name)?;
                    let origin = dir.join(format!("{name}_*.npy"));
                    self.push_named(name, MaterialData::Neural(Arc::new(net)), &origin)?;
                }
            }
        }
        Ok(())
    }

    /// Appends a material read from `f` (a file, or a set's pattern), its name checked.
    fn push_named(
        &mut self,
        name: String,
        data: MaterialData,
        f: &Path,
    ) -> Result<(), CollectionError> {
        check_name(&name).map_err(|message| CollectionError::BadName {
            path: f.to_path_buf(),
            name: name.clone(),
            message,
        })?;
        self.push(
            Material {
                name,
                data,
                origin: f.display().to_string(),
            },
            f,
            0,
        )
    }

    fn push_measured(&mut self, f: &Path) -> Result<(), CollectionError> {
        let table = read_binary(f)?;
        self.push_file(f, MaterialData::Measured(Arc::new(table)))
    }

    /// An RGL-EPFL `.bsdf` file, named by its stem (tabulated on the grid as it loads).
    fn push_rgl(&mut self, f: &Path) -> Result<(), CollectionError> {
        // The name first: a bad name is found before the tabulation's work.
        file_name(f)?;
        let m = RglMaterial::load(f)?;
        self.push_file(f, MaterialData::Rgl(Arc::new(m)))
    }

    /// Appends the material read from the file `f`, named by its stem.
    fn push_file(&mut self, f: &Path, data: MaterialData) -> Result<(), CollectionError> {
        self.push_named(stem(f), data, f)
    }

    /// Materials in order.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.materials.len()
    }

    /// How many materials are analytic and how many are not (MERL tables, RGL-EPFL files,
    /// neural BRDFs), when the collection holds both kinds; `None` otherwise. The Ngan 2005
    /// table's albedos leave out MERL's channel scales, which the measured kinds include
    /// (`docs/selection.md`, "Mixing analytic and measured materials").
    pub fn mixed_scales(&self) -> Option<(usize, usize)> {
        let analytic = self
            .materials
            .iter()
            .filter(|m| matches!(m.data, MaterialData::Analytic(_)))
            .count();
        let other = self.materials.len() - analytic;
        (analytic > 0 && other > 0).then_some((analytic, other))
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.materials.is_empty()
    }

    /// Names in order.
    pub fn names(&self) -> Vec<String> {
        self.materials.iter().map(|m| m.name.clone()).collect()
    }

    /// Index of a material by name, with close-name suggestions on failure.
    pub fn index_of(&self, name: &str) -> Result<usize, CollectionError> {
        if name.trim().is_empty() {
            return Err(CollectionError::EmptyName);
        }
        self.index
            .get(name)
            .copied()
            .ok_or_else(|| CollectionError::UnknownMaterial {
                name: name.to_string(),
                suggestions: self.suggest(name),
            })
    }

    /// Material by name.
    pub fn get(&self, name: &str) -> Result<&Material, CollectionError> {
        Ok(&self.materials[self.index_of(name)?])
    }

    /// Materials per kind ([`MaterialData::kind`]), in the order analytic, MERL table,
    /// neural, RGL-EPFL; kinds the collection does not hold are left out.
    pub fn kind_counts(&self) -> Vec<(&'static str, usize)> {
        let mut out: Vec<(&'static str, usize)> = Vec::new();
        for m in &self.materials {
            let k = m.data.kind();
            match out.iter_mut().find(|(x, _)| *x == k) {
                Some((_, n)) => *n += 1,
                None => out.push((k, 1)),
            }
        }
        let order = ["analytic", "MERL table", "neural", "RGL-EPFL"];
        out.sort_by_key(|(k, _)| order.iter().position(|o| o == k).unwrap_or(order.len()));
        out
    }

    /// Whether every material is analytic.
    pub fn all_analytic(&self) -> bool {
        self.materials.iter().all(|m| m.analytic().is_some())
    }

    /// The fingerprint of the collection: XXH3-64 ([`crate::hash`]) over every
    /// material's name (length-prefixed) and its parameters (analytic) or table values
    /// (measured), little-endian, as 16 hex digits. Saved matrices, tiles and fit files
    /// carry it, so that results of different collections are never mixed.
    pub fn fingerprint(&self) -> String {
        let mut h = crate::hash::Hasher::new();
        for m in &self.materials {
            h.write(&(m.name.len() as u64).to_le_bytes());
            h.write(m.name.as_bytes());
            match &m.data {
                MaterialData::Analytic(a) => {
                    h.write(b"A");
                    h.write_f64s(&[a.d[0], a.d[1], a.d[2], a.s[0], a.s[1], a.s[2], a.f0, a.n]);
                }
                MaterialData::Measured(t) => {
                    h.write(b"M");
                    h.write_f32s(&t.rgb);
                }
                MaterialData::Rgl(t) => {
                    h.write(b"R");
                    h.write_f32s(&t.table().rgb);
                }
                MaterialData::Neural(n) => {
                    h.write(b"N");
                    h.write_f32s(n.weights());
                }
            }
        }
        h.hex()
    }

    /// A new collection with the materials at `idx`, in that order.
    pub fn subset(&self, idx: &[usize]) -> Self {
        let mut c = Self::new();
        for &i in idx {
            let m = self.materials[i].clone();
            c.index.insert(m.name.clone(), c.materials.len());
            c.materials.push(m);
        }
        c
    }

    fn suggest(&self, name: &str) -> Vec<String> {
        let mut scored: Vec<(usize, &str)> = self
            .materials
            .iter()
            .map(|m| (strsim::levenshtein(name, &m.name), m.name.as_str()))
            .filter(|(d, n)| *d <= 3.max(name.len() / 3) || n.contains(name))
            .collect();
        scored.sort();
        scored
            .into_iter()
            .take(3)
            .map(|(_, n)| n.to_string())
            .collect()
    }
}

/// The material name of a measured file: its stem, checked.
fn file_name(f: &Path) -> Result<String, CollectionError> {
    let name = stem(f);
    check_name(&name).map_err(|message| CollectionError::BadName {
        path: f.to_path_buf(),
        name: name.clone(),
        message,
    })?;
    Ok(name)
}

/// What a COLLECTION argument is, from its metadata and extension.
enum Source {
    Dir,
    Binary,
    Rgl,
    Csv,
}

/// The kind of `path`: the file type first, from metadata (never opening a FIFO, which
/// would block, or a device): directories are listed, regular files read by extension,
/// anything else refused.
fn source_of(path: &Path) -> Result<Source, CollectionError> {
    let meta = std::fs::metadata(path).map_err(|source| CollectionError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if meta.is_dir() {
        return Ok(Source::Dir);
    }
    match path.extension().and_then(|e| e.to_str()) {
        Some("binary") => Ok(Source::Binary),
        Some("bsdf") => Ok(Source::Rgl),
        Some("csv") => Ok(Source::Csv),
        _ => Err(CollectionError::UnknownKind {
            path: path.to_path_buf(),
        }),
    }
}

/// The analytic table `path`, read and parsed.
fn read_csv(path: &Path) -> Result<Collection, CollectionError> {
    let bytes = read_regular(path, MAX_CSV_BYTES)?;
    parse_csv(&bytes, path)
}

/// A material of a directory ([`dir_entries`]): a `.binary` file, a `.bsdf` file or the
/// first file of an NBRDF set.
enum Entry {
    Binary(PathBuf),
    Rgl(PathBuf),
    Neural(PathBuf),
}

/// The materials of directory `path` by name, sorted, without reading them
/// ([`Collection::load`]'s listing).
fn dir_entries(path: &Path) -> Result<Vec<(String, Entry)>, CollectionError> {
    let io = |source| CollectionError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(io)?
        .map(|e| e.map(|e| e.path()).map_err(io))
        .collect::<Result<_, _>>()?;
    files.sort();
    let mut entries: Vec<(String, Entry)> = Vec::new();
    let mut sets: std::collections::BTreeMap<String, Vec<PathBuf>> = Default::default();
    for f in files {
        match f.extension().and_then(|e| e.to_str()) {
            Some("binary") => entries.push((stem(&f), Entry::Binary(f))),
            Some("bsdf") => entries.push((stem(&f), Entry::Rgl(f))),
            Some("npy") => {
                let st = stem(&f);
                let name = NBRDF_PARTS.iter().find_map(|(part, _, _)| {
                    st.strip_suffix(part)?
                        .strip_suffix('_')
                        .filter(|n| !n.is_empty())
                });
                match name {
                    Some(n) => sets.entry(n.to_string()).or_default().push(f),
                    None => {
                        return Err(CollectionError::Neural {
                            path: f,
                            message: "a .npy file that is not part of a neural BRDF set (a set is NAME_fc1.npy, NAME_b1.npy, NAME_fc2.npy, NAME_b2.npy, NAME_fc3.npy and NAME_b3.npy)".into(),
                        })
                    }
                }
            }
            _ => {}
        }
    }
    for (name, files) in sets {
        entries.push((name, Entry::Neural(files[0].clone())));
    }
    if entries.is_empty() {
        return Err(CollectionError::EmptyDir {
            path: path.to_path_buf(),
        });
    }
    entries.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(entries)
}

/// The file stem of `f` (a material name), lossily as text.
fn stem(f: &Path) -> String {
    f.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Reads the NBRDF set `NAME_fc1.npy` ... `NAME_b3.npy` of material `name` in `dir`
/// (SPEC 9): each file a float32 array of its exact shape, every value finite. Any other
/// file, shape or value is an error naming the file.
pub fn read_nbrdf_set(dir: &Path, name: &str) -> Result<Nbrdf, CollectionError> {
    let mut flat = Vec::with_capacity(NBRDF_WEIGHTS);
    for (part, shape, offset) in NBRDF_PARTS {
        let f = dir.join(format!("{name}_{part}.npy"));
        let err = |message: String| CollectionError::Neural {
            path: f.clone(),
            message,
        };
        if !f.exists() {
            return Err(err(format!(
                "missing: the neural BRDF `{}` needs all six files {name}_fc1.npy, _b1, _fc2, _b2, _fc3 and _b3.npy",
                crate::error::short_name(name)
            )));
        }
        let a = crate::npy_format::read_npy_f32(&f, 4096).map_err(err)?;
        let want = |s: &[usize]| {
            s.iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(" x ")
        };
        if a.shape != shape {
            return Err(err(format!(
                "shape {} where `{part}` of a neural BRDF is {}",
                want(&a.shape),
                want(shape)
            )));
        }
        if let Some(i) = a.data.iter().position(|v| !v.is_finite()) {
            return Err(err(format!(
                "value {i} is not a finite number ({})",
                a.data[i]
            )));
        }
        debug_assert_eq!(flat.len(), offset);
        flat.extend_from_slice(&a.data);
    }
    let at = || dir.join(format!("{name}_*.npy"));
    let net = Nbrdf::from_weights(flat).map_err(|message| CollectionError::Neural {
        path: at(),
        message,
    })?;
    // Outputs beyond what the f32 evaluations hold are refused here, once for every
    // back-end (audit 2, T13), not clamped by one and infinite in the other.
    net.check_output_range()
        .map_err(|message| CollectionError::Neural {
            path: at(),
            message: format!("material `{}`: {message}", crate::error::short_name(name)),
        })?;
    Ok(net)
}

/// Largest analytic CSV read (a table of 10,000 materials is about 1 MB).
pub const MAX_CSV_BYTES: u64 = 256 << 20;

/// Reads a regular file of at most `max` bytes. Anything else (a FIFO, a device, a
/// socket) is refused from its metadata, before it is opened, so that reading never blocks.
pub(crate) fn read_regular(path: &Path, max: u64) -> Result<Vec<u8>, CollectionError> {
    let io = |source| CollectionError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(CollectionError::NotRegular {
            path: path.to_path_buf(),
            kind: crate::merl::file_kind(&meta),
        });
    }
    if meta.len() > max {
        return Err(CollectionError::TooLarge {
            path: path.to_path_buf(),
            bytes: meta.len(),
            max,
        });
    }
    std::fs::read(path).map_err(io)
}

/// Checks a material name: not empty, no control character (names are printed in
/// messages, reports and JSON), no comma (flags take comma-separated lists of names).
/// Names never choose a path (see `cli::fit` for exported files), so `/` and `..` are
/// allowed. Returns what is wrong.
pub(crate) fn check_name(name: &str) -> Result<(), String> {
    if name.trim().is_empty() {
        return Err("empty material name".into());
    }
    if name.chars().any(char::is_control) {
        return Err("material names may not contain control characters".into());
    }
    if name.contains(',') {
        return Err(
            "material names may not contain commas (flags such as --basis take comma-separated names)"
                .into(),
        );
    }
    Ok(())
}

/// Largest magnitude accepted for a parameter: computations on the grid run in f32.
pub const MAX_PARAMETER: f64 = f32::MAX as f64;

/// `n` seeded synthetic Ashikhmin-Shirley materials (`synth-00000`, ...): diffuse albedo
/// in `[0, 0.6]^3`, specular scale in `[0, 1.2]^3`, F0 in `[0.02, 0.98]`, exponent
/// log-uniform in `[1, 80,000]`. The large-collection bench's collection (and its tests').
#[doc(hidden)]
pub fn synthetic(n: usize, seed: u64) -> Collection {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut csv = String::from("material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n");
    for i in 0..n {
        let d: Vec<f64> = (0..3).map(|_| rng.random_range(0.0..0.6)).collect();
        let s: Vec<f64> = (0..3).map(|_| rng.random_range(0.0..1.2)).collect();
        let f0: f64 = rng.random_range(0.02..0.98);
        let e: f64 = 80_000f64.powf(rng.random_range(0.0..1.0));
        csv.push_str(&format!(
            "synth-{i:05},{},{},{},{},{},{},{f0},{e}\n",
            d[0], d[1], d[2], s[0], s[1], s[2]
        ));
    }
    parse_csv(csv.as_bytes(), Path::new("<synthetic>")).expect("a valid synthetic collection")
}

/// Parses an analytic CSV (SPEC 1) from bytes; `path` names the source in errors.
///
/// Long function: one check per column and per value, each with its own error
/// naming the file, line and column, read top to bottom in SPEC 1's column order.
pub fn parse_csv(bytes: &[u8], path: &Path) -> Result<Collection, CollectionError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let malformed = |line: u64, message: String| CollectionError::Malformed {
        path: path.to_path_buf(),
        line,
        message,
    };
    let headers = rdr
        .headers()
        .map_err(|e| malformed(1, e.to_string()))?
        .clone();
    if headers.iter().all(|h| h.is_empty()) {
        return Err(CollectionError::Empty {
            path: path.to_path_buf(),
        });
    }
    for (j, name) in headers.iter().enumerate() {
        if let Some(i) = headers
            .iter()
            .take(j)
            .position(|h| !h.is_empty() && h == name)
        {
            return Err(CollectionError::DuplicateColumn {
                path: path.to_path_buf(),
                column: name.escape_debug().to_string(),
                first: i + 1,
                second: j + 1,
            });
        }
    }
    let mut col = [0usize; 9];
    for (k, name) in REQUIRED_COLUMNS.iter().enumerate() {
        col[k] = headers.iter().position(|h| h == *name).ok_or_else(|| {
            CollectionError::MissingColumn {
                path: path.to_path_buf(),
                column: name.to_string(),
            }
        })?;
    }
    let mut out = Collection::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            malformed(line, e.to_string())
        })?;
        let line = rec.position().map_or(0, |p| p.line());
        if rec.iter().all(|f| f.is_empty()) {
            continue;
        }
        let material = rec.get(col[0]).unwrap_or("").to_string();
        if let Err(message) = check_name(&material) {
            return Err(CollectionError::BadValue {
                path: path.to_path_buf(),
                line,
                column: "material".into(),
                value: material.clone(),
                material: material.clone(),
                message,
            });
        }
        let mut v = [0f64; 8];
        for k in 0..8 {
            let column = REQUIRED_COLUMNS[k + 1];
            let text = rec.get(col[k + 1]).unwrap_or("");
            let bad = |message: &str| CollectionError::BadValue {
                path: path.to_path_buf(),
                line,
                column: column.into(),
                material: material.clone(),
                value: text.into(),
                message: message.into(),
            };
            let x: f64 = text.parse().map_err(|_| bad("not a number"))?;
            if !x.is_finite() {
                return Err(bad("not a finite number"));
            }
            if x.abs() > MAX_PARAMETER {
                return Err(bad(
                    "too large: grid computations run in f32 (at most 3.4e38)",
                ));
            }
            match column {
                "F0" if !(0.0..=1.0).contains(&x) => return Err(bad("F0 must lie in [0, 1]")),
                "n" if x <= 0.0 => return Err(bad("n must be > 0")),
                c if c.starts_with("d_") && x < 0.0 => {
                    return Err(bad("diffuse albedo must be >= 0"))
                }
                c if c.starts_with("s_") && x < 0.0 => {
                    return Err(bad("specular scale must be >= 0"))
                }
                _ => {}
            }
            v[k] = x;
        }
        let m = AshikhminShirley {
            d: [v[0], v[1], v[2]],
            s: [v[3], v[4], v[5]],
            f0: v[6],
            n: v[7],
        };
        let origin = format!("{}:{}", path.display(), line);
        out.push(
            Material {
                name: material,
                data: MaterialData::Analytic(m),
                origin,
            },
            path,
            line,
        )?;
    }
    if out.is_empty() {
        return Err(CollectionError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}

impl crate::merl::CellSet {
    /// The cells of `mask` on the grid sub-sampled every `stride` cells, restricted to
    /// the cells valid in every measured material of `coll` (weights renormalised to sum
    /// 1 when any is measured): the cells every reduction over `coll` runs over.
    pub fn for_collection(
        coll: &Collection,
        mask: crate::merl::Mask,
        weighting: crate::merl::Weighting,
        stride: std::num::NonZeroUsize,
    ) -> Self {
        let mut cs = Self::new(mask, weighting, stride.get());
        let tables: Vec<&MerlTable> = coll
            .materials()
            .iter()
            .filter_map(|m| match &m.data {
                MaterialData::Measured(t) => Some(t.as_ref()),
                MaterialData::Rgl(t) => Some(t.table().as_ref()),
                MaterialData::Analytic(_) | MaterialData::Neural(_) => None,
            })
            .collect();
        if !tables.is_empty() {
            let keep: Vec<bool> = cs
                .cells
                .iter()
                .map(|&c| tables.iter().all(|t| t.is_valid(c as usize)))
                .collect();
            let mut k = keep.iter();
            cs.cells.retain(|_| *k.next().unwrap_or(&false));
            let mut k = keep.iter();
            cs.weights.retain(|_| *k.next().unwrap_or(&false));
            let total: f64 = cs.weights.iter().sum();
            if total > 0.0 {
                cs.weights.iter_mut().for_each(|w| *w /= total);
            }
        }
        cs
    }
}
