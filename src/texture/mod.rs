//! Deforming volumes (issue 12; Georgii & Westermann 2006, section 3): a scalar volume kept as
//! a 3D texture and bound to a coarse tetrahedral **cage** whose vertices carry 3D texture
//! coordinates. Inside a tet the texture coordinate is the barycentric interpolation of its
//! four vertices' coordinates, and the scalar is the volume sampled there (trilinear, clamp to
//! edge). Moving the cage's vertices moves the volume with them; the texture and the texture
//! coordinates never change.
//!
//! **Texture coordinates** are normalized, as a GPU sampler reads them: sample `i` of an axis
//! with `n` samples has its centre at `(i + 0.5) / n`. World positions map to the voxel grid as
//! `tetvr generate nifti` places it (voxel `(i, j, k)` at `(i, j, k) * pixdim[1..4]`, the
//! qform/sform affine not applied), so an undeformed cage ([`cage()`]) covers the same box as the
//! volume's tet mesh from [`crate::generate::volume::nifti_to_tets`].

pub mod cage;
pub mod iso;
pub(crate) mod ranges;
pub mod reference;

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use crate::cpu::raycast::{CpuRaycastRenderer, CpuRaycastSettings};
use crate::generate::volume::{VolumeError, VolumeToTets, check_header_file, read_samples_file};
use crate::gpu::ShellsRenderer;
use crate::gpu::raycast::{RaycastRenderer, RaycastSettings};
use crate::gpu::{GpuContext, GpuError};
use crate::mesh::{TetMesh, box_diagonal};
use crate::mode::{AutoPath, ModeSettings, textured_auto_needs};
use crate::render::{RenderError, Renderer};

pub use cage::{CageError, CageOptions, cage, cage_within};
pub use reference::TexturedReference;

/// The point array of texture coordinates a cage carries unless told otherwise.
pub const DEFAULT_TEXCOORDS: &str = "texcoords";

/// A scalar volume on a regular grid: `f32` samples, x fastest, with the world position of
/// sample 0 and the world distance between neighbouring samples along each axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    dims: [usize; 3],
    origin: DVec3,
    spacing: DVec3,
    values: Vec<f32>,
}

/// Why a volume could not be made.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum VolumeShapeError {
    /// The sample count disagrees with the dimensions.
    #[error("a volume of {dims:?} samples needs {expected} values, got {found}")]
    Count {
        /// Samples along x, y, z.
        dims: [usize; 3],
        /// Their product.
        expected: usize,
        /// Values given.
        found: usize,
    },
    /// An axis with fewer than 2 samples, or a spacing that is not positive and finite.
    #[error(
        "a volume needs at least 2 samples per axis and positive finite spacing; got {dims:?} samples spaced {spacing}"
    )]
    Shape {
        /// Samples along x, y, z.
        dims: [usize; 3],
        /// The spacing given.
        spacing: DVec3,
    },
    /// A sample that is NaN or infinite.
    #[error("sample {index} of the volume is {value}; every sample must be finite")]
    NonFinite {
        /// Its index (x fastest).
        index: usize,
        /// Its value.
        value: f32,
    },
}

impl Volume {
    /// A volume of `dims` samples (`values` x fastest), sample 0 at `origin`, `spacing` apart.
    pub fn new(
        dims: [usize; 3],
        origin: DVec3,
        spacing: DVec3,
        values: Vec<f32>,
    ) -> Result<Self, VolumeShapeError> {
        let expected = dims.iter().product::<usize>();
        if values.len() != expected {
            return Err(VolumeShapeError::Count {
                dims,
                expected,
                found: values.len(),
            });
        }
        let spaced = spacing.is_finite() && spacing.min_element() > 0.0;
        if dims.iter().any(|&d| d < 2) || !spaced {
            return Err(VolumeShapeError::Shape { dims, spacing });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            let value = values[index];
            return Err(VolumeShapeError::NonFinite { index, value });
        }
        Ok(Self {
            dims,
            origin,
            spacing,
            values,
        })
    }

