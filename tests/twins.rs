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

mod common;

use glam::{Vec3, Vec4};
use tetvr::gpu::cellproj::twin as cellproj_twin;
use tetvr::gpu::gpu_data::{ShellUniforms, SlicingUniforms, TetRecord, TfPoint, ViewUniforms};
use tetvr::gpu::shaders;
use tetvr::gpu::shells::twin;
use tetvr::gpu::tf_points;
use tetvr::tf::{ControlPoint, TransferFunction};
use wgpu::util::DeviceExt;

use common::ctx;

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
    staging
        .slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("poll");
    let bytes = staging
        .slice(..)
        .get_mapped_range()
        .expect("mapped")
        .to_vec();
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
    let bytes = dispatch(
        src,
        "twin_main",
        &[group0, &group1],
        n as u32,
        (&out, out_len),
    );
    bytemuck::cast_slice(&bytes).to_vec()
}

// ---------------------------------------------------------------------------------------------
// Comparing
// ---------------------------------------------------------------------------------------------

/// The comparison of one stage: values compared, values whose bits differ, and the worst
/// difference in units of f32 epsilon of each value's scale (the magnitude of the terms that
/// produced it, times the condition of the computation), with the case where it occurred.
#[derive(Debug, Default)]
struct Drift {
    values: usize,
    differing_bits: usize,
    worst: f32,
    worst_case: String,
}

impl Drift {
    /// Compares the GPU's values of case `what` with the twin's, value `i` on scale `scale[i]`.
    fn check(&mut self, what: impl FnOnce() -> String, gpu: &[f32], twin: &[f32], scale: &[f32]) {
        assert_eq!(gpu.len(), twin.len());
        let mut worst = 0.0f32;
        for ((&g, &t), &sc) in gpu.iter().zip(twin).zip(scale) {
            self.values += 1;
            if g.to_bits() == t.to_bits() || (g == t) || (g.is_nan() && t.is_nan()) {
                continue;
            }
            self.differing_bits += 1;
            let e = (g - t).abs() / (sc * f32::EPSILON);
            // NaN against a number is the worst drift.
            worst = worst.max(if e.is_nan() { f32::INFINITY } else { e });
        }
        if worst > self.worst {
            self.worst = worst;
            self.worst_case = format!("{}: GPU {gpu:?} vs twin {twin:?}", what());
        }
    }

    fn merge(&mut self, other: Drift) {
        self.values += other.values;
        self.differing_bits += other.differing_bits;
        if other.worst > self.worst {
            self.worst = other.worst;
            self.worst_case = other.worst_case;
        }
    }

    /// Asserts at least `min_values` compared, none off by more than `bound` epsilons of its
    /// scale.
    fn assert_within(&self, stage: &str, min_values: usize, bound: f32) {
        eprintln!("{stage}: {self:?}");
        assert!(
            self.values >= min_values,
            "{stage}: only {} values",
            self.values
        );
        assert!(
            self.worst <= bound,
            "{stage} drifted from its twin: {self:?}"
        );
    }
}

