//! Samples files (SPEC 10): a CSV with header, columns `theta_i,phi_i,theta_o,phi_o,r,g,b`
//! (degrees; both directions above the horizon), optional `sigma` or
//! `sigma_r,sigma_g,sigma_b`, other columns ignored; or an ASTM E1392 `.astm` file (the
//! Cornell layout: `KEY value` header lines, `VARS theta_i,phi_i,theta_s,phi_s,R,G,B`, then
//! one comma-separated row per sample, angles in radians). Every value is validated; an
//! error names the file, the line (the header is line 1) and the column.
//!
//! One reader serves the samples of `fit --samples` ([`read_samples`]) and the candidate
//! directions of `plan --candidates` ([`read_candidates`]: the same files, whose values,
//! if any, are ignored). Both refuse a header that names a column twice (which one holds
//! the value?) and an ASTM `VARS` line that names one quantity twice, under the same or
//! another of its names (`theta_s` and `theta_o`; `R,G,B` and `BRDF`).
//!
//! Range: a reflectance above [`MAX_VALUE`] and standard deviations more than
//! [`MAX_SIGMA_RATIO`] apart are refused (the fit's weighted sums must stay finite and its
//! weights above zero); the fit weights are `(sigma_min / sigma)^2`, the SPEC's
//! `1 / sigma^2` scaled by the smallest sigma of the set, so scaling every sigma by one
//! constant changes nothing.

use super::eval::direction;
use super::AcquireError;
use std::path::Path;

/// Largest samples file read.
pub const MAX_SAMPLES_BYTES: u64 = 256 << 20;

/// Largest reflectance (or BRDF value) a sample may hold: the fit sums squares of weighted
/// values over the samples, which must stay finite with room to spare (measured
/// reflectances are below 1e6).
pub const MAX_VALUE: f64 = 1e100;

/// Largest ratio between the largest and the smallest standard deviation of a sample set:
/// the weights `(sigma_min / sigma)^2` then stay at or above 1e-200, far from underflow.
pub const MAX_SIGMA_RATIO: f64 = 1e100;

/// One measured sample: a direction pair in the local frame and the RGB reflectance there
/// (MERL scales applied, SPEC 2), with per-channel standard deviations.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Incoming direction (unit, z > 0).
    pub wi: [f64; 3],
    /// Outgoing direction (unit, z > 0).
    pub wo: [f64; 3],
    /// Measured reflectance, RGB (finite, >= 0).
    pub rgb: [f64; 3],
    /// Standard deviation per channel (> 0); `None` without sigma (weight 1).
    pub sigma: Option<[f64; 3]>,
    /// 1-based line of the file (0 for samples given as arrays).
    pub line: usize,
}

impl Sample {
    /// Weight of channel `c` in a set whose smallest standard deviation is `floor`
    /// (`sigma_floor`): `(floor / sigma)^2`, the SPEC's `1 / sigma^2` scaled by
    /// `floor^2` so that it never underflows or overflows (1 without sigma). Scaling every
    /// sigma of the set by one constant leaves the weights unchanged.
    pub fn weight(&self, c: usize, floor: f64) -> f64 {
        self.sigma.map_or(1.0, |s| {
            let r = floor / s[c];
            r * r
        })
    }
}

/// The smallest standard deviation of `samples` (1 when none has sigma): the scale of
/// [`Sample::weight`].
pub(crate) fn sigma_floor(samples: &[Sample]) -> f64 {
    let low = samples
        .iter()
        .filter_map(|s| s.sigma)
        .flatten()
        .fold(f64::INFINITY, f64::min);
    if low.is_finite() {
        low
    } else {
        1.0
    }
}