    /// Reads a NIfTI-1 volume (`.nii`, `.nii.gz`) as `tetvr generate nifti` does, box-averaged
    /// by `downsample` (1 keeps every voxel); samples are placed where that command puts its
    /// vertices.
    pub fn load(path: impl AsRef<Path>, downsample: u32) -> Result<Self, VolumeError> {
        let opts = VolumeToTets {
            downsample,
            threshold: None,
        };
        let samples = read_samples_file(path.as_ref(), &opts)?;
        let f = downsample as f64;
        // Checked by the reader: at least 2 samples per axis, finite values, spacing non-zero.
        Ok(Self {
            dims: samples.dims,
            origin: samples.spacing * (f - 1.0) / 2.0,
            spacing: samples.spacing * f,
            values: samples.values.iter().map(|&v| v as f32).collect(),
        })
    }

    /// Checks that [`Self::load`] can read `path` from its header alone (and its length, when
    /// not gzipped), reading no voxel: a command refuses a bad volume before its mesh is read.
    pub fn check_file(path: impl AsRef<Path>) -> Result<(), VolumeError> {
        check_header_file(path.as_ref())
    }

    /// Samples along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The samples, x fastest.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// World position of sample 0.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    /// World distance between neighbouring samples along each axis.
    pub fn spacing(&self) -> DVec3 {
        self.spacing
    }

    /// The box of the sample centres: where the trilinear field is defined without clamping.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let n = DVec3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        );
        (self.origin, self.origin + (n - 1.0) * self.spacing)
    }

    /// The smallest and largest sample.
    pub fn range(&self) -> (f64, f64) {
        let (lo, hi) = self
            .values
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        (lo as f64, hi as f64)
    }

    /// The normalized texture coordinate of world point `p` (undeformed).
    pub fn texcoord(&self, p: DVec3) -> DVec3 {
        ((p - self.origin) / self.spacing + 0.5) / self.dims_f64()
    }

    fn dims_f64(&self) -> DVec3 {
        DVec3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        )
    }

    fn at(&self, i: usize, j: usize, k: usize) -> f64 {
        self.values[i + self.dims[0] * (j + self.dims[1] * k)] as f64
    }

    /// The trilinear interpolation of the samples at normalized texture coordinate `tc`, clamped
    /// to the edge samples outside (a GPU's linear filter with clamp-to-edge addressing, in f64).
    pub fn sample(&self, tc: DVec3) -> f64 {
        let x = tc * self.dims_f64() - 0.5;
        let axis = |a: usize| {
            let hi = (self.dims[a] - 1) as f64;
            let u = x[a].clamp(0.0, hi);
            let i = (u.floor() as usize).min(self.dims[a] - 2);
            (i, u - i as f64)
        };
        let ((i, fx), (j, fy), (k, fz)) = (axis(0), axis(1), axis(2));
        let lerp = |a: f64, b: f64, w: f64| a + (b - a) * w;
        let row = |j: usize, k: usize| lerp(self.at(i, j, k), self.at(i + 1, j, k), fx);
        let plane = |k: usize| lerp(row(j, k), row(j + 1, k), fy);
        lerp(plane(k), plane(k + 1), fz)
    }

    /// This volume box-averaged by `factor` along every axis (blocks sticking out at the upper
    /// ends dropped, as [`Volume::load`] does), with the sample positions moved to the blocks'
    /// centres; `None` when an axis would keep fewer than 2 samples.
    pub fn downsampled(&self, factor: usize) -> Option<Self> {
        let out = self.dims.map(|d| d / factor.max(1));
        if out.iter().any(|&d| d < 2) {
            return None;
        }
        let f = factor.max(1);
        let norm = 1.0 / (f * f * f) as f64;
        let mut values = Vec::with_capacity(out.iter().product());
        for k in 0..out[2] {
            for j in 0..out[1] {
                for i in 0..out[0] {
                    let mut sum = 0.0;
                    for (a, b, c) in block(f) {
                        sum += self.at(i * f + a, j * f + b, k * f + c);
                    }
                    values.push((sum * norm) as f32);
                }
            }
        }
        let f64f = f as f64;
        Some(Self {
            dims: out,
            origin: self.origin + self.spacing * (f64f - 1.0) / 2.0,
            spacing: self.spacing * f64f,
            values,
        })
    }
}

