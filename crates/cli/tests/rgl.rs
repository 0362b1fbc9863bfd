//! RGL-EPFL `.bsdf` files (SPEC 9): the container reader refuses malformed files with the
//! file and field named; the evaluation matches Mitsuba 3's `measured` BSDF (values in
//! `crates/cli/tests/reference/rgl_mitsuba_values.csv`, written by `crates/cli/tests/reference/rgl_mitsuba.py`);
//! the tabulation round-trips through a `.binary` file; and every command runs on a
//! collection mixing RGL and analytic materials.

use crate::common;
use brdf_basis::rgl::{self, RglBsdf};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The four RGL files of `../shared/data/real/rgl_bsdf`.
const FILES: [&str; 4] = [
    "cc_ibiza_sunset_rgb",
    "cg_sunflower_rgb",
    "colodur_napoli_4f_rgb",
    "paper_white_rgb",
];

fn rgl_path(stem: &str, test: &str) -> Option<PathBuf> {
    common::shared_or_skip(&format!("real/rgl_bsdf/{stem}.bsdf"), test)
}

/// One row of the Mitsuba reference: file stem, kind of pair, wi, wo, f (RGB).
struct RefRow {
    file: String,
    kind: String,
    wi: [f64; 3],
    wo: [f64; 3],
    f: [f64; 3],
}

fn reference_rows() -> Vec<RefRow> {
    let path = crate::common::repo().join("crates/cli/tests/reference/rgl_mitsuba_values.csv");
    let mut rdr = csv::Reader::from_path(&path).expect("reference CSV");
    rdr.records()
        .map(|r| {
            let r = r.expect("row");
            let x = |i: usize| r[i].parse::<f64>().expect("number");
            RefRow {
                file: r[0].to_string(),
                kind: r[1].to_string(),
                wi: [x(2), x(3), x(4)],
                wo: [x(5), x(6), x(7)],
                f: [x(8), x(9), x(10)],
            }
        })
        .collect()
}

/// Relative tolerance against Mitsuba wherever the reference exceeds [`FLOOR`] (SPEC 9).
const REL: f64 = 1e-3;
/// Below it, the difference must stay under `REL * FLOOR`.
const FLOOR: f64 = 1e-4;