/// Samples from angles in degrees and values, validated like a file (`line` names the row
/// in errors; `what` the source).
#[allow(clippy::too_many_arguments)]
pub(crate) fn sample_from_degrees(
    what: &Path,
    line: usize,
    angles: [f64; 4],
    rgb: [f64; 3],
    sigma: Option<[f64; 3]>,
    names: [&str; 4],
) -> Result<Sample, AcquireError> {
    let err = |col: &str, message: String| AcquireError::Parse {
        path: what.to_path_buf(),
        line,
        column: Some(col.to_string()),
        message,
    };
    let (wi, wo) = directions_from_degrees(what, line, angles, names)?;
    for (c, (&v, name)) in rgb.iter().zip(["r", "g", "b"]).enumerate() {
        if !v.is_finite() || v < 0.0 {
            return Err(err(
                name,
                format!("{v} is not a finite non-negative reflectance"),
            ));
        }
        if v > MAX_VALUE {
            return Err(err(
                name,
                format!(
                    "{v:e} is beyond the largest reflectance the fit carries ({MAX_VALUE:e}); measured reflectances are far below it: check the file's units"
                ),
            ));
        }
        if let Some(s) = sigma {
            if !s[c].is_finite() || s[c] <= 0.0 {
                return Err(err(
                    ["sigma_r", "sigma_g", "sigma_b"][c],
                    format!("{} is not a positive standard deviation", s[c]),
                ));
            }
        }
    }
    Ok(Sample {
        wi,
        wo,
        rgb,
        sigma,
        line,
    })
}

/// The unit directions of angles in degrees `[theta_i, phi_i, theta_o, phi_o]`, both
/// above the horizon (`names` name the angles in errors).
fn directions_from_degrees(
    what: &Path,
    line: usize,
    angles: [f64; 4],
    names: [&str; 4],
) -> Result<([f64; 3], [f64; 3]), AcquireError> {
    let err = |col: &str, message: String| AcquireError::Parse {
        path: what.to_path_buf(),
        line,
        column: Some(col.to_string()),
        message,
    };
    for (k, (&a, name)) in angles.iter().zip(names).enumerate() {
        if !a.is_finite() {
            return Err(err(name, format!("{a} is not a finite angle")));
        }
        if k % 2 == 0 && !(0.0..90.0).contains(&a) {
            return Err(err(
                name,
                format!(
                    "{a} deg is not above the horizon (a polar angle must lie in [0, 90) degrees)"
                ),
            ));
        }
    }
    let [ti, pi, to, po] = angles.map(f64::to_radians);
    Ok((direction(ti, pi), direction(to, po)))
}

/// Refuses standard deviations more than [`MAX_SIGMA_RATIO`] apart in `samples` read from
/// `what`, naming the line and column of the largest (`columns`: the sigma columns, per
/// channel, as the source names them).
pub(crate) fn check_sigma_range(
    what: &Path,
    samples: &[Sample],
    columns: [&str; 3],
) -> Result<(), AcquireError> {
    let mut low: Option<(f64, usize, usize)> = None;
    let mut high: Option<(f64, usize, usize)> = None;
    for s in samples {
        for (c, &v) in s.sigma.iter().flatten().enumerate() {
            if low.is_none_or(|l| v < l.0) {
                low = Some((v, s.line, c));
            }
            if high.is_none_or(|h| v > h.0) {
                high = Some((v, s.line, c));
            }
        }
    }
    let (Some(low), Some(high)) = (low, high) else {
        return Ok(());
    };
    if high.0 / low.0 <= MAX_SIGMA_RATIO {
        return Ok(());
    }
    Err(AcquireError::Parse {
        path: what.to_path_buf(),
        line: high.1,
        column: Some(columns[high.2].to_string()),
        message: format!(
            "standard deviation {} is {:e} times the smallest, {} (line {}, column `{}`): the fit weights each sample by 1/sigma^2, and sigmas more than {MAX_SIGMA_RATIO:e} apart give weights it cannot carry; a sample this much less precise than the others adds nothing to the fit: leave it out",
            crate::stats::num(high.0),
            high.0 / low.0,
            crate::stats::num(low.0),
            low.1,
            columns[low.2]
        ),
    })
}

/// `e` with its column renamed by `f` (a parse error naming a column).
fn with_column(e: AcquireError, f: impl FnOnce(&str) -> String) -> AcquireError {
    match e {
        AcquireError::Parse {
            path,
            line,
            column: Some(c),
            message,
        } => AcquireError::Parse {
            path,
            line,
            column: Some(f(&c)),
            message,
        },
        e => e,
    }
}

/// An `(incoming, outgoing)` pair of unit directions.
pub type DirectionPair = ([f64; 3], [f64; 3]);

/// What a samples file is read for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Purpose {
    /// Measured samples: directions, values and optional sigmas, all validated.
    Samples,
    /// Candidate directions: the angles only; values, if any, are ignored.
    Candidates,
}