impl Volume {
    /// This volume, box-averaged by the smallest factor that brings every axis to at most
    /// `max` samples (a GPU's 3D texture size), and the factor (1: unchanged). Normalized
    /// texture coordinates keep their meaning exactly where the factor divides each axis, and
    /// shift by less than a sample of the result otherwise (the dropped remainder).
    pub fn fit_within(self, max: usize) -> (Self, usize) {
        let largest = self.dims.iter().copied().max().unwrap_or(0);
        if largest <= max {
            return (self, 1);
        }
        let factor = largest.div_ceil(max.max(1));
        match self.downsampled(factor) {
            Some(v) => (v, factor),
            None => (self, 1),
        }
    }
}

/// The offsets of an `f^3` block.
fn block(f: usize) -> impl Iterator<Item = (usize, usize, usize)> {
    (0..f).flat_map(move |c| (0..f).flat_map(move |b| (0..f).map(move |a| (a, b, c))))
}

/// The renderer of a textured cage in `mode`: `raycast` (GPU, [`RaycastRenderer::textured`]),
/// `shells` (GPU, either sampler, [`ShellsRenderer::textured`]), `raycast-cpu`
/// ([`CpuRaycastRenderer::textured`]), `reference` ([`TexturedReference`]) or `iso` (GPU, the
/// textured field's isosurfaces, [`RaycastRenderer::textured_iso`]); `auto`
/// takes the GPU ray caster on a hardware adapter, else the CPU one (the rule of
/// [`AutoPath`]). Other modes do not read textures yet (issue 12), which the error says.
/// `volume` must fit the adapter's 3D texture size ([`Volume::fit_within`]).
pub fn textured_renderer(
    mode: &ModeSettings,
    gpu: Option<&GpuContext>,
    cage: &TetMesh,
    volume: &Arc<Volume>,
    texcoords: &[DVec3],
) -> Result<Box<dyn Renderer>, RenderError> {
    let gpu_raycast = |gpu: &GpuContext, s: RaycastSettings| -> Result<Box<dyn Renderer>, _> {
        Ok(Box::new(RaycastRenderer::textured(
            gpu, cage, texcoords, volume, None, s,
        )?))
    };
    let cpu_raycast = |s: CpuRaycastSettings| -> Result<Box<dyn Renderer>, RenderError> {
        let tc = texcoords;
        Ok(Box::new(CpuRaycastRenderer::textured(
            cage,
            tc,
            volume.clone(),
            None,
            s,
        )?))
    };
    match (mode, gpu) {
        (ModeSettings::Raycast(s), Some(gpu)) => gpu_raycast(gpu, *s),
        (ModeSettings::Auto(_), Some(gpu))
            if AutoPath::for_gpu(Some(gpu), &textured_auto_needs()) == AutoPath::Gpu =>
        {
            gpu_raycast(gpu, RaycastSettings::default())
        }
        (ModeSettings::Auto(_), _) => cpu_raycast(CpuRaycastSettings::default()),
        (ModeSettings::RaycastCpu(s), _) => cpu_raycast(*s),
        (ModeSettings::Shells(s), Some(gpu)) => Ok(Box::new(ShellsRenderer::textured(
            gpu, cage, texcoords, volume, *s,
        )?)),
        (ModeSettings::Iso(s), Some(gpu)) => Ok(Box::new(RaycastRenderer::textured_iso(
            gpu,
            cage,
            texcoords,
            volume,
            None,
            RaycastSettings::default(),
            s,
        )?)),
        (ModeSettings::Reference(_), _) => Ok(Box::new(TexturedReference::new(
            cage,
            texcoords.to_vec(),
            volume.clone(),
            None,
        )?)),
        (ModeSettings::Shells(_), None) => Err(GpuError::NoAdapter {
            detail: " (--mode shells with --texture needs one; --mode raycast-cpu renders the \
                     textured cage on the CPU)"
                .into(),
        }
        .into()),
        (ModeSettings::Iso(_), None) => Err(GpuError::NoAdapter {
            detail: " (--mode iso with --texture needs one)".into(),
        }
        .into()),
        (ModeSettings::Raycast(_), None) => Err(GpuError::NoAdapter {
            detail: " (--mode raycast with --texture needs one; --mode raycast-cpu renders the \
                     textured cage on the CPU)"
                .into(),
        }
        .into()),
        (other, _) => Err(RenderError::Settings(format!(
            "--texture renders with --mode raycast (GPU), shells (GPU), iso (GPU), raycast-cpu or \
             reference; --mode {} does not read volume textures yet",
            other.name()
        ))),
    }
}