/// The largest magnitude in `v`.
fn max_abs(v: &[f32]) -> f32 {
    v.iter().fold(0.0f32, |m, x| m.max(x.abs()))
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
/// `height` pixels at 40 degrees, and the shells slicing `(t_first, dz, slices_per_shell)`.
fn frame(
    eye: Vec3,
    target: Vec3,
    size: [f32; 2],
    (t_first, dz, slices_per_shell): (f32, f32, u32),
) -> (ViewUniforms, SlicingUniforms) {
    let forward = (target - eye).normalize();
    let up_hint = if forward.z.abs() > 0.9 {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let right = forward.cross(up_hint).normalize();
    let up = right.cross(forward);
    let slope = 20f32.to_radians().tan();
    let view = ViewUniforms {
        right: right.to_array(),
        up: up.to_array(),
        forward: forward.to_array(),
        eye: eye.to_array(),
        epsilon: 1e-4,
        near_z: 0.5 * t_first,
        degenerate_tol: tetvr::gpu::DEGENERATE_TOL,
        size,
        half_extent: [slope * size[0] / size[1], slope],
        proj: [1.0 / (slope * size[0] / size[1]), 1.0 / slope],
        ..Default::default()
    };
    let slicing = SlicingUniforms {
        t_first,
        dz,
        slices_per_shell,
        t_pivot: t_first,
    };
    (view, slicing)
}

/// World direction of eye-space direction `d`.
fn to_world(f: &ViewUniforms, d: Vec3) -> Vec3 {
    Vec3::from(f.right) * d.x + Vec3::from(f.up) * d.y + Vec3::from(f.forward) * d.z
}

/// A random pixel centre.
fn pixel(rng: &mut Rng, f: &ViewUniforms) -> [f32; 2] {
    [
        rng.below(f.size[0] as u32) as f32 + 0.5,
        rng.below(f.size[1] as u32) as f32 + 0.5,
    ]
}

/// The tet families of the sweep, placed around the point at distance `t` along the pixel ray
/// through `xy`, with size `s`: `kind` 0 random, 1 a face plane holding the ray, 2 a face through
/// the point (a sample on a slice boundary when `t` is a slice's distance), 3 a sliver (height
/// down to 1e-6 of its size, around the degenerate threshold), 4 a vertex on the ray at `t`.
fn tet_on_ray(
    rng: &mut Rng,
    f: &ViewUniforms,
    xy: [f32; 2],
    t: f32,
    s: f32,
    kind: u32,
) -> [Vec3; 4] {
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
fn assembly_mesh(rng: &mut Rng, f: &ViewUniforms) -> (Vec<[f32; 4]>, Vec<f32>, Vec<[u32; 4]>) {
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
fn assembly_drift(src: String, f: &ViewUniforms, rng: &mut Rng) -> Drift {
    let (positions, scalars, tets) = assembly_mesh(rng, f);
    let n = tets.len();
    let view_buf = buffer(
        bytemuck::bytes_of(&ViewUniforms {
            tet_count: n as u32,
            ..*f
        }),
        UNIFORM,
    );
    let pos_buf = buffer(bytemuck::cast_slice(&positions), READ);
    let scalar_buf = buffer(bytemuck::cast_slice(&scalars), READ);
    let tet_buf = buffer(bytemuck::cast_slice(&tets), READ);
    let records = buffer(&vec![0; n * size_of::<TetRecord>()], WRITE);
    let degenerate = buffer(&[0; 4], WRITE);
    let group = [
        (0, &view_buf, UNIFORM),
        (1, &pos_buf, READ),
        (2, &scalar_buf, READ),
        (3, &tet_buf, READ),
        (4, &records, WRITE),
        (5, &degenerate, WRITE),
    ];
    let out = (&records, (n * size_of::<TetRecord>()) as u64);
    let gpu: Vec<TetRecord> =
        bytemuck::cast_slice(&dispatch(src.clone(), "main", &[&group], n as u32, out)).to_vec();
    let gpu_degenerate = bytemuck::cast_slice::<u8, u32>(&read_back(&degenerate, 4))[0];
    let mut drift = Drift::default();
    let (mut twin_degenerate, mut borderline) = (0, 0);
    for (k, (tet, g)) in tets.iter().zip(&gpu).enumerate() {
        let p = tet.map(|i| Vec3::from_slice(&positions[i as usize][..3]));
        let s = tet.map(|i| scalars[i as usize]);
        let cond = condition(p);
        let rec = twin::assemble(f, p, s);
        twin_degenerate += rec.is_none() as u32;
        let gpu_degenerate = *g == TetRecord::default();
        if gpu_degenerate != rec.is_none() {
            // The determinant test of a tet within a factor 2 of the threshold may go either
            // way: its determinant is ~1e-6 of its terms, so fused multiply-adds move it by up
            // to ~0.1 of itself.
            assert!(
                (0.5..2.0).contains(&(1.0 / (cond * f.degenerate_tol))),
                "tet {k} {p:?}: GPU degenerate {gpu_degenerate}, condition {cond}"
            );
            borderline += 1;
            continue;
        }
        let rec = rec.unwrap_or_default();
        drift.check(
            || format!("tet {k} {p:?}, condition {cond}"),
            bytemuck::cast_slice(&[*g]),
            bytemuck::cast_slice(&[rec]),
            &record_scales(&rec, cond),
        );
    }
    drift.merge(eye_vertices_drift(src, f, &view_buf, &pos_buf, &positions));
    let gpu_degenerate = gpu_degenerate as i64 - twin_degenerate as i64;
    assert!(
        gpu_degenerate.unsigned_abs() <= borderline,
        "degenerate tets counted"
    );
    assert!(borderline <= 5, "{borderline} tets on the threshold");
    assert!(
        twin_degenerate > 20,
        "the sweep has degenerate tets ({twin_degenerate})"
    );
    drift
}

/// The assembly's `vertices` entry on `f` and the mesh's `positions`, against
/// `twin::eye_vertex` per vertex, each coordinate on the scale of its distance from the eye.
fn eye_vertices_drift(
    src: String,
    f: &ViewUniforms,
    view_buf: &wgpu::Buffer,
    pos_buf: &wgpu::Buffer,
    positions: &[[f32; 4]],
) -> Drift {
    let bytes = size_of_val(positions);
    let eye_buf = buffer(&vec![0; bytes], WRITE);
    let group = [
        (0, view_buf, UNIFORM),
        (1, pos_buf, READ),
        (7, &eye_buf, WRITE),
    ];
    let n = positions.len() as u32;
    let out = dispatch(src, "vertices", &[&group], n, (&eye_buf, bytes as u64));
    let gpu: &[[f32; 4]] = bytemuck::cast_slice(&out);
    let eye = Vec3::from(f.eye);
    let mut drift = Drift::default();
    for (k, (g, p)) in gpu.iter().zip(positions).enumerate() {
        let q = Vec3::from_slice(&p[..3]);
        let twin = twin::eye_vertex(f, q).to_array();
        let scale = (q - eye).length().max(q.length());
        drift.check(|| format!("vertex {k} {q:?}"), g, &twin, &[scale; 4]);
    }
    drift
}

/// The condition of a tet's barycentric transform, |n1| |n2| |n3| / |det(n1, n2, n3)| with
/// n_i its edges from vertex 0 over the longest (the amplification of rounding in its
/// gradients; infinite for a flat tet).
fn condition(p: [Vec3; 4]) -> f32 {
    let e = [p[1] - p[0], p[2] - p[0], p[3] - p[0]];
    let l = e.iter().fold(0.0f32, |m, e| m.max(e.length()));
    let n = e.map(|e| e / l);
    n[0].length() * n[1].length() * n[2].length() / n[0].dot(n[1].cross(n[2])).abs()
}

/// The scale of each of a record's 20 values (see [`Drift`]): gradients on the largest gradient times the condition; the eye's
/// barycentrics and the encoded scalar (sums of terms up to the largest barycentric times
/// encoded scalars up to 2, with cancellation against 1) on that times the condition.
fn record_scales(rec: &TetRecord, cond: f32) -> Vec<f32> {
    let mut scales = Vec::new();
    let grads: Vec<f32> = [rec.grad_x, rec.grad_y, rec.grad_z].concat();
    let grad = max_abs(&grads) * cond;
    let lambda = max_abs(&rec.lambda_eye).max(1.0) * 2.0 * cond;
    scales.extend([grad; 12]);
    scales.extend([lambda; 4]);
    scales.extend([grad * 2.0; 3]);
    scales.push(lambda);
    // A degenerate tet's record is zero on both sides, bit for bit.
    scales
        .iter()
        .map(|&s| if cond.is_finite() { s } else { 0.0 })
        .collect()
}

/// `(view, slicing)` measured from the pivot `pivot_z` ahead of the eye on the view axis
/// instead of from the eye, as iso, cellproj and the shells' raster and compute samplers are
/// given them (`ViewFrame::pivot_uniforms`).
fn pivoted(
    (view, slicing): (ViewUniforms, SlicingUniforms),
    pivot_z: f32,
) -> (ViewUniforms, SlicingUniforms) {
    let eye = Vec3::from(view.eye) + Vec3::from(view.forward) * pivot_z;
    let view = ViewUniforms {
        eye: eye.to_array(),
        pivot_z,
        ..view
    };
    let slicing = SlicingUniforms {
        t_pivot: slicing.t_first - pivot_z,
        ..slicing
    };
    (view, slicing)
}

/// Cameras of the sweep: far, near the mesh, far from the origin, and that one again measured
/// from a pivot near the mesh.
fn cameras() -> Vec<ViewUniforms> {
    let slicing = (0.01, 0.05, 8);
    vec![
        frame(Vec3::new(0.3, -6.0, 1.2), Vec3::ZERO, [64.0, 48.0], slicing),
        frame(
            Vec3::new(0.01, 0.02, -0.03),
            Vec3::new(1.0, 2.0, 0.5),
            [33.0, 65.0],
            slicing,
        ),
        frame(
            Vec3::new(0.0, 0.0, 30.0),
            Vec3::new(0.1, 0.0, 0.0),
            [96.0, 96.0],
            slicing,
        ),
        pivoted(
            frame(
                Vec3::new(0.0, 0.0, 30.0),
                Vec3::new(0.1, 0.0, 0.0),
                [96.0, 96.0],
                slicing,
            ),
            29.5,
        ),
    ]
    .into_iter()
    .map(|(view, _)| view)
    .collect()
}

fn assembly_all(src: &str) -> Drift {
    let mut rng = Rng(14);
    let mut drift = Drift::default();
    for f in cameras() {
        drift.merge(assembly_drift(src.to_owned(), &f, &mut rng));
    }
    drift
}

/// The assembly stage's records and eye-space vertices are the twin's for every tet and vertex
/// of the sweep (3 cameras x 1,400 tets: slivers around the degenerate threshold, zero-length
/// tets, the eye at a vertex, vertices shared between tets), and both count the same
/// degenerate tets. Bound: 8 epsilons
/// of each value's scale (`record_scales` for records, the vertex's coordinates' scale in
/// `eye_vertices_drift`); lavapipe fuses multiplies and adds (about 1 value
/// in 10 differs in its last bits), which moves a value by about one rounding of its terms
/// amplified by the tet's condition; measured worst 1.4. A one-ulp change of an operation
/// is not caught by this bound, a change of 1e-4 (~840 epsilons) is.
#[test]
fn assembly_matches_its_twin() {
    assembly_all(&shaders::assemble()).assert_within("assembly", 4000 * 20, 8.0);
}

// ---------------------------------------------------------------------------------------------
// The composite's transfer function
// ---------------------------------------------------------------------------------------------

/// Transfer functions of the sweep: steps (two points at one value), points outside the data
/// range, points closer than an f32 ulp of the normalized scalar allows, one point, and many.
fn sweep_tfs() -> Vec<Vec<ControlPoint>> {
    let cp = |s: f64, r: f64, a: f64| ControlPoint {
        s,
        color: [r, 1.0 - r, 0.5 * r],
        opacity: a,
    };
    let mut many = Vec::new();
    for k in 0..40 {
        let s = -4.0 + 13.0 * (k as f64 / 39.0).powi(2);
        many.push(cp(s, (k % 7) as f64 / 6.0, (k % 5) as f64 / 5.0));
    }
    vec![
        vec![cp(-3.0, 0.0, 0.0), cp(5.0, 1.0, 0.9)],
        vec![
            cp(-4.0, 0.2, 0.1),
            cp(0.0, 0.9, 0.5),
            cp(0.0, 0.1, 0.05),
            cp(1.3, 0.4, 0.7),
            cp(9.0, 1.0, 0.2),
        ],
        vec![cp(1.0, 0.5, 0.5)],
        vec![
            cp(0.0, 0.1, 0.1),
            cp(0.001, 0.9, 0.8),
            cp(0.002, 0.2, 0.3),
            cp(2.0, 0.5, 0.5),
        ],
        many,
    ]
}

/// The twin's evaluation equals TransferFunction::eval (f32 rounding aside) for the sweep's
/// TFs: points outside the data range, close together, a single point, a step, and many.
#[test]
fn twin_tf_eval_matches_the_transfer_function() {
    let (lo, span) = (-3.0, 8.0);
    for points in sweep_tfs() {
        let tf = TransferFunction::new(points, 0.5).unwrap();
        let block = tf_points(&tf, lo, span).unwrap();
        let pts = &block.points[..tf.points().len()];
        let eval = |u: f64| {
            let t = tf.eval(lo + u * span);
            Vec4::new(
                t.color[0] as f32,
                t.color[1] as f32,
                t.color[2] as f32,
                t.tau as f32,
            )
        };
        for i in 0..=40_000 {
            let u = (i as f64 / 40_000.0 * 1.4 - 0.2) as f32;
            let got = twin::tf_eval(pts, u);
            // Exact up to f32 rounding of u and of the control points (an ulp of u <= 1.2
            // is 1.2e-7): the result lies between the TF at u -/+ 2e-7 (which also spans a
            // step at u), give or take a few ulps of values up to ~9 (tau of 0.9 over 0.5).
            let (a, b) = (eval(u as f64 - 2e-7), eval(u as f64 + 2e-7));
            let (lo_v, hi_v) = (a.min(b) - Vec4::splat(1e-5), a.max(b) + Vec4::splat(1e-5));
            assert!(
                got.cmpge(lo_v).all() && got.cmple(hi_v).all(),
                "u {u}: {got} not in [{a}, {b}]"
            );
        }
    }
}

/// The normalized scalars of the sweep over `points`: a dense sweep beyond both ends, each
/// control point and its f32 neighbours, and -1 (an empty sample's e - 1).
fn tf_inputs(points: &[TfPoint]) -> Vec<f32> {
    let mut u: Vec<f32> = (0..=4000).map(|i| -0.2 + 1.4 * i as f32 / 4000.0).collect();
    for p in points {
        u.extend([p.s, p.s.next_up(), p.s.next_down()]);
    }
    u.push(-1.0);
    u
}

const TF_CASE: &str = "
struct TwinIn { u: f32 }
struct TwinOut { v: vec4<f32> }
fn twin_case(c: TwinIn) -> TwinOut { return TwinOut(tf_eval(c.u)); }
";

/// `tf_eval` of the shipped composite (the unrolled variant of the TF's size and the looping
/// one) against `twin::tf_eval`, via `source(targets, tf_points)`.
fn composite_drift(source: &dyn Fn(u32, u32) -> String) -> Drift {
    let (lo, span) = (-3.0, 8.0);
    let mut drift = Drift::default();
    for points in sweep_tfs() {
        let tf = TransferFunction::new(points, 0.5).expect("a valid TF");
        let n = tf.points().len();
        let block = tf_points(&tf, lo, span).expect("TF points");
        let pts = &block.points[..n];
        let slicing = SlicingUniforms {
            dz: 0.01,
            ..Default::default()
        };
        let slicing_buf = buffer(bytemuck::bytes_of(&slicing), UNIFORM);
        let tf_buf = buffer(bytemuck::bytes_of(&block), UNIFORM);
        let u = tf_inputs(pts);
        let group0 = [(2, &tf_buf, UNIFORM), (4, &slicing_buf, UNIFORM)];
        for variant in [n as u32, 0] {
            let out = run_cases(
                source(2, variant),
                TF_CASE,
                &group0,
                bytemuck::cast_slice(&u),
                4,
                16,
            );
            for (k, (&u, gpu)) in u.iter().zip(out.chunks(4)).enumerate() {
                let twin = twin::tf_eval(pts, u);
                // Values up to max |rgb, tau| mixed with weights in [0, 1].
                let scale = pts.iter().fold(1.0f32, |m, p| m.max(p.tau)).max(1.0);
                drift.check(
                    || format!("TF of {n} points, variant {variant}, u {u} (case {k})"),
                    gpu,
                    &twin.to_array(),
                    &[scale; 4],
                );
            }
        }
    }
    drift
}

/// The composite's transfer-function evaluation against its twin on 5 TFs x ~4,000 scalars,
/// control points and their neighbours included, in both the unrolled and the looping
/// variant: bit for bit (measured; the mix has no multiply-add that lavapipe fuses differently
/// from the twin's lerp), so any change of the shader's arithmetic shows.
#[test]
fn composite_tf_eval_matches_its_twin() {
    composite_drift(&shaders::shells_composite).assert_within(
        "composite tf_eval",
        5 * 4000 * 4 * 2,
        0.0,
    );
}

// ---------------------------------------------------------------------------------------------
// The fragments: shells slices, cellproj segment
// ---------------------------------------------------------------------------------------------

/// One fragment case as the test entry reads it: a record and the pixel centre (xy, 0, 0).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FragmentCase {
    rec: TetRecord,
    xy: [f32; 4],
}

/// Fragment cases for view `f` and slicing `sl`, shell `first_slice`: records of the sweep's tet families
/// around pixel rays at distances within the shell (on slice boundaries for the face family),
/// and some at random distances.
fn fragment_cases(
    rng: &mut Rng,
    (f, sl): (&ViewUniforms, &SlicingUniforms),
    first_slice: u32,
) -> Vec<FragmentCase> {
    let mut cases = Vec::new();
    while cases.len() < 1500 {
        let xy = pixel(rng, f);
        let j = rng.below(sl.slices_per_shell) as f32;
        let t = match cases.len() % 3 {
            0 => sl.t_first + (first_slice as f32 + j) * sl.dz,
            1 => {
                let j = rng.range(-1.0, sl.slices_per_shell as f32);
                sl.t_first + (first_slice as f32 + j) * sl.dz
            }
            _ => rng.range(0.001, 10.0),
        };
        let size = sl.dz * rng.range(0.5, 20.0);
        let kind = rng.below(5);
        let p = tet_on_ray(rng, f, xy, t, size, kind);
        let s = [0; 4].map(|_| rng.range(0.0, 1.0));
        if let Some(rec) = twin::assemble(f, p, s) {
            cases.push(FragmentCase {
                rec,
                xy: [xy[0], xy[1], 0.0, 0.0],
            });
        }
    }
    cases
}

/// Cameras for the fragments: slices of 0.05 seen from afar, slices of 1e-3 starting at
/// 1e-3 with tets at the eye, slices of 0.01 far from the origin, and those again measured
/// from a pivot near the mesh.
fn fragment_cameras() -> Vec<((ViewUniforms, SlicingUniforms), u32)> {
    vec![
        (
            frame(
                Vec3::new(0.3, -6.0, 1.2),
                Vec3::ZERO,
                [64.0, 48.0],
                (0.5, 0.05, 8),
            ),
            97,
        ),
        (
            frame(
                Vec3::new(0.01, 0.02, -0.03),
                Vec3::new(1.0, 2.0, 0.5),
                [33.0, 65.0],
                (1e-3, 1e-3, 8),
            ),
            0,
        ),
        (
            frame(
                Vec3::new(0.0, 0.0, 30.0),
                Vec3::new(0.1, 0.0, 0.0),
                [96.0, 96.0],
                (25.0, 0.01, 8),
            ),
            300,
        ),
        (
            pivoted(
                frame(
                    Vec3::new(0.0, 0.0, 30.0),
                    Vec3::new(0.1, 0.0, 0.0),
                    [96.0, 96.0],
                    (25.0, 0.01, 8),
                ),
                29.5,
            ),
            300,
        ),
    ]
}

const SEGMENT_CASE: &str = "
struct TwinIn { rec: TetRecord, xy: vec4<f32> }
struct TwinOut { d: vec4<f32>, seg: vec4<f32> }
fn twin_case(c: TwinIn) -> TwinOut {
    let v = varyings(vec4<f32>(c.xy.xy, 0.0, 1.0), c.rec);
    return TwinOut(vec4<f32>(pixel_ray(c.xy.xy), 0.0), vec4<f32>(segment(v), 0.0));
}
";

/// The cellproj fragment's `segment` (and `pixel_ray`) against `cellproj_twin::segment` on the
/// GPU's ray. A miss is (0, 0, -1) on the GPU, `None` in the twin.
fn segment_drift(module: String) -> (Drift, u32) {
    let mut rng = Rng(8);
    let (mut drift, mut flips) = (Drift::default(), 0);
    for ((f, sl), first) in fragment_cameras() {
        let f = ViewUniforms {
            epsilon: cellproj_twin::INSIDE_TOL,
            ..f
        };
        let cases = fragment_cases(&mut rng, (&f, &sl), first);
        let view_buf = buffer(bytemuck::bytes_of(&f), UNIFORM);
        let out = run_cases(
            module.clone(),
            SEGMENT_CASE,
            &[(0, &view_buf, UNIFORM)],
            bytemuck::cast_slice(&cases),
            size_of::<FragmentCase>(),
            32,
        );
        for (k, (c, gpu)) in cases.iter().zip(out.chunks(8)).enumerate() {
            let xy = [c.xy[0], c.xy[1]];
            let d = twin::pixel_ray(&f, xy);
            drift.check(
                || format!("pixel_ray {xy:?}"),
                &gpu[..3],
                &d.to_array(),
                &[1.0; 3],
            );
            let gd = Vec3::from_slice(&gpu[..3]);
            let seg = cellproj_twin::segment(&f, &c.rec, gd).unwrap_or(Vec3::new(0.0, 0.0, -1.0));
            let (g, t) = (&gpu[4..7], seg.to_array());
            if (g[2] > 0.0) != (t[2] > 0.0) {
                flips += 1;
                continue;
            }
            let len = max_abs(&c.rec.lambda_eye).max(1.0) * (t[2].abs() + 1.0);
            drift.check(|| format!("case {k} {:?}", c.rec), g, &t, &[1.0, 1.0, len]);
        }
    }
    (drift, flips)
}

/// The cellproj fragment's segment clip against its twin on 4,500 fragments (3 cameras; rays
/// in face planes, faces through the sample, slivers, vertices on the ray, the eye next to
/// the tets), bit for bit except where lavapipe's fused multiply-adds round differently.
#[test]
fn cellproj_segment_matches_its_twin() {
    let (drift, flips) = segment_drift(shaders::cellproj_raster());
    // Measured: 0 flips, worst 4 epsilons (of 1 for the clamped scalars, of the length times
    // the largest barycentric of the eye for the length), ~8% of values differ in their bits.
    assert!(flips <= 5, "{flips} fragments hit on one side only");
    drift.assert_within("cellproj segment", 4500 * 6, 16.0);
}

const SLICES_CASE: &str = "
struct TwinIn { rec: TetRecord, xy: vec4<f32> }
struct TwinOut { d: vec4<f32>, span: vec4<f32>, v: array<vec4<f32>, TARGETS> }
fn twin_case(c: TwinIn) -> TwinOut {
    let v = varyings(vec4<f32>(c.xy.xy, 0.0, 1.0), c.rec);
    let span = slice_span(v, pixel_ray(c.xy.xy));
    return TwinOut(vec4<f32>(pixel_ray(c.xy.xy), 0.0), span, slice_values(span));
}
";

/// The shells fragment's `slice_span` and `slice_values` (2 targets: 8 slices) against
/// `twin::slice_span` and `twin::sample_slices`; returns the drift and the samples whose
/// inside test flipped.
fn slices_drift(source: &dyn Fn(u32) -> String) -> (Drift, u32) {
    let mut rng = Rng(6);
    let (mut drift, mut flips) = (Drift::default(), 0);
    for ((f, sl), first) in fragment_cameras() {
        let cases = fragment_cases(&mut rng, (&f, &sl), first);
        let view_buf = buffer(bytemuck::bytes_of(&f), UNIFORM);
        let shell = ShellUniforms {
            first_slice: first,
            ..Default::default()
        };
        let shell_buf = buffer(bytemuck::bytes_of(&shell), UNIFORM);
        let slicing_buf = buffer(bytemuck::bytes_of(&sl), UNIFORM);
        let group0 = [
            (0, &view_buf, UNIFORM),
            (1, &shell_buf, UNIFORM),
            (4, &slicing_buf, UNIFORM),
        ];
        let out = run_cases(
            source(2),
            SLICES_CASE,
            &group0,
            bytemuck::cast_slice(&cases),
            size_of::<FragmentCase>(),
            64,
        );
        for (k, (c, gpu)) in cases.iter().zip(out.chunks(16)).enumerate() {
            let xy = [c.xy[0], c.xy[1]];
            drift.check(
                || format!("pixel_ray {xy:?}"),
                &gpu[..3],
                &twin::pixel_ray(&f, xy).to_array(),
                &[1.0; 3],
            );
            let twin = twin::sample_slices(&f, &sl, &c.rec, xy, first);
            for (j, (&g, &t)) in gpu[8..].iter().zip(&twin).enumerate() {
                if (g == 0.0) != (t == 0.0) {
                    flips += 1;
                    continue;
                }
                // Encoded scalars 1..2 plus the gradient times the distance.
                let scale = 2.0
                    + max_abs(&c.rec.scalar) * (sl.t_first + (first + j as u32 + 1) as f32 * sl.dz);
                drift.check(
                    || format!("case {k} slice {j} {:?}", c.rec),
                    &[g],
                    &[t],
                    &[scale],
                );
            }
        }
    }
    (drift, flips)
}

/// The shells fragment's slice sampling against its twin on 4,500 fragments x 8 slices (the
/// fragment families of `cellproj_segment_matches_its_twin`, a third of them with a face
/// through a slice's sample).
#[test]
fn shells_slices_match_their_twin() {
    let (drift, flips) = slices_drift(&shaders::shells_raster);
    // Measured: 4 samples of ~36,000 on a boundary whose inside test went the other way, worst
    // 0.49 epsilons of the encoded scalar's scale, ~3% of values differ in their bits.
    assert!(flips <= 20, "{flips} samples inside on one side only");
    drift.assert_within("shells slices", 4500 * 8, 4.0);
}

/// `source` with `from` (which must occur in it) replaced by `to`.
fn perturbed(source: String, from: &str, to: &str) -> String {
    assert!(source.contains(from), "the shader no longer has `{from}`");
    source.replacen(from, to, 1)
}

/// One operation of each stage scaled by 1 + 1e-4 (about 840 epsilons) is caught by its
/// comparison: the bounds above are far below what a change of the arithmetic does.
#[test]
fn perturbed_shaders_are_detected() {
    let scaled = "* 1.0001";
    let assembly = perturbed(
        shaders::assemble(),
        "let k = inv_l / det;",
        &format!("let k = inv_l / det {scaled};"),
    );
    assert!(assembly_all(&assembly).worst > 8.0, "assembly");
    let composite = |t, n| {
        perturbed(
            shaders::shells_composite(t, n),
            "(u - a.s) * a.inv_width",
            &format!("(u - a.s) * a.inv_width {scaled}"),
        )
    };
    assert!(composite_drift(&composite).worst > 0.0, "composite");
    let cellproj = perturbed(
        shaders::cellproj_raster(),
        "let ds = dot(in.scalar.xyz, d);",
        &format!("let ds = dot(in.scalar.xyz, d) {scaled};"),
    );
    assert!(segment_drift(cellproj).0.worst > 16.0, "cellproj segment");
    let span = |t| {
        perturbed(
            shaders::shells_raster(t),
            "let sd = dot(rec.scalar.xyz, d);",
            &format!("let sd = dot(rec.scalar.xyz, d) {scaled};"),
        )
    };
    assert!(slices_drift(&span).0.worst > 4.0, "shells slice_span");
    let values = |t| {
        perturbed(
            shaders::shells_raster(t),
            "span.z + j * span.w",
            &format!("span.z + j * span.w {scaled}"),
        )
    };
    assert!(slices_drift(&values).0.worst > 4.0, "shells slice_values");
}
