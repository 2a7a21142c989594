//! Isosurfaces of a textured cage on the GPU (`--mode iso --texture`, issue 12; Georgii &
//! Westermann 2006, figure 9): the ray caster's traversal (entries, tet to tet through face
//! adjacency, re-entry) with the isosurface integrator `shaders/raycast_texture_iso.wgsl` in
//! place of the volume integrator. Each tet segment is searched at the textured ray caster's
//! step for the first sign change of `field - isovalue`, refined to the crossing, and shaded
//! with the normal of the texture's gradient as iso mode shades
//! ([`crate::reference::iso::shade`]); the per-pixel hit (world normal, distance) comes back
//! with the picture. The f64 reference is [`crate::texture::iso`].

use std::sync::Arc;

use bytemuck::Zeroable;
use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::gpu::gpu_data::IsoUniforms;
use crate::gpu::iso::{DEFAULT_COLOR, IsoSettings, check_isovalues};
use crate::gpu::mesh::GpuTetMesh;
use crate::gpu::util::{
    Work, captured, captured_frame, read_mapped, settings_error, uniform_buffer,
};
use crate::mesh::TetMesh;
use crate::reference::iso::IsoImage;
use crate::render::{RenderError, Timings};
use crate::texture::Volume;
use crate::texture::ranges::tet_range;

use super::frame::{mappable, storage};
use super::texture::{GpuTexture, TextureUse};
use super::{RaycastRenderer, RaycastSettings};

/// A frame of a textured cage's isosurfaces: its targets and hits grow with the image.
pub(super) const FRAME: Work = Work::of_frame("a textured iso frame");
/// The isosurfaces' build: the volume, the cage's links and boundary, the tets' ranges.
const TEXTURED_BUILD: Work = Work::of_texture("building the iso renderer of a textured cage");

/// A textured cage's isovalues (data units of the volume, with their colours), their uniform
/// block (WGSL `Iso`, normalized like the texels) and each tet's range of the field.
pub(super) struct TexturedIso {
    pub(super) isovalues: Vec<(f64, [f32; 3])>,
    pub(super) uniforms: wgpu::Buffer,
    /// Per tet the least and greatest texel its trilinear field can read
    /// ([`upload_tet_ranges`]), normalized: the traversal skips a tet whose range holds no
    /// isovalue.
    pub(super) ranges: wgpu::Buffer,
}

/// Uploads per tet of `cage` (vertices at `texcoords`) the least and greatest texel the
/// trilinear field can read inside it ([`crate::texture::ranges::tet_range`]), normalized as
/// the texels (`(v - lo) / span`), computed straight into the upload's staging memory. Texture
/// coordinates never change, so neither do the ranges when the cage deforms. A tet whose range
/// holds no isovalue has all its samples on one side of each: skipping it changes no hit.
fn upload_tet_ranges(
    ctx: &GpuContext,
    cage: &TetMesh,
    texcoords: &[DVec3],
    volume: &Volume,
) -> wgpu::Buffer {
    let (lo, hi) = volume.range();
    let span = if hi > lo { hi - lo } else { 1.0 };
    let norm = |v: f64| ((v - lo) / span) as f32;
    let tets = cage.tets();
    let ranges = storage(&ctx.device, "textured iso tet ranges", 8 * tets.len());
    ctx.uploader().entries(&ranges, 0, tets.len(), |t| {
        let (least, most) = tet_range(volume, texcoords, tets[t]);
        [norm(least), norm(most)]
    });
    ranges
}

impl TexturedIso {
    /// `isovalues` (empty: the middle of the volume's range, light grey) uploaded for
    /// `texture`, and the tets' ranges of `cage` (vertices at `texcoords` into `volume`).
    fn new(
        ctx: &GpuContext,
        isovalues: &[(f64, [f32; 3])],
        texture: &GpuTexture,
        cage: &TetMesh,
        texcoords: &[DVec3],
        volume: &Volume,
    ) -> Result<Self, RenderError> {
        check_isovalues(isovalues)?;
        let isovalues = match isovalues {
            [] => vec![(texture.lo + 0.5 * texture.span, DEFAULT_COLOR)],
            given => given.to_vec(),
        };
        let mut iso = IsoUniforms::zeroed();
        for (k, &(v, c)) in isovalues.iter().enumerate() {
            iso.values[k / 4][k % 4] = ((v - texture.lo) / texture.span) as f32;
            iso.colors[k] = [c[0], c[1], c[2], 1.0];
        }
        iso.count = isovalues.len() as u32;
        let uniforms = uniform_buffer(&ctx.device, "textured iso", size_of::<IsoUniforms>());
        ctx.queue
            .write_buffer(&uniforms, 0, bytemuck::bytes_of(&iso));
        Ok(Self {
            isovalues,
            uniforms,
            ranges: upload_tet_ranges(ctx, cage, texcoords, volume),
        })
    }
}