#[test]
fn rgl_eval_matches_mitsuba() {
    let rows = reference_rows();
    assert!(rows.len() >= 4 * 300, "{} reference rows", rows.len());
    let mut worst: HashMap<String, (f64, usize, usize)> = HashMap::new();
    let mut bsdfs: HashMap<String, RglBsdf> = HashMap::new();
    for stem in FILES {
        let Some(p) = rgl_path(stem, "rgl_eval_matches_mitsuba") else {
            return;
        };
        bsdfs.insert(stem.to_string(), rgl::read(&p).expect("read"));
    }
    let mut failures = Vec::new();
    for (k, row) in rows.iter().enumerate() {
        let b = &bsdfs[&row.file];
        let f = b.eval(row.wi, row.wo);
        let e = worst.entry(row.file.clone()).or_insert((0.0, 0, 0));
        for (c, (&a, &r)) in f.iter().zip(&row.f).enumerate() {
            let bad = if r.abs() > FLOOR {
                let rel = (a - r).abs() / r.abs();
                if rel > e.0 {
                    *e = (rel, k, e.2);
                }
                rel > REL
            } else {
                (a - r).abs() > REL * FLOOR
            };
            if r.abs() > FLOOR {
                e.2 += 1;
            }
            if bad {
                failures.push(format!(
                    "row {} ({} {}): channel {c}: {a:e} vs Mitsuba {r:e}",
                    k + 2,
                    row.file,
                    row.kind
                ));
            }
        }
    }
    for stem in FILES {
        let (rel, k, n) = worst[stem];
        println!(
            "{stem}: max relative error vs Mitsuba {rel:.2e} (row {}, {n} values above {FLOOR:e})",
            k + 2
        );
        assert!(
            n >= 600,
            "{stem}: only {n} reference values above the floor"
        );
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

// ---------------------------------------------------------------------------------------
// A synthetic `.bsdf` file, written by the tests (no byte of a real file).

/// One field of a container: name, dtype code, shape, data bytes.
#[derive(Clone)]
pub(crate) struct Fld {
    name: String,
    dtype: u8,
    shape: Vec<u64>,
    pub(crate) data: Vec<u8>,
}

fn fld(name: &str, dtype: u8, shape: &[u64], data: Vec<u8>) -> Fld {
    Fld {
        name: name.into(),
        dtype,
        shape: shape.to_vec(),
        data,
    }
}

pub(crate) fn f32_bytes(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// The header size of a container of `fields`.
fn header_len(fields: &[Fld]) -> usize {
    18 + fields
        .iter()
        .map(|f| 2 + f.name.len() + 2 + 1 + 8 + 8 * f.shape.len())
        .sum::<usize>()
}

/// A tensor_file v1.0 holding `fields`, data laid out after the header in order.
fn container(fields: &[Fld]) -> Vec<u8> {
    let mut b = b"tensor_file\0".to_vec();
    b.extend_from_slice(&[1, 0]);
    b.extend_from_slice(&(fields.len() as u32).to_le_bytes());
    let mut offset = header_len(fields) as u64;
    for f in fields {
        b.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
        b.extend_from_slice(f.name.as_bytes());
        b.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
        b.push(f.dtype);
        b.extend_from_slice(&offset.to_le_bytes());
        for d in &f.shape {
            b.extend_from_slice(&d.to_le_bytes());
        }
        offset += f.data.len() as u64;
    }
    for f in fields {
        b.extend_from_slice(&f.data);
    }
    b
}

const F32: u8 = 10;
const U8: u8 = 1;
/// Incident elevations of the synthetic file.
const THETA_I: [f32; 3] = [0.0, 0.6, 1.2];
/// VNDF resolution (columns = theta axis, rows = phi axis) and RGB resolution.
const VW: usize = 9;
const VH: usize = 5;
const N: usize = 4;

/// A synthetic isotropic RGB file whose evaluation has a closed form: the VNDF density is
/// `2 x` in the unit theta coordinate `x` (uniform in phi), so its inverse sampling map
/// sends `x` to `x^2`; the RGB table is `(c + 1) s_x` (bilinear interpolation is exact on
/// it); `ndf` = 2 and `sigma` = 0.5, so `D / (4 sigma) = 1`. Hence
/// `f_c cos theta_o = (c + 1) * 2 theta_m / pi` with `theta_m` the half vector's elevation.
fn synthetic_fields() -> Vec<Fld> {
    let nt = THETA_I.len() as u64;
    let vndf = (0..nt as usize * VH * VW).map(|k| 2.0 * (k % VW) as f32 / (VW - 1) as f32);
    let rgb = (0..nt as usize * 3 * N * N).map(|k| {
        let c = (k / (N * N)) % 3;
        (c + 1) as f32 * (k % N) as f32 / (N - 1) as f32
    });
    let lum = (0..nt as usize * N * N).map(|k| 1.0 + (k % N) as f32);
    vec![
        fld("version", U8, &[2], vec![1, 0]),
        fld("description", U8, &[9], b"synthetic".to_vec()),
        fld("phi_i", F32, &[1], f32_bytes([0.0])),
        fld("theta_i", F32, &[nt], f32_bytes(THETA_I)),
        fld("sigma", F32, &[2, 8], f32_bytes([0.5; 16])),
        fld("ndf", F32, &[2, 8], f32_bytes([2.0; 16])),
        fld("vndf", F32, &[1, nt, VH as u64, VW as u64], f32_bytes(vndf)),
        fld(
            "luminance",
            F32,
            &[1, nt, N as u64, N as u64],
            f32_bytes(lum),
        ),
        fld("rgb", F32, &[1, nt, 3, N as u64, N as u64], f32_bytes(rgb)),
        fld("jacobian", U8, &[1], vec![1]),
        fld(
            "valid",
            U8,
            &[(nt as usize * N * N / 8) as u64],
            vec![0xff; 6],
        ),
    ]
}

fn synthetic() -> Vec<u8> {
    container(&synthetic_fields())
}

fn elevation(v: [f64; 3]) -> f64 {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (v[2] / l).clamp(-1.0, 1.0).acos()
}

fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

#[test]
fn rgl_synthetic_file_evaluates_to_its_closed_form() {
    let b = rgl::parse(synthetic(), Path::new("synthetic.bsdf")).expect("valid");
    assert_eq!(b.description, "synthetic");
    assert_eq!(b.resolution, N);
    use rand::Rng;
    let mut rng = common::rng(16);
    let mut checked = 0;
    for _ in 0..2000 {
        let wi = dir(rng.random_range(0.0..89.0), rng.random_range(-180.0..180.0));
        let wo = dir(rng.random_range(0.0..89.0), rng.random_range(-180.0..180.0));
        let m = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let base = 2.0 * elevation(m) / std::f64::consts::PI / wo[2];
        let f = b.eval(wi, wo);
        for (c, &fc) in f.iter().enumerate() {
            let want = (c + 1) as f64 * base;
            // The tables are float32: 2 k / 8 and 1 / 3 round at ~6e-8 relative.
            assert!(
                (fc - want).abs() <= 1e-6 * want.max(1e-3),
                "wi {wi:?} wo {wo:?} channel {c}: {fc} vs {want}"
            );
        }
        checked += 1;
    }
    assert_eq!(checked, 2000);
    // Below the horizon: 0.
    assert_eq!(b.eval(dir(30.0, 0.0), [0.3, 0.0, -0.9]), [0.0; 3]);
    assert_eq!(b.eval([0.3, 0.0, -0.9], dir(30.0, 0.0)), [0.0; 3]);
}

/// The error of parsing `bytes` as `name`; it must name the file.
fn parse_err(bytes: Vec<u8>, name: &str) -> (brdf_basis::error::RglError, String) {
    let e = rgl::parse(bytes, Path::new(name)).expect_err("malformed");
    let text = e.to_string();
    assert!(text.contains(name), "the error names the file: {text}");
    (e, text)
}

pub(crate) fn with(f: impl FnOnce(&mut Vec<Fld>)) -> Vec<u8> {
    let mut v = synthetic_fields();
    f(&mut v);
    container(&v)
}

pub(crate) fn field_mut<'a>(v: &'a mut [Fld], name: &str) -> &'a mut Fld {
    v.iter_mut().find(|f| f.name == name).expect("field")
}

use brdf_basis::error::RglError as E;

#[test]
fn rgl_refuses_empty_and_wrong_magic() {
    assert!(matches!(parse_err(vec![], "empty.bsdf").0, E::Magic { .. }));
    let mut b = synthetic();
    b[0] = b'T';
    assert!(matches!(parse_err(b, "magic.bsdf").0, E::Magic { .. }));
    // A MERL .binary header is not a tensor file.
    let merl: Vec<u8> = [90i32, 90, 180]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    assert!(matches!(parse_err(merl, "merl.bsdf").0, E::Magic { .. }));
}

#[test]
fn rgl_refuses_every_truncation() {
    let b = synthetic();
    let header = header_len(&synthetic_fields());
    for len in 1..b.len() {
        let (e, text) = parse_err(b[..len].to_vec(), "cut.bsdf");
        if len < header {
            assert!(matches!(e, E::Truncated { .. }), "{len}: {text}");
        } else {
            // The header is whole: some field's data runs past the end.
            assert!(matches!(e, E::PastEnd { .. }), "{len}: {text}");
            assert!(text.contains("runs past the end"), "{text}");
        }
    }
}

#[test]
fn rgl_refuses_wrong_version_and_unknown_dtype() {
    let mut b = synthetic();
    b[12] = 2;
    let (e, text) = parse_err(b, "v2.bsdf");
    assert!(
        matches!(e, E::Version { major: 2, .. }) && text.contains("2.0"),
        "{text}"
    );
    let b = with(|v| field_mut(v, "ndf").dtype = 99);
    let (e, text) = parse_err(b, "dtype99.bsdf");
    assert!(
        matches!(e, E::UnknownDtype { code: 99, .. }) && text.contains("`ndf`"),
        "{text}"
    );
}

#[test]
fn rgl_refuses_wrong_dtype() {
    // rgb as float64: the same values doubled in size.
    let b = with(|v| {
        let f = field_mut(v, "rgb");
        f.dtype = 11;
        let d = f.data.clone();
        f.data = d
            .chunks_exact(4)
            .flat_map(|c| (f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64).to_le_bytes())
            .collect();
    });
    let (e, text) = parse_err(b, "f64.bsdf");
    assert!(
        matches!(
            e,
            E::WrongDtype {
                field: "rgb",
                expected: "float32",
                found: "float64",
                ..
            }
        ),
        "{text}"
    );
    let b = with(|v| field_mut(v, "jacobian").dtype = F32);
    // A 1-element float32 needs 4 bytes where 1 is stored: the shape lies about the data
    // unless it is the last field's... either way an error naming the file.
    let (_, text) = parse_err(b, "jac.bsdf");
    assert!(text.contains("jac.bsdf"), "{text}");
}

#[test]
fn rgl_refuses_lying_shapes() {
    // More data claimed than stored: past the end (rgb is near the end of the file).
    let b = with(|v| field_mut(v, "valid").shape = vec![600]);
    let (e, text) = parse_err(b, "long.bsdf");
    assert!(
        matches!(e, E::PastEnd { .. }) && text.contains("`valid`"),
        "{text}"
    );
    // A shape that disagrees with theta_i.
    let b = with(|v| {
        let f = field_mut(v, "rgb");
        f.shape = vec![1, 2, 3, N as u64, N as u64];
        f.data.truncate(2 * 3 * N * N * 4);
    });
    let (e, text) = parse_err(b, "rgbshape.bsdf");
    assert!(
        matches!(e, E::Shape { field: "rgb", .. }) && text.contains("[1, 2, 3, 4, 4]"),
        "{text}"
    );
    // rgb of another resolution than the luminance table.
    let b = with(|v| {
        let f = field_mut(v, "rgb");
        f.shape = vec![1, 3, 3, 2, 8];
    });
    assert!(matches!(
        parse_err(b, "res.bsdf").0,
        E::Shape { field: "rgb", .. }
    ));
    let b = with(|v| field_mut(v, "vndf").shape = vec![1, 3, VW as u64 * VH as u64]);
    assert!(matches!(
        parse_err(b, "ndim.bsdf").0,
        E::Shape { field: "vndf", .. }
    ));
    let b = with(|v| {
        let f = field_mut(v, "ndf");
        f.shape = vec![1, 16];
    });
    assert!(matches!(
        parse_err(b, "ndf1.bsdf").0,
        E::Shape { field: "ndf", .. }
    ));
}

#[test]
fn rgl_refuses_offsets_past_the_end_and_overflowing_sizes() {
    let fields = synthetic_fields();
    let good = container(&fields);
    // Field k's offset sits after its name, dimension count and dtype.
    let offset_at = |k: usize| {
        18 + fields[..k]
            .iter()
            .map(|f| 2 + f.name.len() + 2 + 1 + 8 + 8 * f.shape.len())
            .sum::<usize>()
            + 2
            + fields[k].name.len()
            + 3
    };
    let k = fields
        .iter()
        .position(|f| f.name == "sigma")
        .expect("sigma");
    for bad in [good.len() as u64, u64::MAX - 3, 1 << 40] {
        let mut b = good.clone();
        b[offset_at(k)..offset_at(k) + 8].copy_from_slice(&bad.to_le_bytes());
        let (e, text) = parse_err(b, "offset.bsdf");
        assert!(
            matches!(e, E::PastEnd { .. } | E::Overflow { .. }) && text.contains("`sigma`"),
            "{text}"
        );
    }
    // A shape whose element count overflows 64 bits.
    let b = with(|v| field_mut(v, "ndf").shape = vec![u64::MAX, 3]);
    let (e, text) = parse_err(b, "overflow.bsdf");
    assert!(
        matches!(e, E::Overflow { .. }) && text.contains("`ndf`"),
        "{text}"
    );
    // One whose byte size overflows.
    let b = with(|v| field_mut(v, "ndf").shape = vec![1 << 62, 2]);
    assert!(matches!(parse_err(b, "bytes.bsdf").0, E::Overflow { .. }));
    // A field count far beyond what the file holds: truncated, not a huge allocation.
    let mut b = good.clone();
    b[14..18].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(parse_err(b, "count.bsdf").0, E::Truncated { .. }));
}

