//! BRDFs (`Brdf`), the sphere renderer of SPEC 7 and the image error.

use crate::*;

/// A BRDF `f(wi, wo) -> RGB` in a local frame with the normal on +z: an analytic
/// material, a measured one (MERL lookup), or a fitted combination.
#[pyclass(frozen, module = "brdf_basis._native", name = "Brdf")]
pub(crate) struct Brdf {
    pub(crate) f: bb::eval::shade::BrdfFn,
    pub(crate) label: String,
}

#[pymethods]
impl Brdf {
    /// The BRDF of material `name` of `collection`.
    #[staticmethod]
    fn material(collection: &Bound<'_, Collection>, name: &str) -> PyResult<Self> {
        let coll = coll_of(collection);
        let m = coll.get(name).map_err(lib_err)?;
        Ok(Self {
            f: bb::eval::shade::material_brdf(&m.data),
            label: name.to_string(),
        })
    }

    /// The fitted combination of `target` read from a `fit` JSON file.
    #[staticmethod]
    fn fitted(collection: &Bound<'_, Collection>, fit: PathBuf, target: &str) -> PyResult<Self> {
        let coll = coll_of(collection);
        let f = bb::fit::file::FitFile::combination_from(&fit, &coll, target).map_err(lib_err)?;
        Ok(Self {
            f,
            label: format!("fit of {target} ({})", fit.display()),
        })
    }

    /// Evaluates at one pair of unit directions (3 floats each): (r, g, b). A direction
    /// with a NaN or infinite component, or of length other than 1 (within 1e-5), is
    /// refused with ValueError naming it: it would be read as another direction (or none).
    fn eval1(&self, wi: [f64; 3], wo: [f64; 3]) -> PyResult<(f64, f64, f64)> {
        unit("wi", wi)?;
        unit("wo", wo)?;
        let v = (self.f)(wi, wo);
        Ok((v[0], v[1], v[2]))
    }

    /// Evaluates at arrays of directions, shape (..., 3) each: returns (..., 3) float64.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArrayDyn<'py, f64>,
        wo: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let shape = wi.shape().to_vec();
        if shape != wo.shape() || shape.last() != Some(&3) {
            return Err(value_err(format!(
                "wi and wo must have the same shape (..., 3), got {:?} and {:?}",
                shape,
                wo.shape()
            )));
        }
        let a: Vec<f64> = wi.as_array().iter().copied().collect();
        let b: Vec<f64> = wo.as_array().iter().copied().collect();
        let f = &self.f;
        let out = py.detach(|| {
            let mut out = vec![0f64; a.len()];
            for ((o, x), y) in out.chunks_mut(3).zip(a.chunks(3)).zip(b.chunks(3)) {
                o.copy_from_slice(&f([x[0], x[1], x[2]], [y[0], y[1], y[2]]));
            }
            out
        });
        Ok(PyArray1::from_vec(py, out).reshape(shape)?.into_any())
    }

    fn __repr__(&self) -> String {
        format!("Brdf({})", self.label)
    }
}

/// The sphere of SPEC 7 (orthographic from +z, one directional light from
/// `light = (theta, phi)` degrees): linear radiance, shape (size, size, 3) float32, row 0
/// at the top (what `brdf-basis render --out` writes). `size` and `light` left out
/// (`None`) are the library's (`RenderParams::default()`, `defaults()`).
#[pyfunction]
#[pyo3(signature = (brdf, *, size = None, light = None))]
pub(crate) fn render<'py>(
    py: Python<'py>,
    brdf: &Bound<'py, Brdf>,
    size: Option<u32>,
    light: Option<(f64, f64)>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut p = bb::eval::render::RenderParams::default();
    set(&mut p.size, size);
    set(&mut p.light, light);
    let size = p.size;
    let f = &brdf.get().f;
    let img = py
        .detach(|| bb::eval::render::render_sphere(&p, f))
        .map_err(lib_err)?;
    let s = size as usize;
    Ok(img.data.to_pyarray(py).reshape([s, s, 3])?.into_any())
}

/// Refuses a direction `name` that is not a finite unit vector (length 1 within 1e-5, the
/// rounding of float32 vectors normalised elsewhere).
fn unit(name: &str, d: [f64; 3]) -> PyResult<()> {
    if d.iter().any(|x| !x.is_finite()) {
        return Err(value_err(format!(
            "{name} = {d:?}: a direction must be finite (a NaN or infinite component)"
        )));
    }
    let len = d.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (len - 1.0).abs() > 1e-5 {
        return Err(value_err(format!(
            "{name} = {d:?}: a direction must be a unit vector, its length is {len} (normalise it first)"
        )));
    }
    Ok(())
}

/// The image `a` (named `name` in messages): shape (height, width, 3), every value
/// finite (a NaN would count as black in the error).
pub(crate) fn image_of(
    a: &PyReadonlyArrayDyn<'_, f32>,
    name: &str,
) -> PyResult<bb::eval::render::Image> {
    let sh = a.shape();
    if sh.len() != 3 || sh[2] != 3 {
        return Err(value_err(format!(
            "{name}: an image has shape (height, width, 3), got {sh:?}"
        )));
    }
    if let Some((i, v)) = a.as_array().indexed_iter().find(|(_, v)| !v.is_finite()) {
        return Err(value_err(format!(
            "{name}: the value at [{}, {}, {}] is {v}; an image must be finite",
            i[0], i[1], i[2]
        )));
    }
    let (h, w) = (sh[0] as u32, sh[1] as u32);
    Ok(bb::eval::render::Image {
        width: w,
        height: h,
        data: a.as_array().iter().copied().collect(),
        mask: bb::eval::render::sphere_mask(w, h),
    })
}

