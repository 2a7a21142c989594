//! Scalar volumes (NIfTI-1 `.nii` / `.nii.gz`) to tetrahedral meshes.
//!
//! Vertices are voxel centres; each cell between 8 neighbouring voxel centres is a hexahedron
//! split into 6 conforming tets ([`crate::mesh::split`]). The voxel `(i, j, k)` lies at
//! `(i, j, k) * pixdim[1..4]`, so voxel 0's centre is the origin and the mesh has the volume's
//! physical size; the file's qform/sform affine (orientation, origin) is deliberately not
//! applied, only the spacing. Intensities are the stored values with the header's
//! `scl_slope`/`scl_inter` applied, in one scalar array named `intensity`.

use std::path::Path;

use glam::{DVec3, UVec3};
use nifti::{IntoNdArray, NiftiObject, ReaderOptions};
use rayon::prelude::*;

use super::{GenerateError, hex_grid_mesh};
use crate::mesh::{MeshError, TetMesh};

/// How [`nifti_to_tets`] turns voxels into tets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeToTets {
    /// Box-average downsampling factor (at least 1): each vertex is the mean of a block of
    /// `downsample^3` voxels, placed at the block's centre. Blocks that would stick out of the
    /// volume at its upper ends are dropped.
    pub downsample: u32,
    /// Drop the cells whose 8 corner values are all below this value (the background).
    pub threshold: Option<f64>,
}

impl Default for VolumeToTets {
    /// Every voxel, every cell.
    fn default() -> Self {
        Self {
            downsample: 1,
            threshold: None,
        }
    }
}

/// Why a volume could not be turned into tets; every message names the file.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum VolumeError {
    /// The file is missing or not NIfTI-1.
    #[error("{path}: cannot read it as NIfTI-1 (.nii or .nii.gz): {message}")]
    Read {
        /// The volume file.
        path: String,
        /// The reader's message.
        message: String,
    },
    /// The volume is not three-dimensional.
    #[error(
        "{path}: has dimensions {dims:?}; tetvr needs a 3D scalar volume (x, y, z, and any further dimension of size 1)"
    )]
    NotVolume3d {
        /// The volume file.
        path: String,
        /// Its dimensions.
        dims: Vec<usize>,
    },
    /// A downsample factor of 0.
    #[error("{path}: downsample factor {factor} is invalid; use 1 (every voxel) or more")]
    BadDownsample {
        /// The volume file.
        path: String,
        /// The factor given.
        factor: u32,
    },
    /// Downsampling leaves no cell along some axis.
    #[error(
        "{path}: downsampling {dims:?} voxels by {factor} leaves fewer than 2 samples along an axis; use a smaller factor"
    )]
    TooSmall {
        /// The volume file.
        path: String,
        /// Voxels along x, y, z.
        dims: [usize; 3],
        /// The factor given.
        factor: u32,
    },
    /// The header's voxel spacing is zero or not finite.
    #[error("{path}: voxel spacing pixdim[1..4] = {spacing:?} must be non-zero and finite")]
    BadSpacing {
        /// The volume file.
        path: String,
        /// pixdim[1..4] of the header.
        spacing: [f32; 3],
    },
    /// A voxel value is NaN or infinite.
    #[error("{path}: voxel ({x}, {y}, {z}) has the non-finite value {value}")]
    NonFinite {
        /// The volume file.
        path: String,
        /// The voxel's x index.
        x: usize,
        /// The voxel's y index.
        y: usize,
        /// The voxel's z index.
        z: usize,
        /// Its value.
        value: f64,
    },
    /// The threshold is NaN or infinite.
    #[error("{path}: threshold {threshold} must be a finite number")]
    BadThreshold {
        /// The volume file.
        path: String,
        /// The threshold given.
        threshold: f64,
    },
    /// The threshold drops every cell.
    #[error(
        "{path}: every cell is below the threshold {threshold} (intensities range from {lo} to {hi}); lower it"
    )]
    AllBelowThreshold {
        /// The volume file.
        path: String,
        /// The threshold given.
        threshold: f64,
        /// The smallest intensity.
        lo: f64,
        /// The largest intensity.
        hi: f64,
    },
    /// The tets could not be made (too many of them).
    #[error("{path}: {source}")]
    Generate {
        /// The volume file.
        path: String,
        /// Why the generator refused.
        source: GenerateError,
    },
}