#[test]
fn rgl_refuses_missing_and_duplicate_fields() {
    for name in [
        "phi_i",
        "theta_i",
        "sigma",
        "ndf",
        "vndf",
        "luminance",
        "rgb",
        "jacobian",
        "description",
    ] {
        let b = with(|v| v.retain(|f| f.name != name));
        let (e, text) = parse_err(b, "missing.bsdf");
        assert!(
            matches!(e, E::MissingField { field, .. } if field == name),
            "{name}: {text}"
        );
    }
    let b = with(|v| {
        let d = v[2].clone();
        v.push(d);
    });
    let (e, text) = parse_err(b, "dup.bsdf");
    assert!(
        matches!(e, E::DuplicateField { .. }) && text.contains("`phi_i`"),
        "{text}"
    );
}

#[test]
fn rgl_refuses_anisotropic_and_spectral_files() {
    let b = with(|v| {
        let f = field_mut(v, "phi_i");
        f.shape = vec![4];
        f.data = f32_bytes([0.0, 0.5, 1.0, 1.5]);
    });
    let (e, text) = parse_err(b, "aniso.bsdf");
    assert!(
        matches!(e, E::Anisotropic { count: 4, .. }) && text.contains("anisotropic"),
        "{text}"
    );
    let b = with(|v| {
        field_mut(v, "rgb").name = "spectra".into();
        v.push(fld(
            "wavelengths",
            F32,
            &[3],
            f32_bytes([400.0, 550.0, 700.0]),
        ));
    });
    let (e, text) = parse_err(b, "spectral.bsdf");
    assert!(
        matches!(e, E::SpectralOnly { .. }) && text.contains("spectral-only"),
        "{text}"
    );
}

