//! Cages: coarse tet grids over a volume's box whose vertices carry the volume's texture
//! coordinates (`tetvr generate cage`). Any tet mesh with a 3-component point array of texture
//! coordinates is a cage; this makes the undeformed one.

use glam::{DVec3, UVec3};

use super::{DEFAULT_TEXCOORDS, Volume};
use crate::generate::volume::VolumeError;
use crate::generate::{GenerateError, check_target_tets, default_max_memory, hex_grid_mesh};
use crate::mesh::{DataArray, MeshError, TetMesh};

/// How [`cage`] grids a volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CageOptions {
    /// About this many tets over the whole box (6 per hexahedral cell, cells as near cubic as
    /// the box allows); a threshold keeps fewer.
    pub tets: u64,
    /// Keep only the cells where some sample of the trilinear field inside reaches this.
    pub threshold: Option<f64>,
}

/// Why a cage could not be made or used.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum CageError {
    /// The volume could not be read.
    #[error(transparent)]
    Volume(#[from] VolumeError),
    /// The grid could not be made (no tets, too many or too much memory asked for).
    #[error("cage: {0}")]
    Generate(#[from] GenerateError),
    /// The threshold is NaN or infinite.
    #[error("cage threshold {0} must be a finite number")]
    BadThreshold(f64),
    /// No cell reaches the threshold.
    #[error(
        "no cage cell reaches the threshold {threshold} (the volume ranges from {lo} to {hi}); lower it"
    )]
    AllBelowThreshold {
        /// The threshold given.
        threshold: f64,
        /// The smallest sample.
        lo: f64,
        /// The largest sample.
        hi: f64,
    },
    /// The mesh has no point array of that name.
    #[error(
        "the mesh has no point array '{name}' of texture coordinates (its multi-component point arrays: {available:?}); make a cage with `tetvr generate cage` or name the array with --texcoords"
    )]
    NoTexcoords {
        /// The array asked for.
        name: String,
        /// The point arrays of several components it has.
        available: Vec<String>,
    },
    /// The array named for the texture coordinates is a scalar point array.
    #[error(
        "point array '{0}' is a scalar (one value per vertex); texture coordinates need a point \
         array of 3 components per vertex (normalized u, v, w), such as the 'texcoords' that \
         `tetvr generate cage` writes; name one with --texcoords"
    )]
    ScalarTexcoords(String),
    /// The texture coordinate array is not 3 components per vertex.
    #[error(
        "point array '{name}' has {components} components per vertex; texture coordinates need 3"
    )]
    TexcoordComponents {
        /// The array.
        name: String,
        /// Its components per vertex.
        components: usize,
    },
    /// The cage mesh is invalid.
    #[error("cage: {0}")]
    Mesh(#[from] MeshError),
}

/// The undeformed cage of `volume`: a grid of hexahedra (6 tets each) over the box of its sample
/// centres ([`Volume::bounds`]), with the point array [`DEFAULT_TEXCOORDS`] (each vertex's
/// normalized texture coordinate) and the scalar array `intensity` (the volume sampled at each
/// vertex, for a coarse untextured preview and the default transfer-function range). At most
/// [`default_max_memory`] ([`cage_within`] takes another limit).
pub fn cage(volume: &Volume, opts: &CageOptions) -> Result<TetMesh, CageError> {
    cage_within(volume, opts, default_max_memory())
}

/// [`cage`] refused with [`GenerateError::OverMemory`] when it needs more than `max_memory`
/// bytes ([`crate::generate::memory_needed`]).
pub fn cage_within(
    volume: &Volume,
    opts: &CageOptions,
    max_memory: u64,
) -> Result<TetMesh, CageError> {
    check_target_tets(opts.tets)?;
    if let Some(t) = opts.threshold.filter(|t| !t.is_finite()) {
        return Err(CageError::BadThreshold(t));
    }
    let (lo, hi) = volume.bounds();
    let cells = cells_for(hi - lo, opts.tets);
    let step = (hi - lo) / cells.as_dvec3();
    let position = |v: UVec3| lo + v.as_dvec3() * step;
    let keep = |c: UVec3| match opts.threshold {
        None => true,
        Some(t) => cell_max(volume, position(c), position(c + UVec3::ONE)) >= t,
    };
    let value = |v: UVec3| volume.sample(volume.texcoord(position(v)));
    let mut mesh = hex_grid_mesh(cells, false, keep, position, value, "intensity", max_memory)
        .map_err(|e| match e {
            GenerateError::Mesh(MeshError::NoTets) => {
                let (lo, hi) = volume.range();
                let threshold = opts.threshold.unwrap_or(f64::NEG_INFINITY);
                CageError::AllBelowThreshold { threshold, lo, hi }
            }
            e => CageError::Generate(e),
        })?;
    let coords: Vec<f64> = mesh
        .positions()
        .iter()
        .flat_map(|&p| volume.texcoord(p).to_array())
        .collect();
    mesh.add_point_vectors(DataArray::new(DEFAULT_TEXCOORDS, 3, coords))?;
    Ok(mesh)
}