/// Reads the NIfTI-1 volume at `path` (gzip-compressed if it ends in `.gz`) and splits it into
/// tets as the [module docs](self) describe, with `opts`' downsampling and threshold.
pub fn nifti_to_tets(path: impl AsRef<Path>, opts: &VolumeToTets) -> Result<TetMesh, VolumeError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let factor = opts.downsample;
    if factor == 0 {
        return Err(VolumeError::BadDownsample { path: name, factor });
    }
    if let Some(threshold) = opts.threshold.filter(|t| !t.is_finite()) {
        return Err(VolumeError::BadThreshold {
            path: name,
            threshold,
        });
    }
    let read_error = |e: nifti::NiftiError| VolumeError::Read {
        path: name.clone(),
        message: match e {
            // The crate shows I/O errors in Debug form; the io::Error reads better.
            nifti::NiftiError::Io(io) => io.to_string(),
            other => other.to_string(),
        },
    };
    let object = ReaderOptions::new().read_file(path).map_err(read_error)?;
    let pixdim = object.header().pixdim;
    let spacing = [pixdim[1], pixdim[2], pixdim[3]];
    if spacing.iter().any(|s| !(s.is_finite() && *s != 0.0)) {
        return Err(VolumeError::BadSpacing {
            path: name,
            spacing,
        });
    }
    let spacing = DVec3::from(spacing.map(|s| s.abs() as f64));
    let array = object
        .into_volume()
        .into_ndarray::<f64>()
        .map_err(read_error)?;
    let shape = array.shape().to_vec();
    if shape.len() < 3 || shape[3..].iter().any(|&d| d != 1) {
        return Err(VolumeError::NotVolume3d {
            path: name,
            dims: shape,
        });
    }
    let dims = [shape[0], shape[1], shape[2]];
    // Reversing the axes makes x the fastest index of the logical order, whatever the layout.
    let voxels: Vec<f64> = array.reversed_axes().iter().copied().collect();
    if let Some(i) = voxels.par_iter().position_first(|v| !v.is_finite()) {
        return Err(VolumeError::NonFinite {
            path: name,
            x: i % dims[0],
            y: i / dims[0] % dims[1],
            z: i / (dims[0] * dims[1]),
            value: voxels[i],
        });
    }
    let (samples, sdims) = box_average(voxels, dims, factor as usize);
    if sdims.iter().any(|&d| d < 2) || sdims.iter().any(|&d| d > u32::MAX as usize) {
        return Err(VolumeError::TooSmall {
            path: name,
            dims,
            factor,
        });
    }
    let sdims = UVec3::new(sdims[0] as u32, sdims[1] as u32, sdims[2] as u32);
    let at = |v: UVec3| {
        samples[v.x as usize + sdims.x as usize * (v.y as usize + sdims.y as usize * v.z as usize)]
    };
    let keep = |c: UVec3| match opts.threshold {
        None => true,
        Some(t) => (0..8u32).any(|k| at(c + UVec3::new(k & 1, (k >> 1) & 1, k >> 2)) >= t),
    };
    // A block's centre in voxel units: the mean of its voxels' indices.
    let half = (factor as f64 - 1.0) / 2.0;
    let position = |v: UVec3| (v.as_dvec3() * factor as f64 + half) * spacing;
    hex_grid_mesh(sdims - UVec3::ONE, false, keep, position, at, "intensity").map_err(|e| match e {
        GenerateError::Mesh(MeshError::NoTets) => {
            let (lo, hi) = samples
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            VolumeError::AllBelowThreshold {
                path: name.clone(),
                threshold: opts.threshold.unwrap_or(f64::NEG_INFINITY),
                lo,
                hi,
            }
        }
        source => VolumeError::Generate {
            path: name.clone(),
            source,
        },
    })
}

/// Means of `f^3` blocks of `voxels` (x fastest, `dims`), dropping incomplete blocks at the
/// upper ends; returns the samples (x fastest) and their dimensions.
fn box_average(voxels: Vec<f64>, dims: [usize; 3], f: usize) -> (Vec<f64>, [usize; 3]) {
    let out = dims.map(|d| d / f);
    if f == 1 {
        return (voxels, out);
    }
    let norm = 1.0 / (f * f * f) as f64;
    let samples = (0..out[0] * out[1] * out[2])
        .into_par_iter()
        .map(|o| {
            let (i, j, k) = (o % out[0], o / out[0] % out[1], o / (out[0] * out[1]));
            let mut sum = 0.0;
            for c in k * f..(k + 1) * f {
                for b in j * f..(j + 1) * f {
                    let row = dims[0] * (b + dims[1] * c);
                    sum += voxels[row + i * f..row + (i + 1) * f].iter().sum::<f64>();
                }
            }
            sum * norm
        })
        .collect();
    (samples, out)
}