/// The texture coordinates of `mesh`'s vertices: its 3-component point array `name`.
pub fn texcoords(mesh: &TetMesh, name: &str) -> Result<Vec<DVec3>, CageError> {
    let array = mesh.point_vector(name).ok_or_else(|| {
        // Only when no vector has the name: a file may hold a scalar and a vector of one name.
        if mesh.arrays().iter().any(|a| a.name == name) {
            return CageError::ScalarTexcoords(name.to_owned());
        }
        CageError::NoTexcoords {
            name: name.to_owned(),
            available: mesh
                .point_vectors()
                .iter()
                .map(|a| a.name.clone())
                .collect(),
        }
    })?;
    if array.components != 3 {
        return Err(CageError::TexcoordComponents {
            name: name.to_owned(),
            components: array.components,
        });
    }
    Ok(array
        .tuples()
        .map(|t| DVec3::new(t[0], t[1], t[2]))
        .collect())
}

/// The most samples a textured renderer's step may take across its cage's bounding-box
/// diagonal. Every segment of a ray lies in that box, so a ray takes at most this many samples
/// (plus one per segment): the bound on its time, which without it was unbounded (a cage
/// scaled by 1e200 against its volume, at the default step of a quarter voxel, took 1e200
/// samples per ray: every textured renderer hung). Chosen from time: 2^20 is a thousand
/// times the samples of the default step across the blob and brain cages (1e2 to 1.4e3), room
/// for convergence studies, while a ray at the limit stays within a second: measured on the
/// 162-tet blob cage at the limit, 4x4 rays, 3 runs each, 2 cores shared with other builds: the
/// reference and raycast-cpu 290 to 370 ns per sample (about 0.3 s for a ray of 2^20),
/// lavapipe 5 to 22 ns. It is a power of two well below 2^24, so the GPU's f32 sample counter
/// (`k += 1.0`, which stops counting at 2^24) stays exact.
pub const MAX_SAMPLES_PER_RAY: f64 = (1u64 << 20) as f64;

/// The sampling step of a textured renderer of `cage`: `step`, or by default
/// [`reference::DEFAULT_STEP_FRACTION`] of `volume`'s smallest sample spacing; checked by
/// [`check_step`].
pub(crate) fn sampling_step(
    step: Option<f64>,
    volume: &Volume,
    cage: &TetMesh,
) -> Result<f64, RenderError> {
    let step = step.unwrap_or(reference::DEFAULT_STEP_FRACTION * volume.spacing().min_element());
    check_step(step, cage.bounds())?;
    Ok(step)
}

