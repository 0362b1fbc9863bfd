//! Measured MERL data: malformed files (each its own clear error), directory and mixed
//! collections, and synthetic measured materials that must behave like their analytic
//! originals.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::backend::weighted::TargetWeight;
use brdf_basis::backend::{Backend, Lobe};
use brdf_basis::collection::{Collection, MaterialData};
use brdf_basis::error::{CollectionError, MerlError};
use brdf_basis::merl::{cell_info, flat, N_CELLS};
use brdf_basis::merl::{read_binary, write_binary, FILE_BYTES};
use std::path::{Path, PathBuf};

/// A valid file's bytes: constant reflectance 0.25 in every valid cell, -1 elsewhere.
fn valid_bytes() -> Vec<u8> {
    let mut b = Vec::with_capacity(FILE_BYTES as usize);
    for d in [90i32, 90, 180] {
        b.extend_from_slice(&d.to_le_bytes());
    }
    for c in 0..3 {
        let scale = brdf_basis::merl::SCALE[c];
        for cell in 0..N_CELLS {
            let v = if cell_info(cell).valid {
                0.25 / scale
            } else {
                -1.0
            };
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

fn set_value(b: &mut [u8], channel: usize, cell: usize, v: f64) {
    let o = 12 + 8 * (channel * N_CELLS + cell);
    b[o..o + 8].copy_from_slice(&v.to_le_bytes());
}

fn err(bytes: &[u8], name: &str) -> (MerlError, String) {
    let d = tmp();
    let p = write(d.path(), name, bytes);
    let e = read_binary(&p).expect_err("malformed");
    let text = e.to_string();
    assert!(text.contains(name), "the error names the file: {text}");
    (e, text)
}

#[test]
fn reads_a_valid_file() {
    let d = tmp();
    let p = write(d.path(), "ok.binary", valid_bytes());
    let t = read_binary(&p).expect("valid");
    assert_eq!(t.valid_count(), 1_096_216);
    let c = flat(10, 20, 30);
    assert!((t.value(1, c) - 0.25).abs() < 1e-7);
}

#[test]
fn malformed_empty_file() {
    assert!(matches!(
        err(&[], "empty.binary").0,
        MerlError::Size { found: 0, .. }
    ));
}

#[test]
fn malformed_header_only() {
    let b = valid_bytes();
    assert!(matches!(
        err(&b[..12], "head.binary").0,
        MerlError::Size { found: 12, .. }
    ));
}

#[test]
fn malformed_truncated_data() {
    let b = valid_bytes();
    let (e, text) = err(&b[..b.len() / 2], "half.binary");
    assert!(
        matches!(e, MerlError::Size { .. }) && text.contains("34992012"),
        "{text}"
    );
}

#[test]
fn malformed_trailing_bytes() {
    let mut b = valid_bytes();
    b.extend_from_slice(&[0; 8]);
    assert!(matches!(err(&b, "long.binary").0, MerlError::Size { .. }));
}

#[test]
fn malformed_wrong_dims() {
    let mut b = valid_bytes();
    b[8..12].copy_from_slice(&90i32.to_le_bytes());
    let (e, text) = err(&b, "dims.binary");
    assert!(
        matches!(
            e,
            MerlError::Dims {
                dims: [90, 90, 90],
                ..
            }
        ) && text.contains("(90, 90, 90)"),
        "{text}"
    );
}

#[test]
fn malformed_negative_dims() {
    let mut b = valid_bytes();
    b[0..4].copy_from_slice(&(-90i32).to_le_bytes());
    assert!(matches!(err(&b, "neg.binary").0, MerlError::Dims { .. }));
}

#[test]
fn malformed_nan_value() {
    let mut b = valid_bytes();
    set_value(&mut b, 1, 777, f64::NAN);
    let (e, text) = err(&b, "nan.binary");
    assert!(
        matches!(
            e,
            MerlError::BadValue {
                channel: 1,
                index,
                cell: [0, 4, 57],
                ..
            } if index == N_CELLS + 777
        ),
        "{text}"
    );
}

#[test]
fn malformed_infinite_value() {
    let mut b = valid_bytes();
    set_value(&mut b, 2, 12345, f64::INFINITY);
    assert!(matches!(
        err(&b, "inf.binary").0,
        MerlError::BadValue {
            channel: 2,
            cell: [0, 68, 105],
            ..
        }
    ));
}

#[test]
fn malformed_all_negative() {
    let mut b = valid_bytes();
    for c in 0..3 {
        for cell in 0..N_CELLS {
            set_value(&mut b, c, cell, -1.0);
        }
    }
    assert!(matches!(
        err(&b, "neg-all.binary").0,
        MerlError::NoValidCell { .. }
    ));
}

#[test]
fn malformed_values_only_below_the_horizon() {
    // Positive values only in cells whose directions are below the horizon: no valid cell.
    let mut b = valid_bytes();
    for c in 0..3 {
        for cell in 0..N_CELLS {
            set_value(
                &mut b,
                c,
                cell,
                if cell_info(cell).valid { -1.0 } else { 1.0 },
            );
        }
    }
    assert!(matches!(
        err(&b, "horizon.binary").0,
        MerlError::NoValidCell { .. }
    ));
}

#[test]
fn malformed_missing_file() {
    let e = read_binary(Path::new("/nonexistent/none.binary"))
        .expect_err("missing")
        .to_string();
    assert!(e.contains("/nonexistent/none.binary"), "{e}");
}

#[test]
fn negative_cells_become_invalid_not_zero() {
    let mut b = valid_bytes();
    let c = flat(5, 6, 7);
    set_value(&mut b, 0, c, -3.0);
    let d = tmp();
    let t = read_binary(&write(d.path(), "hole.binary", &b)).expect("valid");
    assert!(!t.is_valid(c));
    for ch in 0..3 {
        assert!(
            t.value(ch, c) < 0.0,
            "every channel of the cell is marked invalid"
        );
    }
    assert_eq!(t.valid_count(), 1_096_216 - 1);
}

#[test]
fn directory_collections_are_sorted_and_mixed_with_csv() {
    let d = tmp();
    let dir = d.path().join("merl");
    std::fs::create_dir(&dir).expect("mkdir");
    let b = valid_bytes();
    write(&dir, "zeta.binary", &b);
    write(&dir, "alpha.binary", &b);
    write(&dir, "notes.txt", b"ignored");
    let c = Collection::load(&dir).expect("dir");
    assert_eq!(c.names(), vec!["alpha".to_string(), "zeta".to_string()]);
    let csv = d.path().join("a.csv");
    std::fs::write(
        &csv,
        "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nbeta,0.1,0.1,0.1,0.5,0.5,0.5,0.1,30\n",
    )
    .expect("csv");
    let mixed = Collection::load_many(&[csv.clone(), dir.clone(), dir.join("alpha.binary")]);
    let e = mixed.expect_err("alpha twice").to_string();
    assert!(e.contains("duplicate material name `alpha`"), "{e}");
    let mixed = Collection::load_many(&[csv, dir]).expect("mixed");
    assert_eq!(
        mixed.names(),
        vec!["beta".to_string(), "alpha".to_string(), "zeta".to_string()]
    );
    let empty = d.path().join("empty");
    std::fs::create_dir(&empty).expect("mkdir");
    assert!(matches!(
        Collection::load(&empty),
        Err(CollectionError::EmptyDir { .. })
    ));
}

/// Writes `names` of the Ngan table as measured files (f32 tabulation on the CPU), with
/// optional multiplicative noise and a masked theta_d row; returns the directory.
fn synthetic(
    c: &Collection,
    dir: &Path,
    names: &[&str],
    noise: f64,
    mask_row: Option<usize>,
) -> PathBuf {
    let out = dir.join("measured");
    std::fs::create_dir_all(&out).expect("mkdir");
    let cells: Vec<u32> = (0..N_CELLS as u32).collect();
    let cpu = CpuBackend::new();
    let mut rng = rng(0x1234_5678);
    for n in names {
        let m = c.get(n).expect("name");
        let lobes: Vec<Lobe> = (0..3)
            .map(|ch| brdf_basis::fit::channel_lobe(&m.data, ch))
            .collect();
        let mut rgb = cpu.tabulate(&lobes, &cells).expect("tab");
        for cell in 0..N_CELLS {
            let masked = mask_row.is_some_and(|j| brdf_basis::merl::unflat(cell).1 == j);
            for ch in 0..3 {
                let v = &mut rgb[ch * N_CELLS + cell];
                if !cell_info(cell).valid || masked {
                    *v = -1.0;
                } else if noise > 0.0 {
                    let u = rand::Rng::random::<f64>(&mut rng) - 0.5;
                    *v = (*v as f64 * (1.0 + noise * u)) as f32;
                }
            }
        }
        write_binary(&out.join(format!("{n}.binary")), &rgb).expect("write");
    }
    out
}

#[test]
fn analytic_basis_reproduces_its_own_members_measured() {
    use brdf_basis::fit::{fit, FitParams};
    let names = ["gold-metallic-paint", "blue-acrylic", "steel"];
    let Some(csv) = shared_or_skip(
        "ngan2005_ashikhmin_shirley.csv",
        "analytic_basis_reproduces_its_own_members_measured",
    ) else {
        return;
    };
    let ngan = Collection::load(&csv).expect("ngan");
    let d = tmp();
    let dir = synthetic(&ngan, d.path(), &names, 0.0, None);
    let paths = vec![csv];
    // Measured copies are renamed by their directory stem: load them one by one.
    let measured = Collection::load(&dir).expect("measured");
    let mut coll = Collection::load_many(&paths).expect("ngan");
    for m in measured.materials() {
        let mut m = m.clone();
        m.name = format!("measured-{}", m.name);
        coll.push(m, &dir, 0).expect("push");
    }
    let basis: Vec<usize> = names
        .iter()
        .map(|n| coll.index_of(n).expect("basis"))
        .collect();
    let targets: Vec<usize> = names
        .iter()
        .map(|n| coll.index_of(&format!("measured-{n}")).expect("target"))
        .collect();
    assert!(matches!(
        coll.materials()[targets[0]].data,
        MaterialData::Measured(_)
    ));
    let fits = fit(
        &CpuBackend::new(),
        &coll,
        &basis,
        &targets,
        &FitParams {
            stride: 2,
            objective: TargetWeight::L2,
            ..Default::default()
        },
        &|_, _| {},
    )
    .expect("fit");
    for (k, f) in fits.iter().enumerate() {
        for ch in 0..3 {
            for (col, a) in f.coefficients.iter().enumerate() {
                let want = if col == k + 1 { 1.0 } else { 0.0 };
                // f32 round-off of the measured table: 1e-4 on the coefficients.
                assert!(
                    (a[ch] - want).abs() < 1e-4,
                    "{}: {:?}",
                    f.material,
                    f.coefficients
                );
            }
        }
        // The MAE is at the level of f32 round-off of the reflectance.
        let scale = fits
            .iter()
            .map(|f| f.residual.iter().sum::<f64>())
            .sum::<f64>();
        assert!(
            f.mae < 1e-5 && scale.is_finite(),
            "{}: mae {}",
            f.material,
            f.mae
        );
    }
}

#[test]
fn masked_and_noisy_measured_materials_measure_like_their_originals() {
    use brdf_basis::distance::{distance_matrix, lobes, DistanceParams, LobeKind};
    let names = [
        "gold-metallic-paint",
        "blue-acrylic",
        "steel",
        "white-acrylic",
    ];
    let Some(ngan) =
        ngan_or_skip("masked_and_noisy_measured_materials_measure_like_their_originals")
    else {
        return;
    };
    let analytic = ngan.subset(
        &names
            .iter()
            .map(|n| ngan.index_of(n).expect("n"))
            .collect::<Vec<_>>(),
    );
    let p = DistanceParams::default().lobe(LobeKind::Full).stride(2);
    let d = tmp();
    // (a) Exact copies with theta_d row 40 masked: the distance runs over the evaluation
    // cells valid in every material, so it equals the analytic distance over those cells.
    let dir = synthetic(&ngan, &d.path().join("exact"), &names, 0.0, Some(40));
    let measured = Collection::load(&dir).expect("measured");
    let order: Vec<usize> = measured
        .names()
        .iter()
        .map(|n| analytic.index_of(n).expect("same names"))
        .collect();
    let analytic = analytic.subset(&order);
    let dm = distance_matrix(
        &CpuBackend::new(),
        &measured,
        &p.check(&measured).expect("p"),
        &|_, _| {},
    )
    .expect("dm");
    let mut cells = brdf_basis::merl::CellSet::new(
        brdf_basis::merl::Mask::Evaluation,
        brdf_basis::merl::Weighting::Uniform,
        2,
    );
    let keep: Vec<bool> = cells
        .cells
        .iter()
        .map(|&c| brdf_basis::merl::unflat(c as usize).1 != 40)
        .collect();
    let mut k = keep.iter();
    cells.cells.retain(|_| *k.next().expect("k"));
    let n = cells.cells.len() as f64;
    cells.weights = vec![1.0 / n; cells.cells.len()];
    let want = CpuBackend::new()
        .pairwise_l1(&lobes(&analytic, LobeKind::Full), &cells, &|_, _| {})
        .expect("ref");
    let r = max_rel(&dm.condensed(), &want, 1e-300);
    assert!(
        r <= 1e-5,
        "masked measured vs analytic over the same cells: {r:e}"
    );
    if let Some(g) = gpu("masked_and_noisy_measured_materials_measure_like_their_originals") {
        let dg = distance_matrix(g, &measured, &p.check(&measured).expect("p"), &|_, _| {})
            .expect("gpu");
        assert!(
            max_rel(&dg.condensed(), &dm.condensed(), 1e-300) <= 1e-4,
            "gpu vs cpu on measured data"
        );
    }
    // (b) +-1 % multiplicative noise per cell: distances move by a few percent at most
    // (noise is relative to the values, not to their difference).
    let noisy = Collection::load(&synthetic(
        &ngan,
        &d.path().join("noisy"),
        &names,
        0.02,
        None,
    ))
    .expect("noisy");
    let dn = distance_matrix(
        &CpuBackend::new(),
        &noisy,
        &p.check(&noisy).expect("p"),
        &|_, _| {},
    )
    .expect("dn");
    let da = distance_matrix(
        &CpuBackend::new(),
        &analytic,
        &p.check(&analytic).expect("p"),
        &|_, _| {},
    )
    .expect("da");
    let r = max_rel(&dn.condensed(), &da.condensed(), 1e-300);
    assert!(r < 0.05, "noisy measured vs analytic: {r:e}");
}