/// Reads a samples file: `.astm` as ASTM E1392, anything else as the CSV of SPEC 10.
/// At least one sample is required, and sigmas at most [`MAX_SIGMA_RATIO`] apart.
pub fn read_samples(path: &Path) -> Result<Vec<Sample>, AcquireError> {
    read(path, Purpose::Samples)
}

/// Samples given as arrays (Python's `fit_samples`): per sample the angles
/// `[theta_i, phi_i, theta_o, phi_o]` in degrees, the RGB values and optional per-channel
/// standard deviations, validated as a samples file's rows (row `i` is reported as line
/// `i + 1` of `<arrays>`, sigmas at most [`MAX_SIGMA_RATIO`] apart).
///
/// # Errors
/// [`AcquireError`]: arrays of different lengths, an invalid row.
pub fn samples_from_arrays(
    angles: &[[f64; 4]],
    rgb: &[[f64; 3]],
    sigma: Option<&[[f64; 3]]>,
) -> Result<Vec<Sample>, AcquireError> {
    let what = Path::new("<arrays>");
    if angles.len() != rgb.len() || sigma.is_some_and(|s| s.len() != rgb.len()) {
        return Err(AcquireError::InvalidParam {
            name: "sample arrays",
            value: format!("{} angles, {} values", angles.len(), rgb.len()),
            expected: "one row of angles, values (and sigmas) per sample".into(),
        });
    }
    let samples: Vec<Sample> = angles
        .iter()
        .zip(rgb)
        .enumerate()
        .map(|(i, (a, v))| {
            let names = ["theta_i", "phi_i", "theta_o", "phi_o"];
            sample_from_degrees(what, i + 1, *a, *v, sigma.map(|s| s[i]), names)
        })
        .collect::<Result<_, _>>()?;
    check_sigma_range(what, &samples, ["sigma_r", "sigma_g", "sigma_b"])?;
    Ok(samples)
}

/// Reads the candidate directions of `plan --candidates`: a samples file
/// ([`read_samples`]'s formats, columns and checks of the angles) whose values are
/// ignored, so they may be missing (a `plan --out` CSV is a candidates file) or not
/// numbers. Returns `(incoming, outgoing)` unit directions, at least one.
///
/// A direction pair given twice is refused naming both lines: a plan would otherwise
/// measure one direction several times (rows equal to 1e-9 in the unit vectors; at
/// theta 0 every phi is one direction).
pub fn read_candidates(path: &Path) -> Result<Vec<DirectionPair>, AcquireError> {
    unique_pairs(read(path, Purpose::Candidates)?, path)
}

/// [`read_samples`] on the bytes of a file already read (`path` names it in errors and
/// picks the format by its extension): what the fuzz targets run.
pub fn parse_samples(bytes: &[u8], path: &Path) -> Result<Vec<Sample>, AcquireError> {
    parse(bytes, path, Purpose::Samples)
}

/// [`read_candidates`] on the bytes of a file already read, as [`parse_samples`].
pub fn parse_candidates(bytes: &[u8], path: &Path) -> Result<Vec<DirectionPair>, AcquireError> {
    unique_pairs(parse(bytes, path, Purpose::Candidates)?, path)
}

/// The direction pairs of candidates `s`, each at most once (else an error naming both
/// lines).
fn unique_pairs(s: Vec<Sample>, path: &Path) -> Result<Vec<DirectionPair>, AcquireError> {
    let key = |v: &[f64; 3]| v.map(|x| (x * 1e9).round() as i64);
    let mut seen = std::collections::HashMap::with_capacity(s.len());
    for x in &s {
        if let Some(first) = seen.insert((key(&x.wi), key(&x.wo)), x.line) {
            return Err(AcquireError::Parse {
                path: path.to_path_buf(),
                line: x.line,
                column: None,
                message: format!(
                    "the direction pair is the one of line {first} (at theta 0 every phi is one direction); give each candidate once, or a plan could measure one direction twice"
                ),
            });
        }
    }
    Ok(s.into_iter().map(|x| (x.wi, x.wo)).collect())
}

