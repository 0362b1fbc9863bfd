//! `brdf-basis distance`.

use super::Global;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::distance::{
    distance_matrix_banded, distance_tile, DistanceParams, LobeKind, Metric, DEFAULT_BAND_ROWS,
};
use brdf_basis::io::saved::{csv_bytes, stage_npy_with_sidecar, stage_tile};
use brdf_basis::io::sidecar::{sidecar_path, MatrixSettings};
use std::path::PathBuf;

/// Arguments of `distance`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "A .npy output gets a JSON sidecar beside it (d.npy -> d.names.json) holding the \
material names, the settings, a fingerprint of the collection and the size and checksum of \
the .npy; `select --distances d.npy` reads the pair and refuses a mismatched one. A .csv holds \
the names in its header.\n\n\
--tile I/N computes the I-th of N bands of rows (1-based; N up to the number of materials, \
bands balanced by work) into a tile (.npy + sidecar); `brdf-basis merge` assembles the N \
tiles into the matrix, byte-identical to computing it at once (with the same --band-rows, \
which the sidecar records; it changes no value).\n\n\
Examples:\n  brdf-basis distance --out d.csv\n  brdf-basis distance --out d.npy\n  \
brdf-basis distance --stride 2 --band-rows 16 --tile 1/2 --out t1.npy\n  \
brdf-basis distance --stride 2 --band-rows 16 --tile 2/2 --out t2.npy\n  \
brdf-basis merge t1.npy t2.npy --out d.npy"
)]
pub struct DistanceArgs {
    /// Collection(s): analytic .csv, .binary file or directory (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// brdf-it (the paper's Eq. 5) or euclidean (on F0, n).
    #[arg(long, default_value = "brdf-it")]
    pub metric: Metric,
    /// Grid cells and weights.
    #[command(flatten)]
    pub grid: super::GridArgs,
    /// specular (rho_s, analytic only) or full (mean of R, G, B); default: specular when
    /// every material is analytic.
    #[arg(long)]
    pub lobe: Option<LobeKind>,
    /// Compute only band I of N (1-based) into a tile file (.npy + sidecar) for `merge`.
    #[arg(long, value_name = "I/N")]
    pub tile: Option<String>,
    /// Materials per back-end call of the banded computation (a multiple of 4): bounds the
    /// memory of a call and changes no value; tiles merge only with tiles of the same value.
    #[arg(long, default_value_t = DEFAULT_BAND_ROWS)]
    pub band_rows: usize,
    /// Output: .npy (float64 N x N, with a .names.json sidecar) or .csv.
    #[arg(long)]
    pub out: PathBuf,
}

/// Parses `I/N`.
fn parse_tile(s: &str) -> anyhow::Result<(usize, usize)> {
    let parsed = s
        .split_once('/')
        .and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)));
    match parsed {
        Some((i, n)) if i >= 1 && i <= n => Ok((i, n)),
        _ => anyhow::bail!("--tile `{s}`: expected I/N with 1 <= I <= N (e.g. --tile 3/8)"),
    }
}

/// Computes and writes the matrix (or one tile of it).
pub fn run(g: &Global, a: DistanceArgs) -> anyhow::Result<()> {
    let ext = super::extension(&a.out);
    if ext != "npy" && ext != "csv" {
        anyhow::bail!("{}: output must end in .npy or .csv", a.out.display());
    }
    let tile = a.tile.as_deref().map(parse_tile).transpose()?;
    if tile.is_some() && ext != "npy" {
        anyhow::bail!("{}: a tile (--tile) is written as .npy", a.out.display());
    }
    brdf_basis::distance::band::check_band_rows(a.band_rows)?;
    // Every output path before the work (the sidecar too: it replaces only a sidecar).
    let mut plan = OutputPlan::new(&a.collection);
    if ext == "npy" {
        super::plan_matrix(&mut plan, &a.out, "--out")?;
    } else {
        plan.file(&a.out, "--out")?;
    }
    let mut out = plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    let mut p = DistanceParams::default()
        .metric(a.metric)
        .mask(a.grid.mask)
        .weighting(a.grid.weighting)
        .stride(a.grid.stride);
    p.lobe = a.lobe;
    let p = p.check(&coll)?;
    if let Some((i, n)) = tile {
        brdf_basis::distance::band::tile_rows(coll.len(), i, n)?;
    }
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "distance");
    let progress = |done, total| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let settings = MatrixSettings::of(&p, a.band_rows);
    let n = coll.len();
    if let Some((i, count)) = tile {
        let t = distance_tile(
            backend.as_ref(),
            &coll,
            &p,
            a.band_rows,
            i,
            count,
            &progress,
        )?;
        pb.finish_and_clear();
        stage_tile(
            &mut out,
            &a.out,
            &t,
            &coll.names(),
            &settings,
            &coll.fingerprint(),
        )?;
        out.commit()?;
        println!(
            "wrote {} (tile {i}/{count}: rows {}..{} of {n} x {n} {})",
            a.out.display(),
            t.rows.start,
            t.rows.end,
            p.metric()
        );
        println!("wrote {}", sidecar_path(&a.out).display());
        return Ok(());
    }
    let d = distance_matrix_banded(backend.as_ref(), &coll, &p, a.band_rows, &progress)?;
    pb.finish_and_clear();
    if ext == "npy" {
        stage_npy_with_sidecar(&mut out, &a.out, &d, &settings, &coll.fingerprint())?;
    } else {
        out.stage(&a.out, |w| w.write_all(&csv_bytes(&d)?))?;
    }
    out.commit()?;
    println!(
        "wrote {} ({n} x {n} {}, lobe {}, mask {}, weighting {})",
        a.out.display(),
        p.metric(),
        p.lobe(),
        p.mask(),
        p.weighting()
    );
    if ext == "npy" {
        println!("wrote {}", sidecar_path(&a.out).display());
    }
    Ok(())
}
