//! `defaults()`: the settings a Python call takes when a keyword argument is left out
//! (`None`), read from the library's requests (`brdf_basis::run`), their one home. The
//! bindings' signatures hold no default of their own: a test compares each call's
//! recorded settings with these.

use crate::*;
use serde_json::{json, Map, Value};

/// A setting's spelling (the command line's, which the library's `serde` names are).
fn name<T: serde::Serialize>(v: T) -> Value {
    serde_json::to_value(v).unwrap_or(Value::Null)
}

/// `mask`, `weighting` and `stride` of a request's grid.
fn grid(m: &mut Map<String, Value>, g: bb::merl::GridSpec) {
    m.insert("mask".into(), g.mask().as_str().into());
    m.insert("weighting".into(), g.weighting().as_str().into());
    m.insert("stride".into(), g.stride().into());
}

/// `objective` and `eps` (`None` unless relative) when neither is given.
fn objective(m: &mut Map<String, Value>) -> PyResult<()> {
    let w = bb::run::ObjectiveSetting::default()
        .weight()
        .map_err(lib_err)?;
    m.insert("objective".into(), w.kind().name().into());
    m.insert("eps".into(), w.eps().into());
    Ok(())
}

/// The defaults of every command's keyword arguments, by the package's function name
/// (`distance_matrix`, `select`, `fit`, `plan`, `fit_samples`, `cross_validate`,
/// `acquisition_cv`), as JSON text. Settings whose default depends on other settings
/// (`k` of a method, `runs`, ...) are not listed: the request resolves them.
#[pyfunction]
pub(crate) fn defaults_json() -> PyResult<String> {
    let backend = Value::from(bb::BackendChoice::default().as_str());
    let mut all = Map::new();

    let d = bb::run::DistanceRequest::default();
    let mut m = Map::new();
    m.insert("metric".into(), name(d.metric));
    grid(&mut m, d.grid);
    m.insert("backend".into(), backend.clone());
    all.insert("distance_matrix".into(), m.into());

    let s = bb::run::SelectRequest::new(bb::run::SelectMethod::Greedy);
    let mut m = Map::new();
    grid(&mut m, s.grid);
    m.insert("seed".into(), s.seed().into());
    objective(&mut m)?;
    m.insert("backend".into(), backend.clone());
    all.insert("select".into(), m.into());

    let f = bb::run::FitRequest::new(Vec::new());
    let mut m = Map::new();
    grid(&mut m, f.grid);
    m.insert("solver".into(), name(f.solver));
    m.insert("gram".into(), name(f.gram));
    objective(&mut m)?;
    m.insert("appearance".into(), f.appearance.into());
    m.insert("backend".into(), backend.clone());
    all.insert("fit".into(), m.into());

    let p = bb::run::PlanRequest::new(Vec::new());
    let mut m = Map::new();
    m.insert("criterion".into(), name(p.criterion));
    m.insert("seed".into(), p.seed().into());
    objective(&mut m)?;
    m.insert("backend".into(), backend.clone());
    all.insert("plan".into(), m.into());

    let samples = bb::run::Samples::Arrays {
        angles: Vec::new(),
        rgb: Vec::new(),
        sigma: None,
    };
    let fs = bb::run::FitSamplesRequest::of(Vec::new(), samples);
    let mut m = Map::new();
    m.insert("seed".into(), fs.seed.into());
    objective(&mut m)?;
    all.insert("fit_samples".into(), m.into());

    let c = bb::run::CvRequest::default();
    let mut m = Map::new();
    let methods: Vec<String> = c.methods.iter().map(|x| x.to_string()).collect();
    m.insert("methods".into(), json!(methods));
    m.insert("ks".into(), json!(c.ks));
    m.insert("folds".into(), c.folds.into());
    grid(&mut m, c.grid);
    m.insert("render_size".into(), c.render_size.into());
    m.insert("seed".into(), c.seed.into());
    objective(&mut m)?;
    m.insert("appearance".into(), c.appearance.into());
    m.insert("backend".into(), backend.clone());
    all.insert("cross_validate".into(), m.into());

    let a = bb::run::AcquisitionRequest::default();
    let mut m = Map::new();
    let methods: Vec<String> = a.methods.iter().map(|x| x.to_string()).collect();
    m.insert("methods".into(), json!(methods));
    m.insert("k".into(), a.k.into());
    m.insert("plans".into(), name(&a.plans));
    m.insert("ns".into(), json!(a.ns));
    m.insert("noises".into(), json!(a.noises));
    m.insert("folds".into(), a.folds().into());
    m.insert("render_size".into(), a.render_size.into());
    grid(&mut m, a.grid);
    m.insert("seed".into(), a.seed.into());
    objective(&mut m)?;
    m.insert("appearance".into(), a.appearance.into());
    m.insert("backend".into(), backend);
    all.insert("acquisition_cv".into(), m.into());

    // The helpers that are not commands: the library's parameter types' defaults.
    let k = bb::KMedoidsParams::new(2);
    all.insert(
        "kmedoids".into(),
        json!({
            "seed": k.seed,
            "init": k.init.to_string(),
            "algorithm": k.algorithm.to_string(),
            "restarts": k.restarts,
            "max_iter": k.max_iter,
            "order": k.order.to_string(),
            "tolerance": k.tolerance,
        }),
    );
    let r = bb::eval::render::RenderParams::default();
    all.insert(
        "render".into(),
        json!({ "size": r.size, "light": [r.light.0, r.light.1] }),
    );
    let d = bb::eval::image_error::DisplayParams::default();
    all.insert(
        "image_error".into(),
        json!({ "exposure": d.exposure, "gamma": d.gamma }),
    );
    all.insert(
        "mask".into(),
        json!({ "name": bb::merl::GridSpec::default().mask().as_str() }),
    );

    serde_json::to_string_pretty(&Value::Object(all)).map_err(|e| value_err(e.to_string()))
}
