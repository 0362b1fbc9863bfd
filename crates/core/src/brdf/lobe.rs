//! The parameters of one analytic lobe on the grid, shared by the models, the separable
//! tables and the back-ends (CPU and GPU), which all depend on `brdf`, never the reverse.

/// An analytic lobe `kd / pi + ks * rho_s(F0, n)`: the specular lobe is
/// `(0, 1, F0, n)`, one RGB channel `(d_c, s_c, F0, n)`, the channel mean
/// `(mean d, mean s, F0, n)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobeParams {
    /// Coefficient of the Lambertian term `1 / pi`.
    pub kd: f32,
    /// Coefficient of `rho_s`.
    pub ks: f32,
    /// Schlick F0.
    pub f0: f32,
    /// Exponent.
    pub n: f32,
}