/// Cells per axis: about `tets / 6` cells in all, each as near a cube as the box allows (at
/// least one per axis).
fn cells_for(extent: DVec3, tets: u64) -> UVec3 {
    let cells = (tets as f64 / 6.0).max(1.0);
    let side = (extent.x * extent.y * extent.z / cells).cbrt();
    (extent / side).round().max(DVec3::ONE).as_uvec3()
}

/// The largest sample that the trilinear field on the box `[a, b]` (world) depends on: every
/// sample of the voxel cells the box touches, so a cell dropped for it is empty everywhere.
fn cell_max(volume: &Volume, a: DVec3, b: DVec3) -> f64 {
    let dims = volume.dims();
    let index = |p: DVec3, round: fn(f64) -> f64| {
        let x = (p - volume.origin()) / volume.spacing();
        [0, 1, 2].map(|k| (round(x[k]).max(0.0) as usize).min(dims[k] - 1))
    };
    let (i0, i1) = (index(a, f64::floor), index(b, f64::ceil));
    let mut max = f64::NEG_INFINITY;
    for k in i0[2]..=i1[2] {
        for j in i0[1]..=i1[1] {
            let row = dims[0] * (j + dims[1] * k);
            for &v in &volume.values()[row + i0[0]..=row + i1[0]] {
                max = max.max(v as f64);
            }
        }
    }
    max
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::texcoords;

    fn blob() -> Volume {
        // 9^3 samples, spacing 2: zero but for one bright sample at (6, 6, 6).
        let mut values = vec![0.0f32; 729];
        values[6 + 9 * (6 + 9 * 6)] = 5.0;
        Volume::new([9; 3], DVec3::ZERO, DVec3::splat(2.0), values).unwrap()
    }

    #[test]
    fn cage_covers_the_sample_box_with_matching_texcoords() {
        let v = blob();
        let m = cage(
            &v,
            &CageOptions {
                tets: 48,
                threshold: None,
            },
        )
        .unwrap();
        assert_eq!(m.tet_count(), 48);
        assert_eq!(m.bounds(), (DVec3::ZERO, DVec3::splat(16.0)));
        let tc = texcoords(&m, DEFAULT_TEXCOORDS).unwrap();
        // The corner vertices sit on the first and last sample centres: (0.5 / 9, 8.5 / 9).
        for (p, t) in m.positions().iter().zip(&tc) {
            let expected = (*p / 2.0 + 0.5) / 9.0;
            assert!((*t - expected).abs().max_element() < 1e-15);
        }
        let vol: f64 = (0..m.tet_count()).map(|t| m.signed_volume(t)).sum();
        assert!((vol - 16f64.powi(3)).abs() < 1e-9);
    }

    #[test]
    fn threshold_keeps_the_cells_the_bright_sample_reaches() {
        let v = blob();
        let opts = CageOptions {
            tets: 6 * 64,
            threshold: Some(1.0),
        };
        let m = cage(&v, &opts).unwrap();
        // Cells 4 units wide: the sample at 12 lies on the faces of cells 2 and 3 along each
        // axis, so 2^3 cells are kept.
        assert_eq!(m.tet_count(), 6 * 8);
        let high = CageOptions {
            threshold: Some(6.0),
            ..opts
        };
        assert!(matches!(
            cage(&v, &high),
            Err(CageError::AllBelowThreshold { hi: 5.0, .. })
        ));
        let zero = CageOptions { tets: 0, ..opts };
        assert_eq!(
            cage(&v, &zero).unwrap_err(),
            CageError::Generate(GenerateError::ZeroTets)
        );
    }
}