/// Checks a textured renderer's `step` against the cage's bounding box `(lo, hi)` (at build
/// and before every `update_positions`, which changes nothing when this refuses; there from
/// [`crate::mesh::checked_bounds`] of the new positions): a positive finite number of world units taking
/// at most [`MAX_SAMPLES_PER_RAY`] samples across the box's diagonal
/// ([`RenderError::TextureStep`]).
pub(crate) fn check_step(step: f64, (lo, hi): (DVec3, DVec3)) -> Result<(), RenderError> {
    if !(step.is_finite() && step > 0.0) {
        return Err(RenderError::Settings(format!(
            "texture step {step} must be a positive number of world units"
        )));
    }
    let diagonal = box_diagonal(lo, hi);
    // Exact: the limit is a power of two.
    let smallest = diagonal / MAX_SAMPLES_PER_RAY;
    if step < smallest {
        return Err(RenderError::TextureStep {
            step,
            diagonal,
            samples: diagonal / step,
            limit: MAX_SAMPLES_PER_RAY,
            smallest,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Volume {
        // Value x + 10 y + 100 z at sample (x, y, z) of a 3 x 2 x 2 grid, spacing (1, 2, 3).
        let values = (0..12)
            .map(|n| (n % 3 + 10 * ((n / 3) % 2) + 100 * (n / 6)) as f32)
            .collect();
        Volume::new([3, 2, 2], DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0), values).unwrap()
    }

    #[test]
    fn trilinear_is_exact_on_a_linear_field_and_clamps_outside() {
        let v = ramp();
        for p in [
            DVec3::ZERO,
            DVec3::new(1.5, 1.0, 1.5),
            DVec3::new(2.0, 2.0, 3.0),
        ] {
            let expected = p.x + 10.0 * p.y / 2.0 + 100.0 * p.z / 3.0;
            assert!((v.sample(v.texcoord(p)) - expected).abs() < 1e-12, "{p}");
        }
        // Beyond the last sample centre: the edge value.
        assert_eq!(v.sample(DVec3::new(1.0, 1.0, 1.0)), 112.0);
        assert_eq!(v.sample(DVec3::new(-1.0, 0.0, 0.0)), 0.0);
    }

    #[test]
    fn bad_volumes_are_refused_and_downsampling_averages_blocks() {
        let bad = Volume::new([2, 2, 2], DVec3::ZERO, DVec3::ONE, vec![0.0; 7]);
        assert!(matches!(bad, Err(VolumeShapeError::Count { .. })));
        let flat = Volume::new([2, 2, 1], DVec3::ZERO, DVec3::ONE, vec![0.0; 4]);
        assert!(matches!(flat, Err(VolumeShapeError::Shape { .. })));
        let nan = Volume::new([2, 2, 2], DVec3::ZERO, DVec3::ONE, vec![f32::NAN; 8]);
        assert!(matches!(nan, Err(VolumeShapeError::NonFinite { .. })));
        let values: Vec<f32> = (0..64).map(|n| n as f32).collect();
        let v = Volume::new([4, 4, 4], DVec3::ZERO, DVec3::ONE, values).unwrap();
        let half = v.downsampled(2).unwrap();
        assert_eq!(half.dims(), [2, 2, 2]);
        // Block (0, 0, 0) holds x + 4 y + 16 z for x, y, z in {0, 1}: mean 0.5 + 2 + 8.
        assert_eq!(half.values()[0], 10.5);
        assert_eq!(half.origin(), DVec3::splat(0.5));
        assert!(v.downsampled(3).is_none());
    }

    #[test]
    fn fit_within_downsamples_by_the_smallest_factor_that_fits() {
        let values: Vec<f32> = (0..6 * 4 * 2).map(|n| n as f32).collect();
        let v = Volume::new([6, 4, 2], DVec3::ZERO, DVec3::ONE, values).unwrap();
        let (same, factor) = v.clone().fit_within(6);
        assert_eq!((same.dims(), factor), ([6, 4, 2], 1));
        // 6 > 5: factor 2 gives 3 x 2 x 1, but an axis of 1 sample is no volume, so it stays.
        assert_eq!(v.clone().fit_within(5).1, 1);
        let big = Volume::new([8, 8, 8], DVec3::ZERO, DVec3::ONE, vec![1.0; 512]).unwrap();
        let (fitted, factor) = big.fit_within(3);
        assert_eq!((fitted.dims(), factor), ([2, 2, 2], 3));
        // Normalized coordinates keep their meaning where the factor divides the axis: the
        // texture coordinate of a world point is the same in both (8 = 2 x 4 with factor 4).
        let big = Volume::new([8, 8, 8], DVec3::ZERO, DVec3::ONE, vec![1.0; 512]).unwrap();
        let (four, _) = big.clone().fit_within(2);
        let p = DVec3::new(1.0, 2.5, 6.0);
        assert!((four.texcoord(p) - big.texcoord(p)).abs().max_element() < 1e-15);
    }
}
