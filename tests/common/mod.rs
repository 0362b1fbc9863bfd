//! Shared test helpers: the library's tests (tests/main.rs) and the command line's
//! (crates/cli/tests, which add the binary's helpers) both use this file.

use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::gpu::GpuBackend;
use brdf_basis::backend::Backend;
use brdf_basis::backend::Lobe;
use brdf_basis::collection::Collection;
use brdf_basis::collection::{Material, MaterialData};
use brdf_basis::fit::channel_lobe;
use brdf_basis::merl::MerlTable;
use brdf_basis::merl::{cell_info, N_CELLS};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The repository's root (the directory of the workspace's `Cargo.lock`), from the
/// package under test, the root package or crates/cli.
pub(crate) fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .expect("the workspace root above CARGO_MANIFEST_DIR")
}

/// `../shared/data/<name>` beside the repository.
fn shared(name: &str) -> PathBuf {
    repo().join("../shared/data").join(name)
}

/// Writes `line` to the process's standard error directly, past the test harness's
/// capture of `eprintln!`, so that a SKIP shows in a plain `cargo test` run.
fn visible(line: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "{line}");
}

/// `../shared/data/<name>` when it exists. When it does not, prints `SKIP (no shared
/// data) <test>: <path>` and returns `None`, so the README's test command passes on a
/// clone that has only the repository; with `BRDF_BASIS_REQUIRE_SHARED=1` (set by
/// `.ci/run`) a missing file is a failure instead.
pub(crate) fn shared_or_skip(name: &str, test: &str) -> Option<PathBuf> {
    let p = shared(name);
    if p.exists() {
        return Some(p);
    }
    if std::env::var("BRDF_BASIS_REQUIRE_SHARED").is_ok_and(|v| v == "1") {
        panic!(
            "BRDF_BASIS_REQUIRE_SHARED=1 but the shared data file {} is missing ({test})",
            p.display()
        );
    }
    visible(&format!(
        "SKIP (no shared data) {test}: {} is missing",
        p.display()
    ));
    None
}

/// The Ngan et al. 2005 Ashikhmin-Shirley table (100 materials), or `None` after
/// printing SKIP when `../shared` is absent (see [`shared_or_skip`]).
pub(crate) fn ngan_or_skip(test: &str) -> Option<Collection> {
    let p = shared_or_skip("ngan2005_ashikhmin_shirley.csv", test)?;
    Some(Collection::load(&p).expect("../shared/data/ngan2005_ashikhmin_shirley.csv"))
}

/// Writes `bytes` to `dir/name` and returns the path.
pub(crate) fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write");
    p
}

/// A measured copy of `lobe`: its f32 CPU tabulation on every cell, the same table in all
/// three channels, read through `channel`.
pub(crate) fn measured_lobe(lobe: &Lobe, channel: Option<usize>) -> Lobe {
    let all: Vec<u32> = (0..N_CELLS as u32).collect();
    let table = CpuBackend::new()
        .tabulate(std::slice::from_ref(lobe), &all)
        .expect("tab");
    Lobe::Measured {
        table: std::sync::Arc::new(MerlTable {
            rgb: [table.clone(), table.clone(), table].concat(),
        }),
        channel,
    }
}

/// A measured copy of an analytic material: its f64 values rounded to f32 in every valid
/// cell, -1 elsewhere.
pub(crate) fn measured_material(m: &Material) -> Material {
    let cpu = CpuBackend::new();
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let mut rgb = vec![-1f32; 3 * N_CELLS];
    for c in 0..3 {
        let v = cpu.values_f64(&channel_lobe(&m.data, c), &cells);
        for (cell, x) in v.into_iter().enumerate() {
            if cell_info(cell).valid {
                rgb[c * N_CELLS + cell] = x as f32;
            }
        }
    }
    Material {
        name: m.name.clone(),
        data: MaterialData::Measured(std::sync::Arc::new(MerlTable { rgb })),
        origin: "measured copy".into(),
    }
}

/// The GPU back-end, opened once; `None` (after printing SKIP) when there is no adapter,
/// a panic when `BRDF_BASIS_REQUIRE_GPU=1`.
pub(crate) fn gpu(test: &str) -> Option<&'static GpuBackend> {
    static GPU: OnceLock<Result<GpuBackend, String>> = OnceLock::new();
    match GPU.get_or_init(|| GpuBackend::new().map_err(|e| e.to_string())) {
        Ok(g) => Some(g),
        Err(e) => {
            if std::env::var("BRDF_BASIS_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("BRDF_BASIS_REQUIRE_GPU=1 but no GPU adapter: {e}");
            }
            visible(&format!("SKIP (no adapter) {test}: {e}"));
            None
        }
    }
}

/// Largest relative difference `|a - b| / max(|b|, floor)` over pairs.
pub(crate) fn max_rel(a: &[f64], b: &[f64], floor: f64) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(floor))
        .fold(0.0, f64::max)
}

/// The one seeded generator of all test randomness (ChaCha8, as the library's seeded
/// steps): the same seed gives the same numbers on every platform.
pub(crate) fn rng(seed: u64) -> rand_chacha::ChaCha8Rng {
    rand::SeedableRng::seed_from_u64(seed)
}