/// Per pixel the hit's world normal and distance (`[nx, ny, nz, t]`, `t = 0`: no hit),
/// written by the traversal, and its mappable copy.
#[derive(Clone)]
pub(super) struct HitBuffers {
    pub(super) hits: wgpu::Buffer,
    readback: wgpu::Buffer,
}

impl HitBuffers {
    pub(super) fn new(device: &wgpu::Device, pixels: usize) -> Self {
        Self {
            hits: storage(device, "textured iso hits", 16 * pixels),
            readback: mappable(device, "textured iso hits readback", 16 * pixels.max(1)),
        }
    }

    /// Copies the hits to their readback.
    pub(super) fn copy(&self, enc: &mut wgpu::CommandEncoder) {
        enc.copy_buffer_to_buffer(&self.hits, 0, &self.readback, 0, self.readback.size());
    }

    pub(super) fn size(&self) -> u64 {
        self.hits.size() + self.readback.size()
    }

    /// Each pixel's distance in the f32 frame (infinite on a miss) and unit world normal (zero
    /// on a miss), from the last copy.
    fn read(&self, device: &wgpu::Device) -> Result<(Vec<f32>, Vec<[f32; 3]>), RenderError> {
        let out = {
            let data = read_mapped(device, &self.readback, "the textured iso hits")?;
            let hits: &[[f32; 4]] = bytemuck::cast_slice(&data);
            hits.iter()
                .map(|h| match h[3] > 0.0 {
                    true => (h[3], [h[0], h[1], h[2]]),
                    false => (f32::INFINITY, [0.0; 3]),
                })
                .unzip()
        };
        self.readback.unmap();
        Ok(out)
    }
}

impl RaycastRenderer {
    /// The isosurfaces of a textured cage (issue 12; see the module docs): `cage`'s vertices
    /// carry `texcoords` into `volume`, each tet segment is searched every `step` world units
    /// (`None`: the textured ray caster's default); `iso.isovalues` are in the volume's units
    /// (empty: the middle of its range). `iso.shading` is not used: the normals are always the
    /// texture's gradient. [`crate::render::Renderer::update_positions`] bends the surfaces,
    /// normals included, with the cage.
    pub fn textured_iso(
        ctx: &GpuContext,
        cage: &TetMesh,
        texcoords: &[DVec3],
        volume: &Volume,
        step: Option<f64>,
        settings: RaycastSettings,
        iso: &IsoSettings,
    ) -> Result<Self, RenderError> {
        super::check_limits(ctx, settings.entry, Some(TextureUse::Isosurfaces))?;
        captured(&ctx.device, TEXTURED_BUILD, || {
            let texture = GpuTexture::for_cage(ctx, cage, volume, texcoords, step)?;
            let surfaces =
                TexturedIso::new(ctx, &iso.isovalues, &texture, cage, texcoords, volume)?;
            let mesh: Arc<GpuTetMesh> = GpuTetMesh::new(ctx, cage)?;
            let textured = Some((texture, TextureUse::Isosurfaces));
            let mut renderer = Self::build(ctx, mesh, settings, textured, false)?;
            renderer.iso = Some(surfaces);
            Ok(renderer)
        })
    }

    /// The isovalues (volume units) and colours drawn; `None` unless built by
    /// [`RaycastRenderer::textured_iso`].
    pub fn textured_isovalues(&self) -> Option<&[(f64, [f32; 3])]> {
        self.iso.as_ref().map(|i| i.isovalues.as_slice())
    }

    /// Renders `camera`'s view of a textured cage's isosurfaces: the shaded colour and each
    /// pixel's hit distance and world normal (the conventions of [`IsoImage`]), and the
    /// frame's timings. An error unless built by [`RaycastRenderer::textured_iso`].
    pub fn render_surface(&mut self, camera: &Camera) -> Result<(IsoImage, Timings), RenderError> {
        camera.validate()?;
        if self.iso.is_none() {
            return Err(settings_error(
                "render_surface draws a textured cage's isosurfaces: build the renderer with \
                 RaycastRenderer::textured_iso",
            ));
        }
        // A lost device fails here as an error, not as wgpu's panic (as `render` does).
        let (frame, (depth, normal)) = captured_frame(self, FRAME, |r| {
            let frame = r.frame(&r.mesh.frame().camera(camera), None)?;
            let hits = (r.targets.as_ref()).and_then(|t| t.hits.as_ref());
            let hits = hits.ok_or(RenderError::Internal("the iso hit buffers are missing"))?;
            Ok((frame, hits.read(&r.device)?))
        })?;
        let f32_frame = self.mesh.frame();
        // World units in f64: beyond f32's range for a cage of extent past about 1e38.
        let depth = (depth.iter())
            .map(|&d| match d.is_finite() {
                true => f32_frame.world_length(d as f64),
                false => f64::INFINITY,
            })
            .collect();
        let surface = IsoImage {
            color: frame.image,
            depth,
            normal,
        };
        Ok((surface, frame.timings))
    }
}
