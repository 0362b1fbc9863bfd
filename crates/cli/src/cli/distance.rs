//! `brdf-basis distance`.

use super::Global;
use brdf_basis::atomic::OutputPlan;
use brdf_basis::distance::{LobeKind, Metric};
use brdf_basis::io::saved::{csv_bytes, stage_npy_with_sidecar, stage_tile};
use brdf_basis::io::sidecar::{sidecar_path, MatrixSettings};
use brdf_basis::run::{Ctx, DistanceOutput, DistanceRequest, Request};
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
pub(crate) struct DistanceArgs {
    /// Collection(s): analytic .csv, .binary file or directory (none: embedded default).
    pub collection: Vec<PathBuf>,
    /// brdf-it (the paper's Eq. 5) or euclidean (on F0, n).
    #[arg(long, default_value_t = DistanceRequest::default().metric)]
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
    #[arg(long, default_value_t = DistanceRequest::default().band_rows)]
    pub band_rows: usize,
    /// Output: .npy (float64 N x N, with a .names.json sidecar) or .csv.
    #[arg(long)]
    pub out: PathBuf,
}

/// Parses `I/N` (the range is the request's rule).
fn parse_tile(s: &str) -> anyhow::Result<(usize, usize)> {
    s.split_once('/')
        .and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)))
        .ok_or_else(|| {
            anyhow::anyhow!("--tile `{s}`: expected I/N with 1 <= I <= N (e.g. --tile 3/8)")
        })
}

impl DistanceArgs {
    /// The request these flags make.
    pub(crate) fn request(&self) -> anyhow::Result<DistanceRequest> {
        let mut r = DistanceRequest::default();
        r.metric = self.metric;
        r.grid = self.grid.grid()?;
        r.lobe = self.lobe;
        r.band_rows = self.band_rows;
        r.tile = self.tile.as_deref().map(parse_tile).transpose()?;
        Ok(r)
    }
}

/// Computes and writes the matrix (or one tile of it).
pub(crate) fn run(g: &Global, a: DistanceArgs) -> anyhow::Result<()> {
    let ext = super::extension(&a.out);
    if ext != "npy" && ext != "csv" {
        anyhow::bail!("{}: output must end in .npy or .csv", a.out.display());
    }
    let req = a.request()?;
    if req.tile.is_some() && ext != "npy" {
        anyhow::bail!("{}: a tile (--tile) is written as .npy", a.out.display());
    }
    req.check()?;
    // Every output path before the work (the sidecar too: it replaces only a sidecar).
    let mut plan = OutputPlan::new(&a.collection);
    if ext == "npy" {
        super::plan_matrix(&mut plan, &a.out, "--out")?;
    } else {
        plan.file(&a.out, "--out")?;
    }
    let mut out = plan.into_set()?;
    let coll = super::load_collection(&a.collection)?;
    let p = req.params(&coll)?;
    let backend = super::backend(g)?;
    let pb = super::progress_bar(g, 1, "distance");
    let progress = |done, total| {
        pb.set_length(total);
        pb.set_position(done);
    };
    let settings = MatrixSettings::of(&p, a.band_rows);
    let n = coll.len();
    let computed = req.run(&Ctx::new(backend.as_ref(), &coll).progress(&progress))?;
    pb.finish_and_clear();
    let d = match computed {
        DistanceOutput::Matrix(d) => d,
        DistanceOutput::Tile(t) => {
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
                "wrote {} (tile {}/{}: rows {}..{} of {n} x {n} {})",
                a.out.display(),
                t.index,
                t.count,
                t.rows.start,
                t.rows.end,
                p.metric()
            );
            println!("wrote {}", sidecar_path(&a.out).display());
            return Ok(());
        }
        _ => unreachable!("distance computes a matrix or a tile"),
    };
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
