//! One ray-cast frame: upload, the three stages recorded on the shared frame recorder, the
//! readback, and the rerun with longer entry lists when a list overflowed.

use std::time::Instant;

use crate::camera::Camera;
use crate::gpu::frame::{ImageReadback, Timestamps};
use crate::gpu::tf::tf_points;
use crate::gpu::util::{check_image_size, entry, map_read, ms_since, settings_error, texture_2d};
use crate::gpu::view::ViewFrame;
use crate::image::Image;
use crate::render::{Frame, RenderError, Timings};
use crate::tf::TransferFunction;

use super::pipelines::{Pipelines, Stage, encode, linear_groups};
use super::{
    COUNTERS, RaycastRenderer, RaycastUniforms, Segments, Targets, default_max_steps, near_tol, psi,
};

/// A storage buffer of `bytes` (at least 16) that is also a copy source and destination.
pub fn storage(device: &wgpu::Device, label: &str, bytes: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (bytes as u64).max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// A buffer of `bytes` the CPU maps to read what was copied into it.
pub fn mappable(device: &wgpu::Device, label: &str, bytes: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// What one run of the stages read back.
struct Run {
    stages: Vec<(&'static str, f64)>,
    gpu_clock: bool,
    /// See [`COUNTERS`].
    counters: [u32; COUNTERS],
}

/// The traversal stage of `segments`.
fn traversal(p: &Pipelines, segments: Segments) -> &Stage {
    match segments {
        Segments::Exact => &p.exact,
        Segments::Partial => &p.partial,
    }
}

impl RaycastRenderer {
    /// Renders one frame; see the module docs.
    pub(super) fn frame(
        &mut self,
        camera: &Camera,
        tf: &TransferFunction,
    ) -> Result<Frame, RenderError> {
        let start = Instant::now();
        let mut timings = Timings::default();
        let t = Instant::now();
        self.upload(camera, tf)?;
        timings.stage("upload", ms_since(t));
        let mut reruns = 0;
        let run = loop {
            self.ensure_targets(camera.width, camera.height)?;
            let run = self.record()?;
            if run.counters[2] == 0 {
                break run;
            }
            self.capacity *= 2;
            self.write_params();
            reruns += 1;
        };
        let t = Instant::now();
        let image = self.read_image()?;
        for stage in ["planes", "entries", "traverse"] {
            let ms = run
                .stages
                .iter()
                .find(|(s, _)| *s == stage)
                .map_or(0.0, |s| s.1);
            timings.stage(stage, ms);
        }
        timings.stage("readback", ms_since(t));
        timings.stage("total", ms_since(start));
        timings.clock = if run.gpu_clock {
            "GPU timestamps for planes, entries, traverse (the last run); wall clock for \
             upload, readback and total"
        } else {
            "wall clock, GPU drained after each stage"
        };
        self.count(&mut timings, &run, reruns);
        Ok(Frame { image, timings })
    }

    fn count(&self, timings: &mut Timings, run: &Run, reruns: u64) {
        timings.count("tets", self.mesh.tet_count() as u64);
        timings.count("boundary faces", self.boundary_count as u64);
        timings.count("thin tets", run.counters[0] as u64);
        timings.count("eye in a tet", (run.counters[1] != u32::MAX) as u64);
        timings.count("entry list length", self.capacity as u64);
        timings.count("list overflow reruns", reruns);
        timings.count("rays at step limit", run.counters[3] as u64);
        timings.count("bytes per tet", self.bytes_per_tet().round() as u64);
    }

    /// Writes the frame constants, the TF and the ray caster's constants.
    fn upload(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<(), RenderError> {
        let m = self.mesh.read();
        let view = ViewFrame::new(camera);
        let nt = m.tets.len() as u32;
        let frame = view.uniforms(m.origin, 0.0, near_tol(m.radius), nt);
        self.queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&frame));
        let points = tf_points(tf, m.scalar_min, m.scalar_span)?;
        self.queue
            .write_buffer(&self.tf_buf, 0, bytemuck::bytes_of(&points));
        self.eye_tol = near_tol(m.radius);
        drop(m);
        if self.settings.segments == Segments::Partial && self.psi.size() == 16 {
            let table = psi::table();
            self.psi = storage(&self.device, "raycast psi table", 4 * table.len());
            (self.queue).write_buffer(&self.psi, 0, bytemuck::cast_slice(table));
        }
        self.write_params();
        Ok(())
    }

    fn write_params(&self) {
        let params = RaycastUniforms {
            capacity: self.capacity,
            max_steps: (self.settings.max_steps)
                .unwrap_or_else(|| default_max_steps(self.mesh.tet_count())),
            boundary_count: self.boundary_count,
            eye_tol: self.eye_tol,
        };
        self.queue
            .write_buffer(&self.params_buf, 0, bytemuck::bytes_of(&params));
    }

    /// The output image and entry lists for `width` x `height` at the current capacity, kept
    /// while both match; an error naming the sizes when the lists exceed one binding.
    fn ensure_targets(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        let keep = self
            .targets
            .as_ref()
            .is_some_and(|t| (t.width, t.height, t.capacity) == (width, height, self.capacity));
        if keep {
            return Ok(());
        }
        check_image_size(&self.limits, width, height)?;
        let pixels = width as u64 * height as u64;
        let bytes = pixels * self.capacity as u64 * 8;
        let max = (self.limits.max_storage_buffer_binding_size).min(self.limits.max_buffer_size);
        if bytes > max {
            return Err(settings_error(format!(
                "--mode raycast: entry lists of {} boundary-face hits per pixel at \
                 {width}x{height} need {bytes} bytes, more than one storage binding of this \
                 adapter holds ({max}); render a smaller image",
                self.capacity
            )));
        }
        let format = wgpu::TextureFormat::Rgba32Float;
        let image = texture_2d(
            &self.device,
            "raycast image",
            (width, height, 1),
            format,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        );
        let device = &self.device;
        self.targets = Some(Targets {
            width,
            height,
            readback: ImageReadback::new(device, "raycast readback", width, height, format),
            image,
            counts: storage(device, "raycast entry counts", 4 * pixels as usize),
            entries: storage(device, "raycast entries", bytes as usize),
            capacity: self.capacity,
        });
        Ok(())
    }

    fn group(&self, stage: &Stage, entries: &[wgpu::BindGroupEntry]) -> wgpu::BindGroup {
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raycast"),
            layout: &stage.layout,
            entries,
        })
    }

    /// The bind groups of the planes, entries and traversal stages.
    fn bind(&self, t: &Targets) -> [wgpu::BindGroup; 3] {
        let nt = self.mesh.tet_count() as u64;
        let p = &self.pipelines;
        let view = t.image.create_view(&Default::default());
        let planes = self.group(
            &p.planes,
            &[
                entry(0, &self.frame_buf),
                entry(1, self.mesh.positions()),
                entry(2, self.mesh.scalars()),
                self.links.window(3, 0, nt),
                self.planes.window(4, 0, nt),
                entry(5, &self.counters),
                entry(6, &self.params_buf),
            ],
        );
        let entries = self.group(
            &p.entries,
            &[
                entry(0, &self.frame_buf),
                entry(1, self.mesh.positions()),
                self.links.window(2, 0, nt),
                self.planes.window(3, 0, nt),
                entry(4, &self.boundary),
                entry(5, &t.counts),
                entry(6, &t.entries),
                entry(7, &self.counters),
                entry(8, &self.params_buf),
            ],
        );
        let traverse = self.group(
            traversal(p, self.settings.segments),
            &[
                entry(0, &self.frame_buf),
                self.links.window(1, 0, nt),
                self.planes.window(2, 0, nt),
                entry(3, &t.counts),
                entry(4, &t.entries),
                entry(5, &self.tf_buf),
                entry(6, &self.params_buf),
                entry(7, &self.counters),
                wgpu::BindGroupEntry {
                    binding: 8,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                entry(9, self.mesh.positions()),
                entry(10, &self.psi),
            ],
        );
        [planes, entries, traverse]
    }

    /// Runs the three stages once and reads the counters back.
    fn record(&mut self) -> Result<Run, RenderError> {
        let t = (self.targets.as_ref())
            .ok_or_else(|| settings_error("internal: render target missing"))?;
        let [planes, entries, traverse] = self.bind(t);
        let reset: [u32; COUNTERS] = [0, u32::MAX, 0, 0];
        self.queue
            .write_buffer(&self.counters, 0, bytemuck::cast_slice(&reset));
        let max = self.limits.max_compute_workgroups_per_dimension;
        let nt = self.mesh.tet_count() as u64;
        let tiles = (t.width.div_ceil(8), t.height.div_ceil(8));
        let passes = [
            (
                "planes",
                &self.pipelines.planes,
                &planes,
                linear_groups(nt, max),
            ),
            ("entries", &self.pipelines.entries, &entries, {
                linear_groups(self.boundary_count as u64, max)
            }),
            (
                "traverse",
                traversal(&self.pipelines, self.settings.segments),
                &traverse,
                tiles,
            ),
        ];
        let mut rec = (self.frame).recorder(&self.device, &self.queue, 3, 0);
        rec.encoder().clear_buffer(&t.counts, 0, None);
        for (name, stage, group, groups) in passes {
            let ts = rec.timestamps(name);
            let writes = ts.as_ref().map(Timestamps::compute);
            encode(rec.encoder(), name, (stage, group), groups, writes);
            rec.end_stage(name)?;
        }
        let bytes = 4 * COUNTERS as u64;
        (rec.encoder()).copy_buffer_to_buffer(&self.counters, 0, &self.counters_read, 0, bytes);
        let stats = rec.finish(&[(&t.image, &t.readback)], &self.counters, 0)?;
        map_read(&self.device, &self.counters_read)?;
        let counters = {
            let data = (self.counters_read.get_mapped_range(..))
                .map_err(|e| settings_error(format!("mapping the counters failed: {e}")))?;
            let words: &[u32] = bytemuck::cast_slice(&data);
            std::array::from_fn(|i| words[i])
        };
        self.counters_read.unmap();
        Ok(Run {
            stages: stats.stages,
            gpu_clock: stats.gpu_clock,
            counters,
        })
    }

    fn read_image(&self) -> Result<Image, RenderError> {
        let t = (self.targets.as_ref())
            .ok_or_else(|| settings_error("internal: render target missing"))?;
        let mut image = Image::new(t.width, t.height);
        image.pixels = t.readback.read(&self.device)?;
        Ok(image)
    }
}
