//! A textured cage's GPU side (issue 12): the volume as a 3D texture and the cage vertices'
//! texture coordinates, both uploaded once. Moving the cage ([`GpuTetMesh::update_positions`]
//! through the renderer) touches neither: the volume moves with the cage at the cost of one
//! upload of the cage's positions.
//!
//! [`GpuTetMesh::update_positions`]: crate::gpu::mesh::GpuTetMesh::update_positions

use glam::DVec3;

use crate::gpu::GpuContext;
use crate::gpu::util::{Work, captured, settings_error};
use crate::mesh::TetMesh;
use crate::render::RenderError;
use crate::texture::{Volume, sampling_step};

use super::frame::storage;

/// The upload of a volume and its cage's texture coordinates ([`GpuTexture::new`]).
const UPLOAD: Work = Work::of_texture("uploading the volume texture");

/// What the traversal does with a textured cage's field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureUse {
    /// Direct volume rendering: the TF integrated by stepping (`shaders/raycast_texture.wgsl`).
    Volume,
    /// The first isosurface hit (`shaders/raycast_texture_iso.wgsl`, [`super::texture_iso`]).
    Isosurfaces,
}

/// The volume texture (R32Float, values normalized to [0, 1] by the volume's range), the
/// texture coordinates (vec4 per vertex, w unused) and the sampling step. A clone shares the
/// GPU objects (the shells' walk sampler reads its renderer's).
#[derive(Clone)]
pub struct GpuTexture {
    texture: wgpu::Texture,
    pub(crate) view: wgpu::TextureView,
    pub(crate) texcoords: wgpu::Buffer,
    /// The volume's smallest sample and range: texels are `(v - lo) / span`.
    pub(crate) lo: f64,
    pub(crate) span: f64,
    /// World units between samples along a ray (WGSL `params.step` takes it in the mesh's
    /// frame); `None` for the shells' texture, whose slices sample it instead.
    pub(super) step: Option<f64>,
}

impl GpuTexture {
    /// [`GpuTexture::new`] for `cage`, sampled along rays every `step` world units (`None`:
    /// the reference's default,
    /// [`crate::texture::reference::DEFAULT_STEP_FRACTION`] of the smallest sample spacing),
    /// after checking that it has one texture coordinate per vertex and point data, and the
    /// step ([`crate::texture::check_step`]).
    pub(super) fn for_cage(
        ctx: &GpuContext,
        cage: &TetMesh,
        volume: &Volume,
        texcoords: &[DVec3],
        step: Option<f64>,
    ) -> Result<Self, RenderError> {
        if texcoords.len() != cage.vertex_count() || cage.cell_scalars().is_some() {
            return Err(settings_error(format!(
                "a textured cage needs one texture coordinate per vertex ({} for {} vertices) \
                 and point data, not cell data",
                texcoords.len(),
                cage.vertex_count()
            )));
        }
        let step = sampling_step(step, volume, cage)?;
        Ok(Self {
            step: Some(step),
            ..Self::new(ctx, volume, texcoords)?
        })
    }

    /// Uploads `volume` and the cage's `texcoords` (one per vertex), not stepped along rays
    /// (the shells' slices sample it; the ray caster's `GpuTexture::for_cage` steps). An error when the
    /// volume exceeds the adapter's 3D texture size ([`Volume::fit_within`] makes it fit).
    pub fn new(
        ctx: &GpuContext,
        volume: &Volume,
        texcoords: &[DVec3],
    ) -> Result<Self, RenderError> {
        let max = ctx.limits.max_texture_dimension_3d;
        let dims = volume.dims();
        if dims.iter().any(|&d| d > max as usize) {
            return Err(settings_error(format!(
                "the volume's {dims:?} samples exceed this adapter's 3D texture size {max}; \
                 downsample it (Volume::fit_within)"
            )));
        }
        let (lo, hi) = volume.range();
        let span = if hi > lo { hi - lo } else { 1.0 };
        let texels: Vec<f32> = (volume.values().iter())
            .map(|&v| ((v as f64 - lo) / span) as f32)
            .collect();
        captured(&ctx.device, UPLOAD, || {
            let texture = upload_volume(ctx, dims, &texels);
            let buffer = storage(
                &ctx.device,
                "cage texture coordinates",
                16 * texcoords.len(),
            );
            ctx.uploader().entries(&buffer, 0, texcoords.len(), |v| {
                let t = texcoords[v];
                [t.x as f32, t.y as f32, t.z as f32, 0.0]
            });
            Ok(Self {
                view: texture.create_view(&Default::default()),
                texture,
                texcoords: buffer,
                lo,
                span,
                step: None,
            })
        })
    }

    /// Bytes on the GPU: the texture (4 per sample) and the coordinates (16 per vertex).
    pub fn bytes(&self) -> u64 {
        let e = self.texture.size();
        4 * e.width as u64 * e.height as u64 * e.depth_or_array_layers as u64
            + self.texcoords.size()
    }
}

fn upload_volume(ctx: &GpuContext, dims: [usize; 3], texels: &[f32]) -> wgpu::Texture {
    let size = wgpu::Extent3d {
        width: dims[0] as u32,
        height: dims[1] as u32,
        depth_or_array_layers: dims[2] as u32,
    };
    let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("cage volume texture"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    ctx.queue.write_texture(
        texture.as_image_copy(),
        bytemuck::cast_slice(texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(4 * size.width),
            rows_per_image: Some(size.height),
        },
        size,
    );
    texture
}
