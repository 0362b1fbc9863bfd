//! The command line, run as a user would.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::collection::Collection;
use brdf_basis::distance::{distance_matrix, DistanceParams};
use brdf_basis::io::saved::load_saved_matrix;
use brdf_basis::merl::{cell_directions, cell_info, N_CELLS, N_PD, N_TD, N_TH};
use brdf_basis::merl::{read_binary, FILE_BYTES, SCALE};

fn backend_flag() -> &'static str {
    if gpu("cli backend").is_some() {
        "gpu"
    } else {
        "cpu"
    }
}

#[test]
fn tabulate_gold_metallic_paint_writes_a_merl_file_equal_to_the_model() {
    const TEST: &str = "tabulate_gold_metallic_paint_writes_a_merl_file_equal_to_the_model";
    let Some(csv) = shared_or_skip("ngan2005_ashikhmin_shirley.csv", TEST) else {
        return;
    };
    let ngan = Collection::load(&csv).expect("ngan");
    let dir = tmp();
    let out = dir.path().join("g.binary");
    let st = bin_quiet()
        .args(["--backend", backend_flag(), "tabulate"])
        .arg(&csv)
        .args(["--material", "gold-metallic-paint", "--out"])
        .arg(&out)
        .status()
        .expect("run");
    assert!(st.success());
    // A MERL file: three i32 dimensions, then 3 channels x f64 per (theta_h, theta_d,
    // phi_d) cell.
    let want = 3 * 4 + 3 * 8 * N_TH * N_TD * N_PD;
    assert_eq!(FILE_BYTES as usize, want);
    assert_eq!(std::fs::metadata(&out).expect("meta").len() as usize, want);
    let head = std::fs::read(&out).expect("raw");
    let dims: Vec<i32> = head[..12]
        .chunks(4)
        .map(|b| i32::from_le_bytes(b.try_into().expect("4 bytes")))
        .collect();
    assert_eq!(dims, [N_TH as i32, N_TD as i32, N_PD as i32]);
    let t = read_binary(&out).expect("read back");
    // Written again from what was read: byte-identical.
    let again = dir.path().join("again.binary");
    brdf_basis::merl::write_binary(&again, &t.rgb).expect("write");
    assert_eq!(
        std::fs::read(&out).expect("a"),
        std::fs::read(&again).expect("b")
    );
    // Equal to the f64 model within f32 rounding (plus the GPU's 1e-4 where it is used).
    let m = *ngan
        .get("gold-metallic-paint")
        .expect("gold")
        .analytic()
        .expect("analytic");
    let raw = std::fs::read(&out).expect("raw");
    let mut worst = 0f64;
    for cell in (0..N_CELLS).step_by(11) {
        let valid = cell_info(cell).valid;
        let (wi, wo) = cell_directions(cell);
        let f = m.eval(wi, wo);
        for c in 0..3 {
            let o = 12 + 8 * (c * N_CELLS + cell);
            let stored = f64::from_le_bytes(raw[o..o + 8].try_into().expect("8 bytes"));
            if !valid {
                assert_eq!(stored, -1.0);
                continue;
            }
            let rel = (stored * SCALE[c] - f[c]).abs() / f[c];
            worst = worst.max(rel);
            assert!(
                rel <= 1e-4,
                "cell {cell} channel {c}: {} vs {}",
                stored * SCALE[c],
                f[c]
            );
        }
    }
    eprintln!("tabulate: worst relative error {worst:e}");
}

#[test]
fn info_names_the_adapter_backend_and_limits() {
    let out = bin_quiet().args(["info"]).output().expect("run");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("backend:") && text.contains("cpu back-end:"),
        "{text}"
    );
    if gpu("info_names_the_adapter").is_some() {
        assert!(
            text.contains("adapter: ") && text.contains("max_storage_buffer_binding_size"),
            "{text}"
        );
    }
}

#[test]
fn distance_on_the_embedded_default_writes_csv_and_npy() {
    // Both files hold the library's matrix of the embedded collection, bit for bit, under
    // its names.
    let coll = Collection::embedded_default();
    let p = DistanceParams::default()
        .stride(4)
        .check(&coll)
        .expect("params");
    let want = distance_matrix(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("distances");
    let dir = tmp();
    for ext in ["csv", "npy"] {
        let out = dir.path().join(format!("d.{ext}"));
        let st = bin_quiet()
            .args(["--backend", "cpu", "distance", "--stride", "4", "--out"])
            .arg(&out)
            .status()
            .expect("run");
        assert!(st.success());
        let got = load_saved_matrix(&out)
            .unwrap_or_else(|e| panic!("{ext}: {e}"))
            .matrix;
        assert_eq!(got.names(), coll.names(), "{ext}: names");
        assert_eq!(got.as_full(), want.as_full(), "{ext}: values");
    }
}

#[test]
fn errors_name_the_problem_and_exit_non_zero() {
    let dir = tmp();
    let bad = dir.path().join("bad.csv");
    std::fs::write(
        &bad,
        "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nx,0,0,0,0,0,0,1.5,3\n",
    )
    .expect("write");
    let out = bin_quiet()
        .args(["distance"])
        .arg(&bad)
        .args(["--out", "x.csv"])
        .output()
        .expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.csv") && err.contains("line 2") && err.contains("F0"),
        "{err}"
    );
    let out = bin_quiet()
        .args(["tabulate", "--material", "nope", "--out"])
        .arg(dir.path().join("n.binary"))
        .output()
        .expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no material named `nope`"));
    assert!(
        !dir.path().join("n.binary").exists(),
        "nothing half-written"
    );
    let x = dir.path().join("x.csv");
    let out = bin_quiet()
        .args(["distance", "--metric", "cosine", "--out"])
        .arg(&x)
        .output()
        .expect("run");
    assert_eq!(out.status.code(), Some(2), "a usage error");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown metric `cosine`")
            && err.contains("brdf-it")
            && err.contains("euclidean"),
        "{err}"
    );
    assert!(!x.exists(), "nothing written");
}
