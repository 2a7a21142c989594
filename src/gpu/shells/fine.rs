//! The compute sampler's fine stage, once per drawn shell (`shaders/shells_fine.wgsl`): one
//! workgroup per tile of the shell's rectangle samples, composites and accumulates the
//! shell's slices of each unfinished pixel from the tile's list (loaded into workgroup memory
//! in batches, each entry filed under the tile rows its box covers); variants built on first
//! use and kept.

use std::collections::HashMap;

use crate::gpu::shaders;
use crate::gpu::util::wgsl_module;

/// Fine variants by vec4s of slices and TF point count (0: the looping variant for large TFs).
pub(super) struct FinePipelines {
    variants: HashMap<(u32, u32), wgpu::ComputePipeline>,
    /// The accumulated alpha at which a pixel is finished (above 1 without early termination).
    threshold: f32,
    /// Whether the variants sample a textured cage's volume (`shaders/shells_texture.wgsl`).
    textured: bool,
}

impl FinePipelines {
    /// No variant built yet; pixels finish at `threshold` (`None`: never); `textured`: the
    /// variants of a textured cage.
    pub(super) fn new(threshold: Option<f32>, textured: bool) -> Self {
        Self {
            variants: HashMap::new(),
            threshold: threshold.unwrap_or(2.0),
            textured,
        }
    }

    /// The variant sampling `targets` vec4s of slices for a TF of `tf_points` points, built on
    /// first use with `layout`.
    pub(super) fn get(
        &mut self,
        device: &wgpu::Device,
        layout: &wgpu::PipelineLayout,
        targets: u32,
        tf_points: u32,
    ) -> &wgpu::ComputePipeline {
        let key = shaders::tf_variant(tf_points);
        let threshold = self.threshold as f64;
        let source = if self.textured {
            shaders::shells_fine_textured
        } else {
            shaders::shells_fine
        };
        self.variants.entry((targets, key)).or_insert_with(|| {
            let module = wgsl_module(device, "shells_fine", source(targets, key));
            let constants = [("threshold", threshold)];
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("shells fine"),
                layout: Some(layout),
                module: &module,
                entry_point: Some("main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
        })
    }
}
