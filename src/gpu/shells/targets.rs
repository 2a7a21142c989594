//! The shells targets of one image size: the slice layers the raster writes, the accumulation
//! target the composite blends under, its readback, and (with early ray termination) the
//! termination mask and the tile flags.

use crate::gpu::frame::ImageReadback;
use crate::gpu::util::{entry, texture_2d};

use super::ERT_DEPTH;
use super::config::TargetFormats;
use super::pipelines::ErtPipelines;
use super::skips::TileMask;

/// Image-size-dependent targets, rebuilt when the size changes (a clone shares them).
#[derive(Clone)]
pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    /// One view per slice layer (a colour target of 4 slices).
    pub(super) layer_views: Vec<wgpu::TextureView>,
    /// All layers, as the composite reads them.
    pub(super) slices_view: wgpu::TextureView,
    pub(super) accum: wgpu::Texture,
    pub(super) accum_view: wgpu::TextureView,
    pub(super) readback: ImageReadback,
    pub(super) ert: Option<ErtTargets>,
}

/// The early-ray-termination mask and tile flags of one image size.
#[derive(Clone)]
pub(super) struct ErtTargets {
    pub(super) depth_view: wgpu::TextureView,
    pub(super) mark_group: wgpu::BindGroup,
    pub(super) tiles_group: wgpu::BindGroup,
    /// One u32 per tile: nonzero where a pixel is unfinished.
    pub(super) flags: wgpu::Buffer,
    pub(super) flags_readback: wgpu::Buffer,
    pub(super) tiles: (u32, u32),
}

impl Targets {
    /// The targets of a `width` x `height` image with the slice layers and accumulation
    /// target of `formats`.
    pub(super) fn new(
        device: &wgpu::Device,
        (width, height): (u32, u32),
        formats: TargetFormats,
        ert: Option<&ErtPipelines>,
    ) -> Self {
        let TargetFormats {
            slices: format,
            accum: accum_format,
            layers,
        } = formats;
        use wgpu::TextureUsages as U;
        let slices = texture_2d(
            device,
            "shells slices",
            (width, height, layers),
            format,
            U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
        );
        let layer_views = (0..layers)
            .map(|i| {
                slices.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("shells slice layer"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: i,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let slices_view = slices.create_view(&wgpu::TextureViewDescriptor {
            label: Some("shells slices"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let accum_usage = U::RENDER_ATTACHMENT | U::COPY_SRC | U::TEXTURE_BINDING;
        let accum = texture_2d(
            device,
            "shells accumulation",
            (width, height, 1),
            accum_format,
            accum_usage,
        );
        let accum_view = accum.create_view(&Default::default());
        let ert = ert.map(|p| ErtTargets::new(device, (width, height), p, &accum_view));
        Self {
            width,
            height,
            layer_views,
            slices_view,
            accum,
            accum_view,
            readback: ImageReadback::new(device, "shells readback", width, height, accum_format),
            ert,
        }
    }

    /// Bytes of the targets: the slice layers and the accumulation target of `formats`, and
    /// the readback buffer.
    pub(super) fn size(&self, formats: TargetFormats) -> u64 {
        let texel = |f: wgpu::TextureFormat| f.block_copy_size(None).unwrap_or(16) as u64;
        let slices = texel(formats.slices) * formats.layers as u64;
        let pixels = self.width as u64 * self.height as u64;
        pixels * (slices + texel(formats.accum)) + self.readback.size()
    }
}

impl ErtTargets {
    fn new(
        device: &wgpu::Device,
        (width, height): (u32, u32),
        p: &ErtPipelines,
        accum_view: &wgpu::TextureView,
    ) -> Self {
        let depth = texture_2d(
            device,
            "shells termination mask",
            (width, height, 1),
            ERT_DEPTH,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let tiles = TileMask::dims(width, height);
        let bytes = 4 * tiles.0 as u64 * tiles.1 as u64;
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as B;
        let flags = buffer("shells tile flags", B::STORAGE | B::COPY_SRC | B::COPY_DST);
        let flags_readback = buffer("shells tile flags readback", B::MAP_READ | B::COPY_DST);
        let accum_entry = wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(accum_view),
        };
        let mark_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shells mark"),
            layout: &p.mark_layout,
            entries: std::slice::from_ref(&accum_entry),
        });
        let tiles_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shells tiles"),
            layout: &p.tiles_layout,
            entries: &[accum_entry.clone(), entry(1, &flags)],
        });
        Self {
            depth_view: depth.create_view(&Default::default()),
            mark_group,
            tiles_group,
            flags,
            flags_readback,
            tiles,
        }
    }
}
