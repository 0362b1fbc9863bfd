//! Fresnel terms.

/// Schlick's approximation `F(F0, x) = F0 + (1 - F0) (1 - x)^5`, with `x` the cosine of
/// the angle between the light (or view) direction and the half vector.
///
/// Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", CGF 13(3), 1994,
/// doi:10.1111/1467-8659.1330233.
#[inline]
pub(crate) fn schlick(f0: f64, x: f64) -> f64 {
    let m = (1.0 - x).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * m2 * m2 * m
}

/// Schlick's `(1 - x)^5` factor alone, for callers that precompute it per angle.
#[inline]
pub fn schlick_weight(x: f64) -> f64 {
    let m = (1.0 - x).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// Normal-incidence reflectance of a dielectric with real index `eta` in air:
/// `((eta - 1) / (eta + 1))^2`.
#[inline]
pub fn f0_dielectric(eta: f64) -> f64 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// Normal-incidence reflectance of a conductor with complex index `eta + i k` in air:
/// `((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2)`.
#[inline]
pub fn f0_conductor(eta: f64, k: f64) -> f64 {
    ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k)
}
