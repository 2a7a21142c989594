//! What the adapter and the settings make of a shells renderer: the slice format, the slices
//! per shell (fixed, or the candidates chosen among per frame), and the checks of the other
//! settings.

use crate::gpu::util::settings_error;
use crate::gpu::{GpuContext, GpuError, shaders};
use crate::render::RenderError;

use super::{SOFTWARE_SLICES_PER_SHELL, Sampler, ShellSettings, SliceFormat, adaptive};

/// The formats of a renderer's slice and accumulation targets, and its slice layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct TargetFormats {
    /// The slice targets' format.
    pub(super) slices: wgpu::TextureFormat,
    /// The accumulation target's format: 32-bit floats wherever the adapter blends them, even
    /// under 16-bit slices (the rounding of every blend into it would cost more than the
    /// slices' quantization; docs/performance.md, 16-bit slices).
    pub(super) accum: wgpu::TextureFormat,
    /// Layers of the slice texture: the colour targets of the largest count in use.
    pub(super) layers: u32,
}

/// The slice configuration of a renderer.
pub(super) struct SliceConfig {
    pub(super) targets: TargetFormats,
    /// The fixed slices per shell, or `None` when chosen per frame among `candidates`.
    pub(super) fixed: Option<u32>,
    /// The count used without adaptive slices, and kept by them unless another is predicted
    /// to be clearly cheaper.
    pub(super) default: u32,
    pub(super) candidates: Vec<u32>,
    pub(super) model: adaptive::CostModel,
}

/// The slice format for `format` on `ctx`'s adapter, and its bytes per texel.
fn format(
    ctx: &GpuContext,
    format: SliceFormat,
) -> Result<(wgpu::TextureFormat, u32), RenderError> {
    let blendable32 = ctx.features.contains(wgpu::Features::FLOAT32_BLENDABLE);
    match (format, blendable32) {
        (SliceFormat::Auto, true) | (SliceFormat::Float32, true) => {
            Ok((wgpu::TextureFormat::Rgba32Float, 16))
        }
        (SliceFormat::Float32, false) => Err(RenderError::Gpu(GpuError::Missing {
            adapter: ctx.info.name.clone(),
            what: "blendable 32-bit float targets (FLOAT32_BLENDABLE)".into(),
            needed_by: "the shells mode with 32-bit slices (use the 16-bit or auto format)",
        })),
        (SliceFormat::Auto, false) | (SliceFormat::Float16, _) => {
            Ok((wgpu::TextureFormat::Rgba16Float, 8))
        }
    }
}

/// The slice configuration of `settings` on `ctx`'s adapter; an error when the adapter has no
/// usable colour target or the slices per shell are out of its range.
pub(super) fn slices(
    ctx: &GpuContext,
    settings: &ShellSettings,
) -> Result<SliceConfig, RenderError> {
    let limits = &ctx.limits;
    let (format, bytes) = format(ctx, settings.format)?;
    let accum = if ctx.features.contains(wgpu::Features::FLOAT32_BLENDABLE) {
        wgpu::TextureFormat::Rgba32Float
    } else {
        format
    };
    let max_targets = shaders::MAX_TARGETS
        .min(limits.max_color_attachments)
        .min(limits.max_color_attachment_bytes_per_sample / bytes);
    if max_targets == 0 {
        return Err(RenderError::Gpu(GpuError::Missing {
            adapter: ctx.info.name.clone(),
            what: format!("one {format:?} colour target"),
            needed_by: "the shells mode",
        }));
    }
    let software = ctx.info.device_type == wgpu::DeviceType::Cpu;
    let default = if software {
        (4 * max_targets).min(SOFTWARE_SLICES_PER_SHELL)
    } else {
        4 * max_targets
    };
    let fixed = match settings.slices_per_shell {
        None if settings.skips.adaptive_slices => None,
        n => Some(n.unwrap_or(default)),
    };
    let slices_per_shell = fixed.unwrap_or(default);
    if !(1..=4 * max_targets).contains(&slices_per_shell) {
        return Err(settings_error(format!(
            "slices per shell must be between 1 and {} on this adapter ({} {format:?} \
             targets of 4 slices), not {slices_per_shell}",
            4 * max_targets,
            max_targets
        )));
    }
    let (candidates, layers) = match fixed {
        Some(n) => (Vec::new(), n.div_ceil(4)),
        None => (adaptive::candidates(4 * max_targets), max_targets),
    };
    Ok(SliceConfig {
        targets: TargetFormats {
            slices: format,
            accum,
            layers,
        },
        fixed,
        default,
        candidates,
        model: if software {
            adaptive::CostModel::SOFTWARE
        } else {
            adaptive::CostModel::GPU
        },
    })
}

/// An error naming the first setting out of range: samples, dz, the termination threshold,
/// epsilon, and what the walk sampler cannot honour.
pub(super) fn check(settings: &ShellSettings) -> Result<(), RenderError> {
    check_walk(settings)?;
    if settings.samples == 0 {
        return Err(settings_error("samples per ray must be at least 1"));
    }
    if let Some(dz) = settings.dz
        && !(dz.is_finite() && dz > 0.0)
    {
        return Err(settings_error(format!(
            "slice spacing dz must be positive and finite, not {dz}"
        )));
    }
    let threshold = settings.skips.ert_threshold;
    if !(threshold > 0.0 && threshold <= 1.0) {
        return Err(settings_error(format!(
            "the early ray termination threshold must be in (0, 1], not {threshold}"
        )));
    }
    if !(settings.epsilon.is_finite() && settings.epsilon >= 0.0) {
        return Err(settings_error(format!(
            "the barycentric tolerance epsilon must be >= 0 and finite, not {}",
            settings.epsilon
        )));
    }
    Ok(())
}

/// An error when [`Sampler::Walk`] is given a setting that would change its picture and that
/// it does not honour: 16-bit slices (its samples are f32). The settings it ignores change
/// nothing in its picture.
pub(crate) fn check_walk(settings: &ShellSettings) -> Result<(), RenderError> {
    if settings.sampler != Sampler::Walk {
        return Ok(());
    }
    if settings.format == SliceFormat::Float16 {
        return Err(settings_error(
            "--slice-format f16 sets the raster sampler's slice targets; --sampler walk samples \
             in f32: use --slice-format auto or f32, or --sampler raster",
        ));
    }
    Ok(())
}
