//! Fuzzes the analytic CSV loader: any bytes give a collection or a clear error, never a
//! panic; every accepted material satisfies SPEC 1.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(c) = brdf_basis::collection::parse_csv(data, std::path::Path::new("fuzz.csv")) {
        for m in c.materials() {
            let a = m.analytic().expect("CSV materials are analytic");
            assert!(a.d.iter().chain(&a.s).all(|v| v.is_finite() && *v >= 0.0));
            assert!((0.0..=1.0).contains(&a.f0) && a.n > 0.0 && a.n.is_finite());
        }
    }
});
