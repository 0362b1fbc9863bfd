//! Shared test helpers.

use brdf_basis::collection::Collection;
use brdf_basis::gpu::GpuBackend;
use std::path::PathBuf;
use std::sync::OnceLock;

/// `../shared/data/<name>` beside the repository.
pub fn shared(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name)
}

/// The Ngan et al. 2005 Ashikhmin-Shirley table (100 materials).
pub fn ngan() -> Collection {
    Collection::load(&shared("ngan2005_ashikhmin_shirley.csv"))
        .expect("../shared/data/ngan2005_ashikhmin_shirley.csv")
}

/// The GPU back-end, opened once; `None` (after printing SKIP) when there is no adapter,
/// a panic when `BRDF_BASIS_REQUIRE_GPU=1`.
pub fn gpu(test: &str) -> Option<&'static GpuBackend> {
    static GPU: OnceLock<Result<GpuBackend, String>> = OnceLock::new();
    match GPU.get_or_init(|| GpuBackend::new().map_err(|e| e.to_string())) {
        Ok(g) => Some(g),
        Err(e) => {
            if std::env::var("BRDF_BASIS_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("BRDF_BASIS_REQUIRE_GPU=1 but no GPU adapter: {e}");
            }
            eprintln!("SKIP (no adapter) {test}: {e}");
            None
        }
    }
}

/// Largest relative difference `|a - b| / max(|b|, floor)` over pairs.
pub fn max_rel(a: &[f64], b: &[f64], floor: f64) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(floor))
        .fold(0.0, f64::max)
}

/// The one seeded generator of all test randomness (ChaCha8, as the library's seeded
/// steps): the same seed gives the same numbers on every platform.
pub fn rng(seed: u64) -> rand_chacha::ChaCha8Rng {
    rand::SeedableRng::seed_from_u64(seed)
}

/// A temporary directory.
pub fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}
