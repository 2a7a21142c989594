//! Partial pre-integration (Espinha & Celes 2005): the segment integrator steps through the
//! TF's control points inside a tet as the exact one does, and takes each piece's mean
//! transmittance `psi(A, B) = int_0^1 exp(-(A v + (B - A) v^2 / 2)) dv` (Moreland & Angel
//! 2004; `A`, `B` the piece's optical depth at its ends) from a table instead of quadrature.
//! The table depends on nothing else, so it is built once per process and a TF change costs
//! nothing. Its axes are `gamma = sqrt(A) / (1 + sqrt(A))` in `[0, 1]` (at 1, `A` is infinite
//! and `psi` 0), [`PSI_SIZE`] samples each, interpolated bilinearly
//! (`shaders/raycast_psi.wgsl`; CPU twin [`lookup`]). Moreland & Angel map `A / (1 + A)`;
//! for one end deep, `psi` falls as `1 / sqrt(B)`, which is linear in this `gamma` near 1 and
//! not in theirs (measured there: 1.4e-2 at `B = 1e4`).

use std::sync::OnceLock;

use rayon::prelude::*;

use crate::gpu::cellproj::preint::mean_transmittance;

/// Samples per table axis: 512 x 512 f32, 1 MiB.
pub const PSI_SIZE: u32 = 512;

/// The optical depth at table coordinate `gamma` (inverse of [`gamma`]).
fn depth(gamma: f64) -> f64 {
    (gamma / (1.0 - gamma)).powi(2)
}

/// The table coordinate of optical depth `a`: `sqrt(a) / (1 + sqrt(a))`, in `[0, 1)`.
fn gamma(a: f32) -> f32 {
    let r = a.sqrt();
    r / (1.0 + r)
}

/// `psi` at sample `(i, j)` (`A` along i, `B` along j), 0 where either depth is infinite.
fn sample(i: u32, j: u32) -> f32 {
    let n = (PSI_SIZE - 1) as f64;
    let (a, b) = (depth(i as f64 / n), depth(j as f64 / n));
    if a.is_finite() && b.is_finite() {
        mean_transmittance(a, b) as f32
    } else {
        0.0
    }
}

/// The table, row `j` (B) after row `j - 1`, built on first use.
pub fn table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..PSI_SIZE * PSI_SIZE)
            .into_par_iter()
            .map(|k| sample(k % PSI_SIZE, k / PSI_SIZE))
            .collect()
    })
}

/// Bilinear lookup of `psi(a, b)` in [`table`], the operations of WGSL `psi`.
pub fn lookup(a: f32, b: f32) -> f32 {
    let t = table();
    let n = (PSI_SIZE - 1) as f32;
    let g = [gamma(a) * n, gamma(b) * n];
    let i = g.map(|x| (x.floor() as u32).min(PSI_SIZE - 2));
    let w = [g[0] - i[0] as f32, g[1] - i[1] as f32];
    let at = |x: u32, y: u32| t[(y * PSI_SIZE + x) as usize];
    let mix = |p: f32, q: f32, s: f32| p * (1.0 - s) + q * s;
    let lo = mix(at(i[0], i[1]), at(i[0] + 1, i[1]), w[0]);
    let hi = mix(at(i[0], i[1] + 1), at(i[0] + 1, i[1] + 1), w[0]);
    mix(lo, hi, w[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_is_close_to_the_quadrature_over_all_depths() {
        // Depths from 0 to 1e4 on a log grid with the two ends apart and together.
        let depths: Vec<f64> = (0..=60)
            .map(|k| 1e-4 * 10f64.powf(k as f64 / 7.5))
            .collect();
        let mut worst = 0.0f64;
        for &a in &depths {
            for &b in &depths {
                let exact = mean_transmittance(a, b);
                worst = worst.max((lookup(a as f32, b as f32) as f64 - exact).abs());
            }
        }
        // Bilinear interpolation at spacing 1/511 in gamma: measured 8.9e-6 at most; the
        // piece's colour is psi times colours in [0, 1], so this bounds its error too.
        assert!(worst < 2e-5, "worst {worst:e}");
        assert_eq!(lookup(0.0, 0.0), 1.0);
    }
}
