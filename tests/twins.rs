//! Every CPU twin against the WGSL it mirrors, run on the adapter (issue 14, item 8), so that a
//! shader cannot drift while its twin's own tests pass.
//!
//! The assembly runs the shipped `assemble.wgsl` (from [`shaders::assemble`], the string the
//! pipeline compiles) with its real bindings. The fragment and composite functions run in a
//! small `@compute` entry point appended to the shipped module's source (from the same
//! registry functions the pipelines use), which calls the very WGSL functions the fragment
//! shaders call and writes their results to a storage buffer. Each comparison is bit for bit:
//! the twins use the shaders' operations in the shaders' order, and lavapipe compiles them
//! without contracting multiplies and adds into FMAs, so any difference is a drift. A shader
//! with one operation perturbed by one ulp is caught by every comparison
//! (`perturbed_shaders_are_detected`).
//!
//! Inputs come from a seeded sweep (the same on every run) with the hard cases named in the
//! DESIGN's robustness catalogue: slivers down to the degenerate threshold, zero-length tets,
//! rays lying in a face plane, the eye at or near a vertex, samples on slice boundaries, and
//! transfer-function control points (and their f32 neighbours) as scalar values.

use std::sync::OnceLock;

use glam::{Vec3, Vec4};
use tetvr::gpu::cellproj::twin as cellproj_twin;
use tetvr::gpu::gpu_data::{FrameUniforms, ShellUniforms, TetRecord, TfPoint};
use tetvr::gpu::shaders;
use tetvr::gpu::shells::twin;
use tetvr::gpu::tf::tf_points;
use tetvr::gpu::{AdapterChoice, GpuContext};
use tetvr::tf::{ControlPoint, TransferFunction};
use wgpu::util::DeviceExt;

fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(|| {
        GpuContext::new(AdapterChoice::Auto).unwrap_or_else(|e| {
            panic!("the twin tests need a GPU adapter (Mesa's lavapipe will do): {e}")
        })
    })
}

// ---------------------------------------------------------------------------------------------
// Running WGSL on the adapter
// ---------------------------------------------------------------------------------------------

const UNIFORM: wgpu::BufferBindingType = wgpu::BufferBindingType::Uniform;
const READ: wgpu::BufferBindingType = wgpu::BufferBindingType::Storage { read_only: true };
const WRITE: wgpu::BufferBindingType = wgpu::BufferBindingType::Storage { read_only: false };

/// A buffer holding `bytes` (at least 16), usable as `kind` and copied from.
fn buffer(bytes: &[u8], kind: wgpu::BufferBindingType) -> wgpu::Buffer {
    let mut contents = bytes.to_vec();
    contents.resize(bytes.len().max(16), 0);
    let usage = match kind {
        wgpu::BufferBindingType::Uniform => wgpu::BufferUsages::UNIFORM,
        _ => wgpu::BufferUsages::STORAGE,
    };
    ctx()
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("twin test"),
            contents: &contents,
            usage: usage | wgpu::BufferUsages::COPY_SRC,
        })
}

/// The first `len` bytes of `src`, read back.
fn read_back(src: &wgpu::Buffer, len: u64) -> Vec<u8> {
    let device = &ctx().device;
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("twin readback"),
        size: len,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(src, 0, &staging, 0, len);
    ctx().queue.submit([enc.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("poll");
    let bytes = staging.slice(..).get_mapped_range().expect("mapped").to_vec();
    staging.unmap();
    bytes
}

/// Dispatches compute entry `entry` of `src` with `invocations` threads of 64 per workgroup,
/// bindings `group` (binding, buffer, type) in group 0, and returns `output` read back.
fn dispatch(
    src: String,
    entry: &str,
    groups: &[&[(u32, &wgpu::Buffer, wgpu::BufferBindingType)]],
    invocations: u32,
    output: (&wgpu::Buffer, u64),
) -> Vec<u8> {
    let device = &ctx().device;
    let layouts: Vec<wgpu::BindGroupLayout> = groups
        .iter()
        .map(|entries| {
            let entries: Vec<wgpu::BindGroupLayoutEntry> = entries
                .iter()
                .map(|&(binding, _, ty)| wgpu::BindGroupLayoutEntry {
                    binding,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                })
                .collect();
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: None,
                entries: &entries,
            })
        })
        .collect();
    let bind_groups: Vec<wgpu::BindGroup> = groups
        .iter()
        .zip(&layouts)
        .map(|(entries, layout)| {
            let entries: Vec<wgpu::BindGroupEntry> = entries
                .iter()
                .map(|&(binding, buffer, _)| wgpu::BindGroupEntry {
                    binding,
                    resource: buffer.as_entire_binding(),
                })
                .collect();
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout,
                entries: &entries,
            })
        })
        .collect();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("twin test"),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    let layout_refs: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(Some).collect();
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &layout_refs,
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("twin test"),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        for (i, group) in bind_groups.iter().enumerate() {
            pass.set_bind_group(i as u32, group, &[]);
        }
        pass.dispatch_workgroups(invocations.div_ceil(64), 1, 1);
    }
    ctx().queue.submit([enc.finish()]);
    read_back(output.0, output.1)
}