fn read(path: &Path, purpose: Purpose) -> Result<Vec<Sample>, AcquireError> {
    let what = match purpose {
        Purpose::Samples => "a samples file",
        Purpose::Candidates => "a candidates file",
    };
    let bytes = crate::collection::read_regular(path, MAX_SAMPLES_BYTES).map_err(|e| match e {
        crate::error::CollectionError::Io { source, .. } => AcquireError::Io {
            path: path.to_path_buf(),
            source,
        },
        crate::error::CollectionError::NotRegular { kind, .. } => AcquireError::File {
            path: path.to_path_buf(),
            message: format!(
                "is {kind}, not a regular file; {what} is a regular .csv or .astm file"
            ),
        },
        crate::error::CollectionError::TooLarge { bytes, max, .. } => AcquireError::File {
            path: path.to_path_buf(),
            message: format!("{bytes} bytes, larger than the {max} bytes {what} may have"),
        },
        other => AcquireError::File {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    })?;
    parse(&bytes, path, purpose)
}

/// The samples (or candidates) in the bytes of a file named `path`.
fn parse(bytes: &[u8], path: &Path, purpose: Purpose) -> Result<Vec<Sample>, AcquireError> {
    let astm = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("astm"));
    let (s, sigma_columns) = if astm {
        (parse_astm_for(bytes, path, purpose)?, None)
    } else {
        parse_csv_for(bytes, path, purpose)?
    };
    if s.is_empty() {
        return Err(AcquireError::NoSamples {
            what: path.display().to_string(),
        });
    }
    if let Some(columns) = sigma_columns {
        check_sigma_range(path, &s, columns)?;
    }
    Ok(s)
}

/// Refuses a header that names a column twice (`line`: the header's line; columns count
/// from 1 in the message).
fn check_unique(
    path: &Path,
    line: usize,
    header: &[String],
    what: &str,
) -> Result<(), AcquireError> {
    for (j, h) in header.iter().enumerate() {
        if let Some(i) = header[..j].iter().position(|x| x == h) {
            return Err(AcquireError::Parse {
                path: path.to_path_buf(),
                line,
                column: Some(h.clone()),
                message: format!(
                    "appears twice ({what}s {} and {}); each {what} may appear once",
                    i + 1,
                    j + 1
                ),
            });
        }
    }
    Ok(())
}

/// Parses the CSV of SPEC 10.
pub fn parse_csv(bytes: &[u8], path: &Path) -> Result<Vec<Sample>, AcquireError> {
    let (s, columns) = parse_csv_for(bytes, path, Purpose::Samples)?;
    if let Some(columns) = columns {
        check_sigma_range(path, &s, columns)?;
    }
    Ok(s)
}