#[test]
fn rgl_refuses_bad_values() {
    let set = |name: &'static str, index: usize, x: f32| {
        with(move |v| {
            let f = field_mut(v, name);
            f.data[4 * index..4 * index + 4].copy_from_slice(&x.to_le_bytes());
        })
    };
    let (e, text) = parse_err(set("rgb", 7, f32::NAN), "nan.bsdf");
    assert!(
        matches!(
            e,
            E::BadValue {
                field: "rgb",
                index: 7,
                ..
            }
        ) && text.contains("not a finite"),
        "{text}"
    );
    let (e, _) = parse_err(set("vndf", 3, -1.0), "negvndf.bsdf");
    assert!(matches!(
        e,
        E::BadValue {
            field: "vndf",
            index: 3,
            ..
        }
    ));
    let (e, _) = parse_err(set("sigma", 0, 0.0), "sigma0.bsdf");
    assert!(matches!(e, E::BadValue { field: "sigma", .. }));
    let (e, _) = parse_err(set("theta_i", 2, 0.3), "order.bsdf");
    assert!(matches!(
        e,
        E::BadValue {
            field: "theta_i",
            index: 2,
            ..
        }
    ));
    let (e, _) = parse_err(set("theta_i", 2, 2.0), "range.bsdf");
    assert!(matches!(
        e,
        E::BadValue {
            field: "theta_i",
            ..
        }
    ));
    let b = with(|v| field_mut(v, "jacobian").data = vec![2]);
    assert!(matches!(
        parse_err(b, "jac2.bsdf").0,
        E::BadValue {
            field: "jacobian",
            ..
        }
    ));
    // A VNDF slice that is zero everywhere has no inverse.
    let b = with(|v| {
        let f = field_mut(v, "vndf");
        let slice = 4 * VW * VH;
        f.data[slice..2 * slice].iter_mut().for_each(|x| *x = 0);
    });
    let (e, text) = parse_err(b, "zero.bsdf");
    assert!(
        matches!(e, E::BadValue { field: "vndf", .. }) && text.contains("slice 2"),
        "{text}"
    );
}

