//! Samples files (SPEC 10): a CSV with header, columns `theta_i,phi_i,theta_o,phi_o,r,g,b`
//! (degrees; both directions above the horizon), optional `sigma` or
//! `sigma_r,sigma_g,sigma_b`, other columns ignored; or an ASTM E1392 `.astm` file (the
//! Cornell layout: `KEY value` header lines, `VARS theta_i,phi_i,theta_s,phi_s,R,G,B`, then
//! one comma-separated row per sample, angles in radians). Every value is validated; an
//! error names the file, the line (the header is line 1) and the column.

use super::eval::direction;
use super::AcquireError;
use std::path::Path;

/// Largest samples file read.
pub const MAX_SAMPLES_BYTES: u64 = 256 << 20;

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
    /// Weight `1 / sigma^2` of channel `c` (1 without sigma).
    pub fn weight(&self, c: usize) -> f64 {
        self.sigma.map_or(1.0, |s| 1.0 / (s[c] * s[c]))
    }
}

/// Samples from angles in degrees and values, validated like a file (`line` names the row
/// in errors; `what` the source).
#[allow(clippy::too_many_arguments)]
pub fn sample_from_degrees(
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
    for (c, (&v, name)) in rgb.iter().zip(["r", "g", "b"]).enumerate() {
        if !v.is_finite() || v < 0.0 {
            return Err(err(
                name,
                format!("{v} is not a finite non-negative reflectance"),
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
    let [ti, pi, to, po] = angles.map(f64::to_radians);
    Ok(Sample {
        wi: direction(ti, pi),
        wo: direction(to, po),
        rgb,
        sigma,
        line,
    })
}

/// Reads a samples file: `.astm` as ASTM E1392, anything else as the CSV of SPEC 10.
/// At least one sample is required.
pub fn read_samples(path: &Path) -> Result<Vec<Sample>, AcquireError> {
    let bytes = crate::collection::read_regular(path, MAX_SAMPLES_BYTES).map_err(|e| match e {
        crate::error::CollectionError::Io { source, .. } => AcquireError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => AcquireError::Parse {
            path: path.to_path_buf(),
            line: 0,
            column: None,
            message: other.to_string(),
        },
    })?;
    let astm = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("astm"));
    let s = if astm {
        parse_astm(&bytes, path)?
    } else {
        parse_csv(&bytes, path)?
    };
    if s.is_empty() {
        return Err(AcquireError::NoSamples {
            what: path.display().to_string(),
        });
    }
    Ok(s)
}

/// Parses the CSV of SPEC 10.
pub fn parse_csv(bytes: &[u8], path: &Path) -> Result<Vec<Sample>, AcquireError> {
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
    let col = |name: &str| header.iter().position(|h| h == name);
    let required = ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b"];
    let mut idx = [0usize; 7];
    for (i, name) in required.iter().enumerate() {
        idx[i] = col(name).ok_or_else(|| {
            perr(
                1,
                Some(name),
                format!(
                    "missing column (required: {}; optional: sigma or sigma_r,sigma_g,sigma_b)",
                    required.join(",")
                ),
            )
        })?;
    }
    let sig: Option<[usize; 3]> =
        match (col("sigma"), col("sigma_r"), col("sigma_g"), col("sigma_b")) {
            (Some(_), Some(_), _, _) | (Some(_), _, Some(_), _) | (Some(_), _, _, Some(_)) => {
                return Err(perr(
                    1,
                    Some("sigma"),
                    "give either sigma or sigma_r,sigma_g,sigma_b, not both".into(),
                ))
            }
            (Some(s), None, None, None) => Some([s; 3]),
            (None, Some(r), Some(g), Some(b)) => Some([r, g, b]),
            (None, None, None, None) => None,
            _ => {
                return Err(perr(
                    1,
                    Some("sigma_r"),
                    "per-channel sigmas need all three columns sigma_r,sigma_g,sigma_b".into(),
                ))
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
        let rgb = [num(idx[4])?, num(idx[5])?, num(idx[6])?];
        let sigma = match sig {
            Some(s) => Some([num(s[0])?, num(s[1])?, num(s[2])?]),
            None => None,
        };
        let mut s = sample_from_degrees(
            path,
            line,
            a,
            rgb,
            sigma,
            ["theta_i", "phi_i", "theta_o", "phi_o"],
        )?;
        s.line = line;
        out.push(s);
    }
    Ok(out)
}

/// Parses an ASTM E1392 file in the Cornell layout: header lines `KEY value` up to
/// `VARS name,name,...`, then one comma- (or blank-) separated row per sample. Variables:
/// `theta_i`, `phi_i`, `theta_s` (or `theta_o`, `theta_r`), `phi_s` (or `phi_o`, `phi_r`)
/// in radians, and `R,G,B` (or one `BRDF` value, used for all three channels).
pub fn parse_astm(bytes: &[u8], path: &Path) -> Result<Vec<Sample>, AcquireError> {
    let perr = |line: usize, column: Option<&str>, message: String| AcquireError::Parse {
        path: path.to_path_buf(),
        line,
        column: column.map(str::to_string),
        message,
    };
    let text =
        std::str::from_utf8(bytes).map_err(|e| perr(0, None, format!("not UTF-8 text: {e}")))?;
    let mut lines = text.lines().enumerate();
    let mut vars: Option<(usize, Vec<String>)> = None;
    for (k, l) in lines.by_ref() {
        let t = l.trim();
        if let Some(rest) = t.strip_prefix("VARS") {
            let names: Vec<String> = rest
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(|s| s.to_ascii_lowercase())
                .collect();
            vars = Some((k + 1, names));
            break;
        }
    }
    let Some((vline, names)) = vars else {
        return Err(perr(
            0,
            None,
            "no `VARS` line: not an ASTM E1392 file".into(),
        ));
    };
    let find = |alts: &[&str]| names.iter().position(|n| alts.contains(&n.as_str()));
    let ti = find(&["theta_i"])
        .ok_or_else(|| perr(vline, Some("theta_i"), "missing variable".into()))?;
    let pi =
        find(&["phi_i"]).ok_or_else(|| perr(vline, Some("phi_i"), "missing variable".into()))?;
    let to = find(&["theta_s", "theta_o", "theta_r"])
        .ok_or_else(|| perr(vline, Some("theta_s"), "missing variable".into()))?;
    let po = find(&["phi_s", "phi_o", "phi_r"])
        .ok_or_else(|| perr(vline, Some("phi_s"), "missing variable".into()))?;
    let rgb_idx: [usize; 3] = match (find(&["r"]), find(&["g"]), find(&["b"]), find(&["brdf"])) {
        (Some(r), Some(g), Some(b), _) => [r, g, b],
        (_, _, _, Some(v)) => [v; 3],
        _ => {
            return Err(perr(
                vline,
                Some("R"),
                "missing variables R,G,B (or BRDF)".into(),
            ))
        }
    };
    let mut out = Vec::new();
    for (k, l) in lines {
        let t = l.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let line = k + 1;
        let f: Vec<&str> = t
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        let num = |i: usize| -> Result<f64, AcquireError> {
            let s = f.get(i).copied().unwrap_or("");
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
        let rgb = [num(rgb_idx[0])?, num(rgb_idx[1])?, num(rgb_idx[2])?];
        out.push(sample_from_degrees(
            path,
            line,
            rad.map(f64::to_degrees),
            rgb,
            None,
            [&names[ti], &names[pi], &names[to], &names[po]].map(|s| s.as_str()),
        )?);
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