/// The CSV of SPEC 10 read for `purpose`, and the sigma columns per channel (if any).
fn parse_csv_for(
    bytes: &[u8],
    path: &Path,
    purpose: Purpose,
) -> Result<(Vec<Sample>, Option<[&'static str; 3]>), AcquireError> {
    let perr = |line: usize, column: Option<&str>, message: String| AcquireError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.map(str::to_string),
        message,
    };
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let header: Vec<String> = r
        .headers()
        .map_err(|e| perr(1, None, e.to_string()))?
        .iter()
        .map(str::to_string)
        .collect();
    check_unique(path, 1, &header, "column")?;
    let col = |name: &str| header.iter().position(|h| h == name);
    let angles = ["theta_i", "phi_i", "theta_o", "phi_o"];
    let required: &[&str] = match purpose {
        Purpose::Samples => &["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b"],
        Purpose::Candidates => &angles,
    };
    let mut idx = [0usize; 7];
    for (i, name) in required.iter().enumerate() {
        idx[i] = col(name).ok_or_else(|| {
            perr(
                1,
                Some(name),
                match purpose {
                    Purpose::Samples => format!(
                        "missing column (required: {}; optional: sigma or sigma_r,sigma_g,sigma_b)",
                        required.join(",")
                    ),
                    Purpose::Candidates => format!(
                        "missing column (required: {}; any other column, such as r,g,b, is ignored)",
                        required.join(",")
                    ),
                },
            )
        })?;
    }
    let (sig, sig_names): (Option<[usize; 3]>, [&'static str; 3]) =
        if purpose == Purpose::Candidates {
            (None, ["sigma"; 3])
        } else {
            match (col("sigma"), col("sigma_r"), col("sigma_g"), col("sigma_b")) {
                (Some(_), Some(_), _, _) | (Some(_), _, Some(_), _) | (Some(_), _, _, Some(_)) => {
                    return Err(perr(
                        1,
                        Some("sigma"),
                        "give either sigma or sigma_r,sigma_g,sigma_b, not both".into(),
                    ))
                }
                (Some(s), None, None, None) => (Some([s; 3]), ["sigma"; 3]),
                (None, Some(r), Some(g), Some(b)) => {
                    (Some([r, g, b]), ["sigma_r", "sigma_g", "sigma_b"])
                }
                (None, None, None, None) => (None, ["sigma"; 3]),
                _ => {
                    return Err(perr(
                        1,
                        Some("sigma_r"),
                        "per-channel sigmas need all three columns sigma_r,sigma_g,sigma_b".into(),
                    ))
                }
            }
        };
    let mut out = Vec::new();
    for (k, rec) in r.records().enumerate() {
        let line = k + 2;
        let rec = rec.map_err(|e| perr(line, None, e.to_string()))?;
        let num = |i: usize| -> Result<f64, AcquireError> {
            let s = rec.get(i).unwrap_or("");
            s.parse::<f64>()
                .map_err(|_| perr(line, Some(&header[i]), format!("`{s}` is not a number")))
        };
        let a = [num(idx[0])?, num(idx[1])?, num(idx[2])?, num(idx[3])?];
        let s = match purpose {
            Purpose::Candidates => {
                let (wi, wo) = directions_from_degrees(path, line, a, angles)?;
                Sample {
                    wi,
                    wo,
                    rgb: [0.0; 3],
                    sigma: None,
                    line,
                }
            }
            Purpose::Samples => {
                let rgb = [num(idx[4])?, num(idx[5])?, num(idx[6])?];
                let sigma = match sig {
                    Some(s) => Some([num(s[0])?, num(s[1])?, num(s[2])?]),
                    None => None,
                };
                // A single `sigma` column is named as the file names it.
                sample_from_degrees(path, line, a, rgb, sigma, angles).map_err(|e| {
                    with_column(e, |c| {
                        if c.starts_with("sigma_") && sig_names[0] == "sigma" {
                            "sigma".to_string()
                        } else {
                            c.to_string()
                        }
                    })
                })?
            }
        };
        out.push(s);
    }
    Ok((out, sig.map(|_| sig_names)))
}

/// Parses an ASTM E1392 file in the Cornell layout: header lines `KEY value` up to
/// `VARS name,name,...`, then one comma- (or blank-) separated row per sample. Variables:
/// `theta_i`, `phi_i`, `theta_s` (or `theta_o`, `theta_r`), `phi_s` (or `phi_o`, `phi_r`)
/// in radians, and `R,G,B` (or one `BRDF` value, used for all three channels); one
/// quantity named twice (under one name or two) is refused. A `NUM_POINTS` header must
/// match the rows, and no data row may precede `VARS`.
pub fn parse_astm(bytes: &[u8], path: &Path) -> Result<Vec<Sample>, AcquireError> {
    parse_astm_for(bytes, path, Purpose::Samples)
}

/// The text of an ASTM file: UTF-8, or else (audit 2, U9) header and comment lines in
/// Latin-1 (ISO 8859-1, as instruments write a `SOURCE` or an operator's name), each byte
/// one character; the `VARS` line and the rows after it must still be text (ASCII or
/// UTF-8), and one that is not is refused naming its line.
fn astm_text<'a>(bytes: &'a [u8], path: &Path) -> Result<std::borrow::Cow<'a, str>, AcquireError> {
    if let Ok(t) = std::str::from_utf8(bytes) {
        return Ok(std::borrow::Cow::Borrowed(t));
    }
    let mut out = String::with_capacity(bytes.len());
    let mut data = false;
    for (k, line) in bytes.split(|&b| b == b'\n').enumerate() {
        data |= line.trim_ascii_start().starts_with(b"VARS");
        match std::str::from_utf8(line) {
            Ok(t) => out.push_str(t),
            Err(e) if data => {
                return Err(AcquireError::Parse {
                    path: path.to_path_buf(),
                    line: k + 1,
                    column: None,
                    message: format!(
                        "not text: {e} (header and comment lines may be Latin-1; the VARS line and the data rows must be ASCII or UTF-8)"
                    ),
                })
            }
            Err(_) => out.extend(line.iter().map(|&b| char::from(b))),
        }
        out.push('\n');
    }
    Ok(std::borrow::Cow::Owned(out))
}