/// Seeded random corruption of the synthetic file: byte changes in the header, 64-bit
/// values overwritten, truncations. Parsing never panics; an error names the file; a file
/// that is accepted still evaluates to finite numbers.
#[test]
fn rgl_reader_fuzz() {
    use rand::Rng;
    let good = synthetic();
    let header = header_len(&synthetic_fields());
    let mut rng = common::rng(2018);
    let (mut refused, mut accepted) = (0, 0);
    for _ in 0..4000 {
        let mut b = good.clone();
        match rng.random_range(0..4) {
            0 => {
                let k = rng.random_range(0..header);
                b[k] = rng.random();
            }
            1 => {
                let k = rng.random_range(12..header - 8);
                let v: u64 = if rng.random_bool(0.5) {
                    rng.random()
                } else {
                    rng.random_range(0..2 * good.len() as u64)
                };
                b[k..k + 8].copy_from_slice(&v.to_le_bytes());
            }
            2 => {
                b.truncate(rng.random_range(0..good.len()));
            }
            _ => {
                for _ in 0..rng.random_range(1..6) {
                    let k = rng.random_range(0..b.len());
                    b[k] = rng.random();
                }
            }
        }
        match rgl::parse(b, Path::new("fuzz.bsdf")) {
            Err(e) => {
                assert!(e.to_string().contains("fuzz.bsdf"), "{e}");
                refused += 1;
            }
            Ok(bsdf) => {
                let f = bsdf.eval(dir(30.0, 10.0), dir(40.0, 200.0));
                assert!(f.iter().all(|x| x.is_finite()), "{f:?}");
                accepted += 1;
            }
        }
    }
    println!("fuzz: {refused} refused, {accepted} accepted");
    assert!(
        refused > 1000 && accepted > 100,
        "{refused} refused, {accepted} accepted"
    );
}

