//! A textured cage in the shells mode (issue 12; Georgii & Westermann 2006, section 3): the
//! volume as a 3D texture and the cage vertices' texture coordinates, uploaded once
//! ([`GpuTexture`], the ray caster's), read by the textured variants of both samplers
//! (`shaders/shells_texture.wgsl`). Moving the cage (`update_positions`) touches neither.
//!
//! Transfer-function culling needs each tet's scalar range, which for a textured tet is the
//! texture's range over the tet, not its vertices' values: [`tet_ranges`], taken once
//! (conservative). The other skips do not depend on the scalars.

use glam::DVec3;

use crate::gpu::GpuContext;
use crate::gpu::raycast::texture::GpuTexture;
use crate::gpu::util::{buffer_entry, entry, settings_error};
use crate::mesh::TetMesh;
use crate::render::RenderError;
use crate::texture::Volume;
use crate::texture::ranges::tet_ranges;

/// The volume texture, the texture coordinates, and each tet's range of the volume.
pub(super) struct ShellTexture {
    pub(super) gpu: GpuTexture,
    /// Per tet, a conservative (min, max) of the volume over it, in data units.
    pub(super) ranges: Vec<(f64, f64)>,
}

impl ShellTexture {
    /// Uploads `volume` and `cage`'s `texcoords` (one per vertex); an error when they do not
    /// fit the cage or the adapter.
    pub(super) fn new(
        ctx: &GpuContext,
        cage: &TetMesh,
        texcoords: &[DVec3],
        volume: &Volume,
    ) -> Result<Self, RenderError> {
        if texcoords.len() != cage.vertex_count() || cage.cell_scalars().is_some() {
            return Err(settings_error(format!(
                "a textured cage needs one texture coordinate per vertex ({} for {} vertices) \
                 and point data, not cell data",
                texcoords.len(),
                cage.vertex_count()
            )));
        }
        Ok(Self {
            gpu: GpuTexture::new(ctx, volume, texcoords)?,
            ranges: tet_ranges(volume, texcoords, cage.tets()),
        })
    }
}

/// The bindings of the textured stages (`shaders/shells_texture.wgsl`): 14 the texture
/// coordinates, read by `coords` (the raster's vertex stage or compute), 15 the volume, read
/// by `volume` (the raster's fragment stage or compute). The tets' vertex ids (13) are bound
/// for every shells stage (`shaders/tet_corners.wgsl`).
pub(super) fn layout_entries(
    coords: wgpu::ShaderStages,
    volume: wgpu::ShaderStages,
) -> [wgpu::BindGroupLayoutEntry; 2] {
    let ro = wgpu::BufferBindingType::Storage { read_only: true };
    [
        buffer_entry(14, coords, ro),
        wgpu::BindGroupLayoutEntry {
            binding: 15,
            visibility: volume,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D3,
                multisampled: false,
            },
            count: None,
        },
    ]
}

impl ShellTexture {
    /// The entries of [`layout_entries`].
    pub(super) fn entries(&self) -> [wgpu::BindGroupEntry<'_>; 2] {
        [
            entry(14, &self.gpu.texcoords),
            wgpu::BindGroupEntry {
                binding: 15,
                resource: wgpu::BindingResource::TextureView(&self.gpu.view),
            },
        ]
    }
}