/// Long function: one check per header line and per value, each with its own error
/// naming the file, line and column, read top to bottom as the format lays them out (as
/// `parse_csv_for`).
fn parse_astm_for(
    bytes: &[u8],
    path: &Path,
    purpose: Purpose,
) -> Result<Vec<Sample>, AcquireError> {
    let perr = |line: usize, column: Option<&str>, message: String| AcquireError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.map(str::to_string),
        message,
    };
    let text = astm_text(bytes, path)?;
    let text = text.as_ref();
    let split = |t: &str| -> Vec<String> {
        t.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect()
    };
    let mut lines = text.lines().enumerate();
    let mut vars: Option<(usize, Vec<String>)> = None;
    let mut num_points: Option<(usize, usize)> = None;
    for (k, l) in lines.by_ref() {
        let t = l.trim();
        if let Some(rest) = t.strip_prefix("VARS") {
            vars = Some((k + 1, split(rest)));
            break;
        }
        if let Some(rest) = t.strip_prefix("NUM_POINTS") {
            let v = rest.trim();
            let n = v.parse::<usize>().map_err(|_| {
                perr(
                    k + 1,
                    None,
                    format!("NUM_POINTS `{v}` is not a number of points"),
                )
            })?;
            num_points = Some((k + 1, n));
        }
        let f = split(t);
        if !f.is_empty() && f.iter().all(|x| x.parse::<f64>().is_ok()) {
            return Err(perr(
                k + 1,
                None,
                "a row of numbers before the `VARS` line: the variables must be named before the data".into(),
            ));
        }
    }
    let Some((vline, names)) = vars else {
        return Err(AcquireError::File {
            path: path.to_path_buf(),
            message: "no `VARS` line: not an ASTM E1392 file".into(),
        });
    };
    // Names as the file spells them (in messages); matched without case.
    let lower: Vec<String> = names.iter().map(|s| s.to_ascii_lowercase()).collect();
    check_unique(path, vline, &lower, "variable").map_err(|e| {
        with_column(e, |c| {
            names[lower.iter().position(|l| l == c).unwrap_or(0)].clone()
        })
    })?;
    // One quantity under two of its names is as ambiguous as one name twice.
    let find = |alts: &[&str]| -> Result<Option<usize>, AcquireError> {
        let found: Vec<usize> = (0..lower.len())
            .filter(|&i| alts.contains(&lower[i].as_str()))
            .collect();
        match found[..] {
            [] => Ok(None),
            [i] => Ok(Some(i)),
            [i, j, ..] => Err(perr(
                vline,
                Some(&names[j]),
                format!(
                    "names the same quantity as `{}` (variables {} and {}): which one holds it? give one of {}",
                    names[i],
                    i + 1,
                    j + 1,
                    alts.join(", ")
                ),
            )),
        }
    };
    let missing = |name: &str| perr(vline, Some(name), "missing variable".into());
    let ti = find(&["theta_i"])?.ok_or_else(|| missing("theta_i"))?;
    let pi = find(&["phi_i"])?.ok_or_else(|| missing("phi_i"))?;
    let to = find(&["theta_s", "theta_o", "theta_r"])?.ok_or_else(|| missing("theta_s"))?;
    let po = find(&["phi_s", "phi_o", "phi_r"])?.ok_or_else(|| missing("phi_s"))?;
    let (r, g, b, brdf) = (
        find(&["r"])?,
        find(&["g"])?,
        find(&["b"])?,
        find(&["brdf"])?,
    );
    let rgb_idx: Option<[usize; 3]> = match (r, g, b, brdf) {
        (Some(_), Some(_), Some(_), Some(v)) | (Some(_), _, _, Some(v)) => {
            return Err(perr(
                vline,
                Some(&names[v]),
                "give R,G,B or BRDF, not both: which one holds the value?".into(),
            ))
        }
        (Some(r), Some(g), Some(b), None) => Some([r, g, b]),
        (None, None, None, Some(v)) => Some([v; 3]),
        _ if purpose == Purpose::Candidates => None,
        _ => {
            return Err(perr(
                vline,
                Some("R"),
                "missing variables R,G,B (or BRDF)".into(),
            ))
        }
    };
    let mut out = Vec::new();
    let mut last = vline;
    for (k, l) in lines {
        let t = l.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let line = k + 1;
        last = line;
        let f = split(t);
        let num = |i: usize| -> Result<f64, AcquireError> {
            let s = f.get(i).map_or("", String::as_str);
            s.parse::<f64>()
                .map_err(|_| perr(line, Some(&names[i]), format!("`{s}` is not a number")))
        };
        let rad = [num(ti)?, num(pi)?, num(to)?, num(po)?];
        for (a, i) in rad.iter().zip([ti, pi, to, po]) {
            if a.abs() > 4.0 * std::f64::consts::PI {
                return Err(perr(
                    line,
                    Some(&names[i]),
                    format!("{a} is not an angle in radians (ASTM files give angles in radians)"),
                ));
            }
        }
        let angle_names = [&names[ti], &names[pi], &names[to], &names[po]].map(|s| s.as_str());
        out.push(match (purpose, rgb_idx) {
            (Purpose::Samples, Some(v)) => sample_from_degrees(
                path,
                line,
                rad.map(f64::to_degrees),
                [num(v[0])?, num(v[1])?, num(v[2])?],
                None,
                angle_names,
            )
            .map_err(|e| {
                with_column(e, |c| match ["r", "g", "b"].iter().position(|x| *x == c) {
                    Some(k) => names[v[k]].clone(),
                    None => c.to_string(),
                })
            })?,
            _ => {
                let (wi, wo) =
                    directions_from_degrees(path, line, rad.map(f64::to_degrees), angle_names)?;
                Sample {
                    wi,
                    wo,
                    rgb: [0.0; 3],
                    sigma: None,
                    line,
                }
            }
        });
    }
    if let Some((line, n)) = num_points {
        if n != out.len() {
            return Err(perr(
                line,
                None,
                format!(
                    "NUM_POINTS {n}, but the file has {} data rows (the last at line {last}): a truncated or padded file?",
                    out.len()
                ),
            ));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_rows_and_errors_name_line_and_column() {
        let p = Path::new("m.csv");
        let ok = b"theta_i,phi_i,theta_o,phi_o,r,g,b,note\n0,0,30,180,0.1,0.2,0.3,x\n";
        let s = parse_csv(ok, p).unwrap();
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].line, 2);
        assert!((s[0].wo[0] + 0.5).abs() < 1e-15 && (s[0].wo[2] - 0.75f64.sqrt()).abs() < 1e-15);
        let bad =
            b"theta_i,phi_i,theta_o,phi_o,r,g,b\n0,0,30,0,0.1,0.2,0.3\n0,0,95,0,0.1,0.2,0.3\n";
        let e = parse_csv(bad, p).unwrap_err().to_string();
        assert!(
            e.contains("line 3") && e.contains("theta_o") && e.contains("horizon"),
            "{e}"
        );
        let neg = b"theta_i,phi_i,theta_o,phi_o,r,g,b\n0,0,30,0,0.1,-0.2,0.3\n";
        let e = parse_csv(neg, p).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("column `g`"), "{e}");
        let sig = b"theta_i,phi_i,theta_o,phi_o,r,g,b,sigma\n0,0,30,0,0.1,0.2,0.3,0\n";
        let e = parse_csv(sig, p).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("sigma"), "{e}");
        let miss = b"theta_i,phi_i,theta_o,r,g,b\n";
        let e = parse_csv(miss, p).unwrap_err().to_string();
        assert!(e.contains("line 1") && e.contains("phi_o"), "{e}");
        let nan = b"theta_i,phi_i,theta_o,phi_o,r,g,b\n0,0,30,0,x,0.2,0.3\n";
        let e = parse_csv(nan, p).unwrap_err().to_string();
        assert!(
            e.contains("`x` is not a number") && e.contains("column `r`"),
            "{e}"
        );
    }

    #[test]
    fn astm_cornell_layout_is_read_in_radians() {
        let text = b"SOURCE test\nNUM_POINTS 2\nVARS theta_i,phi_i,theta_s,phi_s,R,G,B\n0,0,0.5235987755982988,3.141592653589793,0.1,0.2,0.3\n0.1,0,0.2,0,1,1,1\n";
        let s = parse_astm(text, Path::new("m.astm")).unwrap();
        assert_eq!(s.len(), 2);
        assert!((s[0].wo[0] + 0.5).abs() < 1e-12, "{:?}", s[0].wo);
        assert_eq!(s[0].rgb, [0.1, 0.2, 0.3]);
        let bad = b"VARS theta_i,phi_i,theta_s,phi_s,R,G,B\n0,0,1.7,0,0.1,0.2,0.3\n";
        let e = parse_astm(bad, Path::new("m.astm"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("theta_s"), "{e}");
    }
}