/// The test entry appended to a shipped module: one invocation per case calls the module's
/// own `twin_case(TwinIn) -> TwinOut` (defined by each test next to its structs).
const TWIN_MAIN: &str = "
@group(1) @binding(0) var<storage, read> twin_in: array<TwinIn>;
@group(1) @binding(1) var<storage, read_write> twin_out: array<TwinOut>;

@compute @workgroup_size(64)
fn twin_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < arrayLength(&twin_out) {
        twin_out[id.x] = twin_case(twin_in[id.x]);
    }
}
";

/// Runs `twin_case` of `module` + `case` over `input` (cases of `in_stride` bytes) with group 0
/// bound as the shipped stage binds it; returns the outputs of `out_stride` bytes each.
fn run_cases(
    module: String,
    case: &str,
    group0: &[(u32, &wgpu::Buffer, wgpu::BufferBindingType)],
    input: &[u8],
    in_stride: usize,
    out_stride: usize,
) -> Vec<f32> {
    let n = input.len() / in_stride;
    let cases = buffer(input, READ);
    let out = buffer(&vec![0; n * out_stride], WRITE);
    let out_len = (n * out_stride) as u64;
    let group1 = [(0, &cases, READ), (1, &out, WRITE)];
    let src = format!("{module}\n{case}\n{TWIN_MAIN}");
    let bytes = dispatch(src, "twin_main", &[group0, &group1], n as u32, (&out, out_len));
    bytemuck::cast_slice(&bytes).to_vec()
}

// ---------------------------------------------------------------------------------------------
// Comparing
// ---------------------------------------------------------------------------------------------

/// Distance in units in the last place between two f32 (0 for equal bits, and for two NaNs;
/// `u32::MAX` for a NaN against a number).
fn ulps(a: f32, b: f32) -> u32 {
    if a.is_nan() || b.is_nan() {
        return if a.is_nan() && b.is_nan() { 0 } else { u32::MAX };
    }
    // Map the sign-magnitude bits to a monotonic integer line (-0 and +0 both to 0).
    let key = |x: f32| {
        let i = x.to_bits() as i32;
        if i < 0 {
            -(i & 0x7fff_ffff) as i64
        } else {
            i as i64
        }
    };
    (key(a) - key(b)).unsigned_abs().min(u32::MAX as u64) as u32
}

/// The comparison of one stage: cases compared, values that differ, and the first difference.
#[derive(Debug, Default)]
struct Drift {
    cases: usize,
    differing: usize,
    first: Option<String>,
}

impl Drift {
    /// Compares the GPU's values of case `what` with the twin's, bit for bit.
    fn check(&mut self, what: impl FnOnce() -> String, gpu: &[f32], twin: &[f32]) {
        self.cases += 1;
        let worst = gpu.iter().zip(twin).map(|(&g, &t)| ulps(g, t)).max();
        let differing = gpu.iter().zip(twin).filter(|(g, t)| ulps(**g, **t) > 0).count();
        if differing > 0 && self.first.is_none() {
            self.first = Some(format!(
                "{}: GPU {gpu:?} vs twin {twin:?} ({worst:?} ulps)",
                what()
            ));
        }
        self.differing += differing;
    }

