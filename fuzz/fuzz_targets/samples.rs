//! Fuzzes the samples reader of `fit --samples` (SPEC 10): any bytes, read as a CSV or
//! (first byte odd) an ASTM E1392 file, give samples or a clear error, never a panic;
//! every accepted sample has unit directions above the horizon, a finite reflectance in
//! range and positive finite sigmas.
#![no_main]
use brdf_basis::acquire::{parse_samples, MAX_VALUE};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else {
        return;
    };
    let name = if kind % 2 == 1 { "fuzz.astm" } else { "fuzz.csv" };
    if let Ok(s) = parse_samples(bytes, std::path::Path::new(name)) {
        assert!(!s.is_empty());
        for x in &s {
            for d in [x.wi, x.wo] {
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                assert!((n - 1.0).abs() < 1e-9 && d[2] > 0.0, "{d:?}");
            }
            assert!(x.rgb.iter().all(|v| v.is_finite() && (0.0..=MAX_VALUE).contains(v)));
            if let Some(sigma) = x.sigma {
                assert!(sigma.iter().all(|v| v.is_finite() && *v > 0.0));
            }
            assert!(x.line >= 1);
        }
    }
});