// ---------------------------------------------------------------------------------------
// Collections, tabulation and the commands.

use brdf_basis::collection::{Collection, MaterialData};
use brdf_basis::merl::{cell_directions, geometric_validity, N_CELLS};

/// Kind counts in a fixed order (the collection's order of kinds is its own business).
fn sorted(mut v: Vec<(&'static str, usize)>) -> Vec<(&'static str, usize)> {
    v.sort();
    v
}

fn rgl_of(m: &brdf_basis::collection::Material) -> &brdf_basis::rgl::RglMaterial {
    match &m.data {
        MaterialData::Rgl(r) => r,
        _ => panic!("{} is not an RGL material", m.name),
    }
}

/// The table of an RGL material is its evaluation at the cell centres (f32), -1 below the
/// horizon; `tabulate` writes it as a MERL `.binary` that reads back as the same table;
/// `info` counts it; a directory of `.bsdf` and `.binary` files is one collection.
#[test]
fn rgl_tabulation_round_trips_through_binary() {
    let d = common::tmp();
    let src = common::write(d.path(), "synth.bsdf", synthetic());
    let coll = Collection::load(&src).expect("load");
    assert_eq!(coll.names(), ["synth"]);
    let m = rgl_of(&coll.materials()[0]);
    let t = m.table();
    let valid = geometric_validity();
    use rand::Rng;
    let mut rng = common::rng(9);
    for _ in 0..5000 {
        let cell = rng.random_range(0..N_CELLS);
        let (wi, wo) = cell_directions(cell);
        let f = m.eval_dirs(wi, wo);
        for (c, &fc) in f.iter().enumerate() {
            let want = if valid[cell] {
                fc.max(0.0) as f32
            } else {
                -1.0
            };
            assert_eq!(t.value(c, cell), want, "cell {cell} channel {c}");
        }
    }
    assert_eq!(t.valid_count(), 1_096_216);
    let out = d.path().join("synth.binary");
    let o = common::bin_cpu()
        .arg("tabulate")
        .arg(&src)
        .args(["--material", "synth", "--out"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let back = brdf_basis::merl::read_binary(&out).expect("read back");
    assert!(
        back.rgb == t.rgb,
        "the .binary reads back as the same table"
    );
    // The written file and the .bsdf side by side in a directory: two materials, one of
    // each kind, sorted by name; info counts them.
    std::fs::rename(&out, d.path().join("tabulated.binary")).expect("rename");
    let dir_coll = Collection::load(d.path()).expect("directory");
    assert_eq!(dir_coll.names(), ["synth", "tabulated"]);
    assert_eq!(
        sorted(dir_coll.kind_counts()),
        [("MERL table", 1), ("RGL-EPFL", 1)]
    );
    let o = common::bin_cpu()
        .arg("info")
        .arg(d.path())
        .output()
        .expect("info");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("collection: 2 materials (")
            && text.contains("1 RGL-EPFL")
            && text.contains("1 MERL table")
            && text.contains(
                "synth (RGL-EPFL: synthetic): 4 x 4 tables, 3 incident elevations; 0 valid cells"
            ),
        "{text}"
    );
    // A malformed .bsdf in a directory: the error names it.
    common::write(d.path(), "bad.bsdf", &synthetic()[..100]);
    let o = common::bin_cpu()
        .arg("info")
        .arg(d.path())
        .output()
        .expect("info");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("bad.bsdf") && err.contains("truncated"),
        "{err}"
    );
}

/// Analytic rows of the mixed collection (from the embedded default).
const ANALYTIC: &str = "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n\
gloss-white-enamel,0.896269,0.896269,0.887923,1,1,1,0.04,2220.22\n\
satin-green-paint,0.0612461,0.296138,0.0666259,1,1,1,0.04,198\n\
polished-gold,0,0,0,1.19723,0.990746,0.510915,0.798947,8886.89\n";

/// Runs the binary with `args` on `backend`, asserting success.
fn run(backend: &str, args: &[std::ffi::OsString]) -> std::process::Output {
    let o = common::bin()
        .args(["--quiet", "--backend", backend])
        .args(args)
        .output()
        .expect("run");
    assert!(
        o.status.success(),
        "{backend} {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).expect("read")).expect("json")
}

/// The four RGL files with three analytic rows: distance (against an f64 recomputation
/// from the tables and the analytic model), select, fit and render, on the CPU and on
/// the GPU back-end (lavapipe) when there is an adapter, which must agree.
#[test]
fn rgl_mixed_collection_end_to_end() {
    const TEST: &str = "rgl_mixed_collection_end_to_end";
    let mut paths = Vec::new();
    for stem in FILES {
        let Some(p) = rgl_path(stem, TEST) else {
            return;
        };
        paths.push(p);
    }
    let d = common::tmp();
    let csv = common::write(d.path(), "analytic.csv", ANALYTIC);
    paths.push(csv);
    let coll = Collection::load_many(&paths).expect("collection");
    assert_eq!(
        sorted(coll.kind_counts()),
        [("RGL-EPFL", 4), ("analytic", 3)]
    );
    let backends: Vec<&str> = if common::gpu(TEST).is_some() {
        vec!["cpu", "gpu"]
    } else {
        vec!["cpu"]
    };
    let args = |extra: &[&str], out: &[(&str, &Path)]| -> Vec<std::ffi::OsString> {
        let mut v: Vec<std::ffi::OsString> = Vec::new();
        v.push(extra[0].into());
        v.extend(paths.iter().map(|p| p.clone().into_os_string()));
        v.extend(extra[1..].iter().map(|s| s.into()));
        for (flag, p) in out {
            v.push(flag.into());
            v.push(p.as_os_str().to_owned());
        }
        v
    };

    // The f64 reference of BRDF_it on the full lobe (SPEC 4, 9): evaluation mask, uniform
    // weights, restricted to cells valid in every table.
    let cs = brdf_basis::merl::CellSet::for_collection(
        &coll,
        brdf_basis::merl::Mask::Evaluation,
        brdf_basis::merl::Weighting::Uniform,
        std::num::NonZeroUsize::MIN,
    );
    let lobes: Vec<Vec<f64>> = coll
        .materials()
        .iter()
        .map(|m| {
            cs.cells
                .iter()
                .map(|&c| match &m.data {
                    MaterialData::Rgl(r) => {
                        (0..3)
                            .map(|k| r.table().value(k, c as usize) as f64)
                            .sum::<f64>()
                            / 3.0
                    }
                    MaterialData::Analytic(a) => {
                        let (wi, wo) = cell_directions(c as usize);
                        a.eval(wi, wo).iter().sum::<f64>() / 3.0
                    }
                    _ => unreachable!(),
                })
                .collect()
        })
        .collect();
    let n = coll.len();
    let wsum: f64 = cs.weights.iter().sum();
    let mut reference = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            reference[i * n + j] = cs
                .weights
                .iter()
                .zip(lobes[i].iter().zip(&lobes[j]))
                .map(|(w, (a, b))| w * (a - b).abs())
                .sum::<f64>()
                / wsum;
        }
    }

    let mut fits = Vec::new();
    let mut bases = Vec::new();
    for backend in &backends {
        let npy = d.path().join(format!("d-{backend}.npy"));
        run(backend, &(args(&["distance"], &[("--out", &npy)])));
        let m = brdf_basis::io::saved::load_saved_matrix(&npy)
            .expect("matrix")
            .matrix;
        assert_eq!(m.names(), coll.names().as_slice());
        let rel = common::max_rel(m.as_full(), &reference, 1e-12);
        assert!(rel <= 1e-4, "{backend}: distance vs f64 reference: {rel:e}");

        let sel = d.path().join(format!("s-{backend}.json"));
        run(
            backend,
            &(args(
                &["select", "--method", "kmedoids", "-k", "2"],
                &[("--json", &sel)],
            )),
        );
        let v = json(&sel);
        assert_eq!(
            v["best"]["medoids"].as_array().map(Vec::len),
            Some(2),
            "{v}"
        );
        let greedy = d.path().join(format!("g-{backend}.json"));
        run(
            backend,
            &(args(
                &["select", "--method", "greedy", "-k", "2"],
                &[("--json", &greedy)],
            )),
        );
        bases.push(json(&greedy)["basis"].clone());

        let fit = d.path().join(format!("f-{backend}.json"));
        run(
            backend,
            &(args(
                &[
                    "fit",
                    "--basis",
                    "paper_white_rgb,polished-gold",
                    "--all-others",
                ],
                &[("--json", &fit)],
            )),
        );
        fits.push(json(&fit));
    }
    if fits.len() == 2 {
        assert_eq!(bases[0], bases[1], "greedy bases: CPU and GPU agree");
        let (a, b) = (&fits[0]["targets"], &fits[1]["targets"]);
        for (ta, tb) in a
            .as_array()
            .expect("targets")
            .iter()
            .zip(b.as_array().expect("targets"))
        {
            let (ma, mb) = (
                ta["mae"].as_f64().expect("mae"),
                tb["mae"].as_f64().expect("mae"),
            );
            assert!(
                (ma - mb).abs() <= 1e-4 * ma.max(1e-6),
                "{}: mae {ma} vs {mb}",
                ta["material"]
            );
        }
    }
    let targets = fits[0]["targets"].as_array().expect("targets");
    assert_eq!(targets.len(), n - 2);
    assert!(targets
        .iter()
        .all(|t| t["mae"].as_f64().is_some_and(f64::is_finite)));

    // Render: each pixel is the exact evaluation in a frame of our own (the BSDF depends
    // only on the two elevations and the relative azimuth), times cos theta_i.
    let exr = d.path().join("sunflower.exr");
    run(
        "cpu",
        &(args(
            &["render", "--material", "cg_sunflower_rgb", "--size", "33"],
            &[("--out", &exr)],
        )),
    );
    let img = brdf_basis::io::image::read_exr(&exr).expect("exr");
    let m = rgl_of(coll.get("cg_sunflower_rgb").expect("material"));
    let light = brdf_basis::eval::render::light_direction(45.0, 45.0);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut lit = 0;
    for row in 0..33u32 {
        for col in 0..33u32 {
            let (x, y) = brdf_basis::eval::render::pixel_centre(col, row, 33, 33);
            let r2 = x * x + y * y;
            let px = &img.data[3 * (row * 33 + col) as usize..][..3];
            let nrm = [x, y, (1.0 - r2).max(0.0).sqrt()];
            let cos_i = dot(nrm, light);
            if r2 >= 1.0 || cos_i <= 0.0 {
                assert_eq!(px, [0.0; 3]);
                continue;
            }
            // Local frame: z = n, x along the light's tangential part.
            let cos_o = nrm[2];
            let t = [
                light[0] - cos_i * nrm[0],
                light[1] - cos_i * nrm[1],
                light[2] - cos_i * nrm[2],
            ];
            let tl = dot(t, t).sqrt();
            let (wi, wo) = if tl < 1e-9 {
                ([0.0, 0.0, 1.0], [(1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o])
            } else {
                let tx = [t[0] / tl, t[1] / tl, t[2] / tl];
                let ty = [
                    nrm[1] * tx[2] - nrm[2] * tx[1],
                    nrm[2] * tx[0] - nrm[0] * tx[2],
                    nrm[0] * tx[1] - nrm[1] * tx[0],
                ];
                let v = [0.0, 0.0, 1.0];
                ([tl, 0.0, cos_i], [dot(v, tx), dot(v, ty), cos_o])
            };
            let f = m.eval_dirs(wi, wo);
            for c in 0..3 {
                let want = (f[c].max(0.0) * cos_i) as f32;
                assert!(
                    (px[c] - want).abs() <= 1e-4 * want.abs().max(1e-3),
                    "pixel ({col}, {row}) channel {c}: {} vs {want}",
                    px[c]
                );
            }
            lit += 1;
        }
    }
    assert!(lit > 300, "{lit} lit pixels");
}