    fn assert_identical(&self, stage: &str, min_cases: usize) {
        eprintln!("{stage}: {self:?}");
        assert!(self.cases >= min_cases, "{stage}: only {} cases", self.cases);
        assert_eq!(self.differing, 0, "{stage} drifted from its twin: {self:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Inputs
// ---------------------------------------------------------------------------------------------

/// SplitMix64: a small seeded generator, so the sweep is the same on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }

    fn below(&mut self, n: u32) -> u32 {
        (self.next() % n as u64) as u32
    }

    fn vec3(&mut self, r: f32) -> Vec3 {
        Vec3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
    }

    /// Barycentric weights, coordinate `zero` (0..4) set to 0 when below 4.
    fn weights(&mut self, zero: u32) -> Vec4 {
        let mut w = Vec4::new(
            self.range(0.05, 1.0),
            self.range(0.05, 1.0),
            self.range(0.05, 1.0),
            self.range(0.05, 1.0),
        );
        if zero < 4 {
            w[zero as usize] = 0.0;
        }
        w / (w.x + w.y + w.z + w.w)
    }
}

/// A camera at `eye` looking at `target` (world z up unless looking along it), `width` x
/// `height` pixels at 40 degrees, and the shells slicing fields.
fn frame(eye: Vec3, target: Vec3, size: [f32; 2], slicing: (f32, f32, u32)) -> FrameUniforms {
    let forward = (target - eye).normalize();
    let up_hint = if forward.z.abs() > 0.9 { Vec3::Y } else { Vec3::Z };
    let right = forward.cross(up_hint).normalize();
    let up = right.cross(forward);
    let slope = 20f32.to_radians().tan();
    let (t_first, dz, slices_per_shell) = slicing;
    FrameUniforms {
        right: right.to_array(),
        up: up.to_array(),
        forward: forward.to_array(),
        eye: eye.to_array(),
        epsilon: 1e-4,
        near_z: 0.5 * t_first,
        degenerate_tol: tetvr::gpu::assembly::DEGENERATE_TOL,
        size,
        half_extent: [slope * size[0] / size[1], slope],
        proj: [1.0 / (slope * size[0] / size[1]), 1.0 / slope],
        t_first,
        dz,
        slices_per_shell,
        ..Default::default()
    }
}

/// World direction of eye-space direction `d`.
fn to_world(f: &FrameUniforms, d: Vec3) -> Vec3 {
    Vec3::from(f.right) * d.x + Vec3::from(f.up) * d.y + Vec3::from(f.forward) * d.z
}

/// A random pixel centre.
fn pixel(rng: &mut Rng, f: &FrameUniforms) -> [f32; 2] {
    [
        rng.below(f.size[0] as u32) as f32 + 0.5,
        rng.below(f.size[1] as u32) as f32 + 0.5,
    ]
}

/// The tet families of the sweep, placed around the point at distance `t` along the pixel ray
/// through `xy`, with size `s`: `kind` 0 random, 1 a face plane holding the ray, 2 a face through
/// the point (a sample on a slice boundary when `t` is a slice's distance), 3 a sliver (height
/// down to 1e-6 of its size, around the degenerate threshold), 4 a vertex on the ray at `t`.
fn tet_on_ray(rng: &mut Rng, f: &FrameUniforms, xy: [f32; 2], t: f32, s: f32, kind: u32) -> [Vec3; 4] {
    let eye = Vec3::from(f.eye);
    let dir = to_world(f, twin::pixel_ray(f, xy));
    let at = eye + dir * t;
    let p = [0; 4].map(|_| at + rng.vec3(s));
    match kind {
        1 => {
            // Two corners on either side of the ray in a plane holding it, the third in it too.
            let side = dir.cross(rng.vec3(1.0)).normalize() * s;
            let along = |rng: &mut Rng| dir * rng.range(-s, s);
            [
                at + along(rng) + side * rng.range(0.2, 1.0),
                at + along(rng) - side * rng.range(0.2, 1.0),
                at + along(rng) + side * rng.range(-1.0, 1.0) + dir * s,
                p[3],
            ]
        }
        2 => {
            let zero = rng.below(4);
            let w = rng.weights(zero);
            let x = p[0] * w.x + p[1] * w.y + p[2] * w.z + p[3] * w.w;
            p.map(|q| q + (at - x))
        }
        3 => {
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let n = e1.cross(e2).normalize_or_zero();
            let base = p[0] + e1 * rng.range(0.1, 0.4) + e2 * rng.range(0.1, 0.4);
            let height = s * 10f32.powf(-rng.range(1.0, 6.5));
            [p[0], p[1], p[2], base + n * height]
        }
        4 => [at, p[1], p[2], p[3]],
        _ => p,
    }
}

// ---------------------------------------------------------------------------------------------
// The assembly stage
// ---------------------------------------------------------------------------------------------

/// A mesh of independent tets (and a few sharing vertices) with the sweep's families, for
/// frame `f`: positions (w 1), normalized scalars, tets.
fn assembly_mesh(rng: &mut Rng, f: &FrameUniforms) -> (Vec<[f32; 4]>, Vec<f32>, Vec<[u32; 4]>) {
    let (mut positions, mut tets) = (Vec::new(), Vec::new());
    for k in 0..1200u32 {
        let xy = pixel(rng, f);
        let t = rng.range(0.01, 8.0);
        let size = rng.range(0.01, 1.0);
        let mut p = tet_on_ray(rng, f, xy, t, size, k % 5);
        match k % 23 {
            // A zero-length tet (NaN edges), and one with the eye at a vertex.
            0 => p = [p[0]; 4],
            1 => p[0] = Vec3::from(f.eye),
            _ => {}
        }
        let first = positions.len() as u32;
        positions.extend(p.map(|q| q.extend(1.0).to_array()));
        tets.push([first, first + 1, first + 2, first + 3]);
    }
    // Tets sharing vertices (the shader fetches through the index buffer).
    let n = positions.len() as u32;
    for _ in 0..200 {
        tets.push([0; 4].map(|_| rng.below(n)));
    }
    let scalars = (0..positions.len()).map(|_| rng.range(0.0, 1.0)).collect();
    (positions, scalars, tets)
}

/// The shipped assembly on `f` and the mesh, against `twin::assemble` per tet (a degenerate
/// tet: the GPU writes a zeroed record and counts it, the twin returns `None`).
fn assembly_drift(src: String, f: &FrameUniforms, rng: &mut Rng) -> Drift {
    let (positions, scalars, tets) = assembly_mesh(rng, f);
    let n = tets.len();
    let frame_buf = buffer(bytemuck::bytes_of(&FrameUniforms { tet_count: n as u32, ..*f }), UNIFORM);
    let pos_buf = buffer(bytemuck::cast_slice(&positions), READ);
    let scalar_buf = buffer(bytemuck::cast_slice(&scalars), READ);
    let tet_buf = buffer(bytemuck::cast_slice(&tets), READ);
    let records = buffer(&vec![0; n * size_of::<TetRecord>()], WRITE);
    let degenerate = buffer(&[0; 4], WRITE);
    let group = [
        (0, &frame_buf, UNIFORM),
        (1, &pos_buf, READ),
        (2, &scalar_buf, READ),
        (3, &tet_buf, READ),
        (4, &records, WRITE),
        (5, &degenerate, WRITE),
    ];
    let out = (&records, (n * size_of::<TetRecord>()) as u64);
    let gpu: Vec<TetRecord> = bytemuck::cast_slice(&dispatch(src, "main", &[&group], n as u32, out)).to_vec();
    let gpu_degenerate = bytemuck::cast_slice::<u8, u32>(&read_back(&degenerate, 4))[0];
    let mut drift = Drift::default();
    let mut twin_degenerate = 0;
    for (k, (tet, g)) in tets.iter().zip(&gpu).enumerate() {
        let p = tet.map(|i| Vec3::from_slice(&positions[i as usize][..3]));
        let s = tet.map(|i| scalars[i as usize]);
        let rec = twin::assemble(f, p, s).unwrap_or_else(|| {
            twin_degenerate += 1;
            TetRecord::default()
        });
        drift.check(
            || format!("tet {k} {p:?}"),
            bytemuck::cast_slice(&[*g]),
            bytemuck::cast_slice(&[rec]),
        );
    }
    assert_eq!(gpu_degenerate, twin_degenerate, "degenerate tets counted");
    assert!(twin_degenerate > 20, "the sweep has degenerate tets ({twin_degenerate})");
    drift
}

/// Cameras of the sweep: far, near the mesh, and far from the origin.
fn cameras() -> Vec<FrameUniforms> {
    let slicing = (0.01, 0.05, 8);
    vec![
        frame(Vec3::new(0.3, -6.0, 1.2), Vec3::ZERO, [64.0, 48.0], slicing),
        frame(Vec3::new(0.01, 0.02, -0.03), Vec3::new(1.0, 2.0, 0.5), [33.0, 65.0], slicing),
        frame(Vec3::new(0.0, 0.0, 30.0), Vec3::new(0.1, 0.0, 0.0), [96.0, 96.0], slicing),
    ]
}

fn assembly_all(src: &str) -> Drift {
    let mut rng = Rng(14);
    let mut drift = Drift::default();
    for f in cameras() {
        let d = assembly_drift(src.to_owned(), &f, &mut rng);
        drift.cases += d.cases;
        drift.differing += d.differing;
        drift.first = drift.first.or(d.first);
    }
    drift
}

/// The assembly stage's records are the twin's, bit for bit, for every tet of the sweep
/// (3 cameras x 1,400 tets: slivers around the degenerate threshold, zero-length tets, the eye
/// at a vertex, vertices shared between tets), and both count the same degenerate tets.
#[test]
fn assembly_matches_its_twin() {
    assembly_all(&shaders::assemble()).assert_identical("assembly", 4000);
}