/// A temporary directory.
pub(crate) fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// A little-endian float32 C-order `.npy` file (format 1.0 or 2.0): its shape and values
/// (a parser of the tests' own, independent of the crate's readers).
pub(crate) fn read_f32_npy(path: &Path) -> (Vec<usize>, Vec<f32>) {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&b[..6], b"\x93NUMPY", "{}", path.display());
    let (hlen, start) = match b[6] {
        1 => (u16::from_le_bytes([b[8], b[9]]) as usize, 10),
        _ => (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12),
    };
    let header = std::str::from_utf8(&b[start..start + hlen]).expect("ASCII header");
    assert!(header.contains("'<f4'"), "{}: {header}", path.display());
    assert!(header.contains("'fortran_order': False"), "{header}");
    let shape_str = header
        .split("'shape':")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .expect("shape");
    let shape: Vec<usize> = shape_str
        .trim_start_matches([' ', '('])
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let data: Vec<f32> = b[start + hlen..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(
        data.len(),
        shape.iter().product::<usize>(),
        "{}",
        path.display()
    );
    (shape, data)
}

/// SPEC 9's accuracy record of tabulated neural values against the f64 network: the
/// worst relative error where the reference exceeds 1e-3 (SPEC 9: 5e-4), the worst
/// absolute error at or below it (1e-6), where each occurred, and the values outside SPEC
/// 9 (the first kept).
#[derive(Clone, Debug, Default)]
pub(crate) struct Spec9 {
    /// Values compared.
    pub n: usize,
    /// Worst relative error (reference > 1e-3) and where: (error, label, got, want).
    pub rel: (f64, String, f64, f64),
    /// Worst absolute error (reference <= 1e-3) and where.
    pub abs: (f64, String, f64, f64),
    /// Values outside SPEC 9.
    pub bad: usize,
    /// The first value outside SPEC 9.
    pub first_bad: Option<(String, f64, f64)>,
}

impl Spec9 {
    /// Records a tabulated value `got` against its f64 reference `want` (both as
    /// tabulated: clamped at 0); `label` names it (material, channel, cell), built only
    /// when needed.
    pub(crate) fn add(&mut self, got: f64, want: f64, label: impl Fn() -> String) {
        self.n += 1;
        let e = (got - want).abs();
        let (worst, tol) = if want.abs() > 1e-3 {
            (&mut self.rel, 5e-4 * want.abs())
        } else {
            (&mut self.abs, 1e-6)
        };
        let err = if want.abs() > 1e-3 { e / want.abs() } else { e };
        if err > worst.0 {
            *worst = (err, label(), got, want);
        }
        if e.is_nan() || e > tol {
            self.bad += 1;
            if self.first_bad.is_none() {
                self.first_bad = Some((label(), got, want));
            }
        }
    }

    /// Both records as one.
    pub(crate) fn merge(mut self, o: Spec9) -> Spec9 {
        self.n += o.n;
        self.bad += o.bad;
        if o.rel.0 > self.rel.0 {
            self.rel = o.rel;
        }
        if o.abs.0 > self.abs.0 {
            self.abs = o.abs;
        }
        if self.first_bad.is_none() {
            self.first_bad = o.first_bad;
        }
        self
    }

    /// One line: the worst errors and where.
    pub(crate) fn report(&self) -> String {
        format!(
            "{} values: worst relative error {:.3e} (values > 1e-3; {}: {:.7e} vs f64 {:.7e}), \
             worst absolute error {:.3e} (values <= 1e-3; {}: {:.4e} vs {:.4e}); {} outside \
             SPEC 9",
            self.n,
            self.rel.0,
            self.rel.1,
            self.rel.2,
            self.rel.3,
            self.abs.0,
            self.abs.1,
            self.abs.2,
            self.abs.3,
            self.bad
        )
    }
}

/// The exact optimum of `min sum_s W_s (sum_j x_j a_j(s) - b_s)^2, x >= 0` by enumerating
/// every set of free columns (m <= 5): the unconstrained least squares on the set (normal
/// equations in f64, Gaussian elimination with partial pivoting), kept when feasible. An
/// active-set method's optimum is one of these; the smallest objective wins.
pub(crate) fn brute_force_nnls(cols: &[Vec<f64>], b: &[f64], w: &[f64]) -> f64 {
    let m = cols.len();
    let obj = |x: &[f64]| -> f64 {
        (0..b.len())
            .map(|s| {
                let r: f64 = (0..m).map(|j| x[j] * cols[j][s]).sum::<f64>() - b[s];
                w[s] * r * r
            })
            .sum()
    };
    let mut best = obj(&vec![0.0; m]);
    for set in 1u32..(1 << m) {
        let free: Vec<usize> = (0..m).filter(|j| set & (1 << j) != 0).collect();
        let p = free.len();
        let mut a = vec![vec![0.0; p + 1]; p];
        for (r, &i) in free.iter().enumerate() {
            for (c, &j) in free.iter().enumerate() {
                a[r][c] = (0..b.len()).map(|s| w[s] * cols[i][s] * cols[j][s]).sum();
            }
            a[r][p] = (0..b.len()).map(|s| w[s] * cols[i][s] * b[s]).sum();
        }
        // Gaussian elimination.
        let mut ok = true;
        for k in 0..p {
            let piv = (k..p)
                .max_by(|&x, &y| a[x][k].abs().total_cmp(&a[y][k].abs()))
                .unwrap();
            a.swap(k, piv);
            if a[k][k].abs() < 1e-300 {
                ok = false;
                break;
            }
            let pivot = a[k].clone();
            for (r, row) in a.iter_mut().enumerate() {
                if r != k {
                    let f = row[k] / pivot[k];
                    for (v, pv) in row[k..].iter_mut().zip(&pivot[k..]) {
                        *v -= f * pv;
                    }
                }
            }
        }
        if !ok {
            continue;
        }
        let mut x = vec![0.0; m];
        for (r, &i) in free.iter().enumerate() {
            x[i] = a[r][p] / a[r][r];
        }
        if x.iter().all(|&v| v >= 0.0) {
            best = best.min(obj(&x));
        }
    }
    best
}