/// Normalised image error of SPEC 7 between two sphere renders (float32 arrays
/// (size, size, 3)): the mean over sphere pixels and channels of |a - b| after the
/// display mapping (exposure, gamma, clamp). `exposure` and `gamma` left out (`None`)
/// are the library's (`DisplayParams::default()`, `defaults()`).
#[pyfunction]
#[pyo3(signature = (a, b, *, exposure = None, gamma = None))]
pub(crate) fn image_error(
    a: PyReadonlyArrayDyn<'_, f32>,
    b: PyReadonlyArrayDyn<'_, f32>,
    exposure: Option<f64>,
    gamma: Option<f64>,
) -> PyResult<f64> {
    let mut d = bb::eval::image_error::DisplayParams::default();
    set(&mut d.exposure, exposure);
    set(&mut d.gamma, gamma);
    d.check().map_err(lib_err)?;
    bb::eval::image_error::normalized_image_error(&image_of(&a, "a")?, &image_of(&b, "b")?, &d)
        .map_err(lib_err)
}

/// CIEDE2000 colour difference of two CIELAB colours (SPEC 11; `k_L = k_C = k_H = 1`).
/// A NaN or infinite component is refused (audit 3, U8: it returned NaN).
#[pyfunction]
pub(crate) fn ciede2000(lab1: [f64; 3], lab2: [f64; 3]) -> PyResult<f64> {
    for (name, lab) in [("lab1", lab1), ("lab2", lab2)] {
        if lab.iter().any(|v| !v.is_finite()) {
            return Err(value_err(format!(
                "{name}: a CIELAB colour is finite, got {lab:?}"
            )));
        }
    }
    Ok(bb::eval::color::ciede2000(lab1, lab2))
}

/// CIELAB (D65) of an sRGB-encoded colour in [0, 1]^3 (SPEC 11's conversion). A
/// component outside [0, 1] (or NaN) is refused (audit 3, U8: it was clamped silently;
/// the image metrics clamp after the display mapping, where the clamp is SPEC 7's).
#[pyfunction]
pub(crate) fn srgb_to_lab(rgb: [f64; 3]) -> PyResult<[f64; 3]> {
    if rgb.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return Err(value_err(format!(
            "rgb: an sRGB-encoded colour lies in [0, 1]^3, got {rgb:?}; clamp it first if that is meant"
        )));
    }
    Ok(bb::eval::color::srgb_to_lab(rgb))
}

/// ICtCp (ITU-R BT.2100, PQ) of an sRGB-encoded display colour in [0, 1]^3, its white at
/// 100 cd/m² (`eval::ictcp`). A component outside [0, 1] (or NaN) is refused, as by
/// `srgb_to_lab`.
#[pyfunction]
pub(crate) fn srgb_to_ictcp(rgb: [f64; 3]) -> PyResult<[f64; 3]> {
    if rgb.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return Err(value_err(format!(
            "rgb: an sRGB-encoded colour lies in [0, 1]^3, got {rgb:?}; clamp it first if that is meant"
        )));
    }
    Ok(bb::eval::ictcp::srgb_to_ictcp(rgb))
}

/// ΔE_ITP (ITU-R BT.2124) of two ICtCp colours; a NaN or infinite component is refused.
#[pyfunction]
pub(crate) fn delta_e_itp(ictcp1: [f64; 3], ictcp2: [f64; 3]) -> PyResult<f64> {
    for (name, c) in [("ictcp1", ictcp1), ("ictcp2", ictcp2)] {
        if c.iter().any(|v| !v.is_finite()) {
            return Err(value_err(format!(
                "{name}: an ICtCp colour is finite, got {c:?}"
            )));
        }
    }
    Ok(bb::eval::ictcp::delta_e_itp(ictcp1, ictcp2))
}

/// The image metrics of SPEC 11 between two sphere renders `reference` and `test`
/// (float32 (size, size, 3), linear): a dict with `image_error`, `ciede2000` and
/// `delta_e_itp` (means over the sphere's pixels; ΔE_ITP of ITU-R BT.2124, white at
/// 100 cd/m²) and `flip` (mean LDR FLIP over the sphere's pixels, the project's own at 67
/// pixels per degree, within 1e-4 of NVIDIA's), all after SPEC 7's display mapping (exposure
/// 0, gamma 2.2, clamped).
#[pyfunction]
pub(crate) fn image_metrics(
    reference: PyReadonlyArrayDyn<'_, f32>,
    test: PyReadonlyArrayDyn<'_, f32>,
) -> PyResult<std::collections::BTreeMap<&'static str, f64>> {
    let (a, b) = (image_of(&reference, "reference")?, image_of(&test, "test")?);
    // Audit 3, U8: a sphere render is square (its mask and FLIP's pixels per degree
    // assume it); a 32 x 64 image was scored.
    for (name, im) in [("reference", &a), ("test", &b)] {
        if im.width != im.height {
            return Err(value_err(format!(
                "{name}: a sphere render is square (size, size, 3), got {} x {}",
                im.height, im.width
            )));
        }
    }
    let s = bb::eval::appearance::light_scores(&a, &b, (f64::NAN, f64::NAN)).map_err(lib_err)?;
    Ok([
        ("image_error", s.image_error),
        ("ciede2000", s.ciede2000),
        ("delta_e_itp", s.delta_e_itp),
        ("flip", s.flip),
    ]
    .into_iter()
    .collect())
}

/// The name of the back-end `backend` opens (`cpu (2 threads, avx2)`, `gpu: ...`).
#[pyfunction]
#[pyo3(signature = (backend = None))]
pub(crate) fn backend_name(backend: Option<&str>) -> PyResult<String> {
    Ok(open_backend(backend)?.name())
}
