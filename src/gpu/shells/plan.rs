//! Stage 1 of a shells frame, on the CPU: the plan (where the frame's slices lie, which
//! slices-per-shell counts it may use), the tets binned against it ([`super::binning`]), and
//! the count it uses ([`super::adaptive`]).

use rayon::prelude::*;

use crate::camera::Camera;
use crate::gpu::mesh::MeshData;
use crate::gpu::util::settings_error;
use crate::gpu::view::ViewFrame;
use crate::render::RenderError;
use crate::tf::TransferFunction;

use super::binning::{self, BinParams, TetBin};
use super::{MAX_SHELLS, ShellsRenderer, adaptive, raster};

/// Where a frame's slices lie and which slices-per-shell counts it may use.
pub(super) struct FramePlan {
    pub(super) view: ViewFrame,
    /// Slice `k` lies at distance `t_first + k dz` from the eye.
    pub(super) t_first: f64,
    pub(super) dz: f64,
    /// Slices across the mesh.
    pub(super) slices: u64,
    /// The slices-per-shell counts that make at most [`MAX_SHELLS`] shells, ascending.
    pub(super) allowed: Vec<u32>,
    /// Every sample has eye-space z at least this; tets with a corner below it are near-plane
    /// tets, clipped at half of it.
    pub(super) near_z: f64,
}

impl FramePlan {
    /// The binning parameters of this plan.
    pub(super) fn bin_params(&self, frustum: bool) -> BinParams {
        BinParams {
            eye: self.view.eye,
            basis: self.view.basis,
            slope: self.view.slope,
            t_first: self.t_first,
            dz: self.dz,
            slices: self.slices,
            near_z: self.near_z,
            frustum,
        }
    }

    /// Shells of `n` slices across the mesh.
    pub(super) fn shells(&self, n: u32) -> u64 {
        self.slices.div_ceil(n as u64)
    }

    /// The pixel rectangle of an image-plane rectangle (see [`raster::scissor`]).
    pub(super) fn scissor(&self, r: binning::ScreenRect) -> [u32; 4] {
        let [w, h] = self.view.size;
        raster::scissor(r, self.view.slope, w, h)
    }
}

/// The slices from `t_first` at spacing `dz` up to the far side of the mesh's bounding sphere
/// seen from `camera`'s eye.
pub(super) fn slice_count(m: &MeshData, camera: &Camera, t_first: f64, dz: f64) -> u64 {
    let dist = (m.origin - camera.eye).length();
    ((dist + m.radius - t_first) / dz).floor() as u64 + 1
}

impl ShellsRenderer {
    /// The slice spacing over the mesh `m` in its frame (see [`ShellsRenderer::dz`]).
    pub(super) fn dz_for(&self, m: &MeshData) -> f64 {
        (self.settings.dz)
            .map(|dz| m.frame.length(dz))
            .unwrap_or(2.0 * m.radius / self.settings.samples as f64)
            .max(f64::MIN_POSITIVE)
    }

    /// `(t_first, dz)` of the slices for `camera` over the mesh `m` (see
    /// [`ShellsRenderer::slice_positions`]).
    pub(super) fn slices_for(&self, m: &MeshData, camera: &Camera) -> (f64, f64) {
        let dz = self.dz_for(m);
        let dist = (m.origin - camera.eye).length();
        ((dist - m.radius).max(0.0) + 0.5 * dz, dz)
    }

    /// The frame's plan; an error when even the largest allowed count makes more than
    /// [`MAX_SHELLS`] shells.
    pub(super) fn plan(&self, m: &MeshData, camera: &Camera) -> Result<FramePlan, RenderError> {
        let view = ViewFrame::new(camera);
        let (t_first, dz) = self.slices_for(m, camera);
        let slices = slice_count(m, camera, t_first, dz);
        let allowed: Vec<u32> = match self.fixed_slices {
            Some(n) => vec![n],
            None => self.candidates.clone(),
        }
        .into_iter()
        .filter(|&n| slices.div_ceil(n as u64) <= MAX_SHELLS)
        .collect();
        if allowed.is_empty() {
            let n = self.fixed_slices.unwrap_or(4 * self.formats.layers);
            let dz = m.frame.world_length(dz);
            return Err(settings_error(format!(
                "dz = {dz} makes {} shells of {n} slices across the mesh; at most \
                 {MAX_SHELLS} are allowed: use fewer samples or a larger dz",
                slices.div_ceil(n as u64)
            )));
        }
        // Every sample has eye-space z >= t_first * cos(widest ray angle).
        let slope = view.slope;
        let cos_corner = 1.0 / (1.0 + slope[0] * slope[0] + slope[1] * slope[1]).sqrt();
        Ok(FramePlan {
            view,
            t_first,
            dz,
            slices,
            allowed,
            near_z: t_first * cos_corner,
        })
    }

    /// Each tet's shells (or why it has none): transparent tets from the per-tet scalar
    /// ranges (a textured cage's: of the volume over each tet), computed once per transfer
    /// function and scalars.
    pub(super) fn classify(
        &mut self,
        m: &MeshData,
        plan: &FramePlan,
        tf: &TransferFunction,
    ) -> Vec<TetBin> {
        let skips = self.settings.skips;
        self.transparent_mask(m, tf);
        let transparent = match &self.transparent {
            Some((_, _, mask)) if skips.tf_cull => mask.as_slice(),
            _ => &[],
        };
        let params = plan.bin_params(skips.frustum);
        binning::classify(&m.positions, &m.tets, &params, |t| {
            transparent.get(t).copied().unwrap_or(false)
        })
    }

    /// With transfer-function culling, brings the cached transparent-tet mask up to date with
    /// `tf` and the scalars.
    pub(super) fn transparent_mask(&mut self, m: &MeshData, tf: &TransferFunction) {
        let version = m.scalars_version;
        let stale = |(t, v, _): &(TransferFunction, u64, Vec<bool>)| t != tf || *v != version;
        if self.settings.skips.tf_cull && self.transparent.as_ref().is_none_or(stale) {
            // A textured cage's tets span the volume's values over them, not their vertices'.
            let ranges = match &self.texture {
                Some(t) => &t.ranges,
                None => m.ranges(),
            };
            let mask = (ranges.par_iter())
                .map(|&(lo, hi)| tf.is_transparent_on(lo, hi))
                .collect();
            self.transparent = Some((tf.clone(), version, mask));
        }
    }

    /// Slices per shell: fixed, or the least predicted work among the allowed counts (the
    /// largest when the slices are too many to profile).
    pub(super) fn choose_slices(&mut self, plan: &FramePlan, bins: &[TetBin]) -> u32 {
        let largest = plan.allowed.last().copied().unwrap_or(1);
        let n = if self.fixed_slices.is_some() {
            largest
        } else {
            let pixels = |r| {
                let [_, _, w, h] = plan.scissor(r);
                w as f64 * h as f64
            };
            adaptive::profile(bins, &plan.allowed, plan.slices, pixels)
                .and_then(|work| {
                    adaptive::choose(&work, &self.model, self.default_slices, adaptive::MARGIN)
                })
                .unwrap_or(largest)
        };
        self.slices_per_shell = n;
        n
    }
}
