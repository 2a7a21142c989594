//! GPU-visible data: the `#[repr(C)]` twins of the WGSL structs (`shaders/shared.wgsl`, the
//! shells' `shaders/shells_shared.wgsl`, and each stage's own uniforms), with compile-time size assertions that mirror the WGSL layout
//! (vec3 aligned to 16 bytes, so each `vec3<f32>` is followed by one scalar that fills its last
//! 4 bytes); `tests/shaders.rs`, `tests/iso_shaders.rs` and `tests/cellproj_shaders.rs` check
//! each size against naga's layout of the WGSL.

use bytemuck::{Pod, Zeroable};

/// The view every mode's stages read (WGSL `View` in `shaders/shared.wgsl`, uniform, 96
/// bytes): the camera's eye space, the image, and the assembly's constants. Each mode's own
/// constants are in blocks of their own ([`SlicingUniforms`], [`IsoUniforms`],
/// [`CellProjUniforms`], [`RaycastUniforms`]); the transfer function carries its point count
/// ([`TfPoints::count`]).
///
/// Eye space has its origin at the eye and axes (right, up, forward): x to the image's right,
/// y to its top, z into the scene. Positions on the GPU are relative to the mesh origin (the
/// bounding-box centre), and so is `eye`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ViewUniforms {
    /// Camera right axis (world, unit).
    pub right: [f32; 3],
    /// Barycentric inside tolerance: a sample is in a tet when its smallest barycentric
    /// coordinate is at least `-epsilon`.
    pub epsilon: f32,
    /// Camera up axis (world, unit).
    pub up: [f32; 3],
    /// Eye-space z below which a tet vertex makes the tet a near-plane tet (drawn as a
    /// screen-space quad of its part in front of this plane instead of its faces).
    pub near_z: f32,
    /// Camera forward axis (world, unit).
    pub forward: [f32; 3],
    /// A tet is degenerate (skipped) when |det(edges / L)| <= this times the product of the
    /// normalized edge lengths, L the longest of the three edges from vertex 0.
    pub degenerate_tol: f32,
    /// The origin of the eye-space arithmetic, relative to the mesh origin: the eye where
    /// `pivot_z` is 0, else the pivot, the point `pivot_z` ahead of the eye on the view axis
    /// (`ViewFrame::pivot_uniforms`, `gpu/view.rs`). The assembly measures eye-space
    /// vertices and the records' `lambda_eye` from it.
    pub eye: [f32; 3],
    /// Number of tets (assembly bound).
    pub tet_count: u32,
    /// Projection scale: NDC = (x * proj.x / z, y * proj.y / z).
    pub proj: [f32; 2],
    /// Image-plane half extent at distance 1: (tan(fov/2) * aspect, tan(fov/2)).
    pub half_extent: [f32; 2],
    /// Image size in pixels.
    pub size: [f32; 2],
    /// Eye-space z of the pivot (`eye`): 0 where `eye` is the eye. Every mode that reads it sets
    /// it: iso's, cellproj's and the shells' fragments and the ray caster's stages (the walk
    /// sampler's too) measure their rays from the pivot.
    pub pivot_z: f32,
    /// Zero: pads the struct to WGSL's 16-byte alignment.
    pub _pad: u32,
}
const _: () = assert!(size_of::<ViewUniforms>() == 96);

/// The shells mode's slicing (WGSL `Slicing` in `shaders/shells_shared.wgsl`, uniform, 16
/// bytes): slice `k` lies at distance `t_first + k dz` from the eye.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SlicingUniforms {
    /// Distance from the eye of slice 0.
    pub t_first: f32,
    /// Slice spacing (world units).
    pub dz: f32,
    /// Slices per shell (the raster stage writes zeros beyond this).
    pub slices_per_shell: u32,
    /// `t_first - ViewUniforms::pivot_z`, in f64 before rounding: slice 0's distance beyond
    /// the pivot's, which the samplers measure their slices from (`t_first` where the pivot
    /// is the eye).
    pub t_pivot: f32,
}
const _: () = assert!(size_of::<SlicingUniforms>() == 16);

/// Per-shell constants (WGSL `Shell` in `shaders/shells_shared.wgsl`), bound with a dynamic offset.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShellUniforms {
    /// Global index of the shell's first slice.
    pub first_slice: u32,
    /// Compute sampler, meshes of several record chunks: how this pass continues the shell's
    /// slices across chunk passes, bits [`CHUNK_LOAD`] and [`CHUNK_STORE`] (0: the shell's
    /// only pass).
    pub chunk_pass: u32,
    /// Compute sampler: the shell's tets drawn by their faces, `(start, count)` in the active
    /// list.
    pub faces: [u32; 2],
    /// Compute sampler: the shell's near-plane tets, `(start, count)` in the active list.
    pub near: [u32; 2],
    /// Zero: aligns `tiles`.
    pub _pad1: [u32; 2],
    /// Compute sampler: the screen tiles of the shell's rectangle, `[x0, y0, x1, y1)`.
    pub tiles: [u32; 4],
}
const _: () = assert!(size_of::<ShellUniforms>() == 48);

/// The shells' GPU binning constants (WGSL `Bin` in `shaders/shells_bin.wgsl`, uniform, 112
/// bytes): the view in f32 (mesh-origin relative), the slicing, the frame's shells.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BinUniforms {
    /// Camera right (world).
    pub right: [f32; 3],
    /// World units of slack in every comparison, against f32 rounding.
    pub margin: f32,
    /// Camera up (world).
    pub up: [f32; 3],
    /// Tets with a corner at eye-space z at most this are near-plane tets.
    pub near_z: f32,
    /// Camera forward (world).
    pub forward: [f32; 3],
    /// Distance of slice 0 from the eye less `pivot_z` (in f64 before rounding): slice 0's
    /// distance beyond the pivot's.
    pub t_pivot: f32,
    /// The pivot (`ViewFrame::pivot`, `gpu/view.rs`) relative to the mesh origin: the binning
    /// measures corners from it, as the assembly does.
    pub pivot: [f32; 3],
    /// Slice spacing (world units).
    pub dz: f32,
    /// Frustum half-slopes.
    pub slope: [f32; 2],
    /// Slices across the mesh.
    pub slices: u32,
    /// Slices per shell.
    pub per_shell: u32,
    /// Shells across the mesh.
    pub shells: u32,
    /// Record chunks: buckets per (shell, near).
    pub chunks: u32,
    /// 1: tets outside a frustum plane are culled.
    pub frustum: u32,
    /// Entries the active list holds.
    pub capacity: u32,
    /// Eye-space z of the pivot.
    pub pivot_z: f32,
    /// Zero: pads the struct to a multiple of 16 bytes.
    pub _pad: [u32; 3],
}
const _: () = assert!(size_of::<BinUniforms>() == 112);

/// The record chunk one count or scatter pass of the GPU binning bins (WGSL `Chunk` in
/// `shaders/shells_bin.wgsl`, uniform, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BinChunk {
    /// Its first tet.
    pub first: u32,
    /// Its tets.
    pub count: u32,
    /// Its number.
    pub index: u32,
    /// Zero: pads the struct to the 16 bytes of a uniform binding.
    pub _pad: u32,
}
const _: () = assert!(size_of::<BinChunk>() == 16);

/// [`ShellUniforms::chunk_pass`] bit: the pass starts from the slices an earlier chunk pass of
/// the shell stored (else from no sample).
pub const CHUNK_LOAD: u32 = 1;
/// [`ShellUniforms::chunk_pass`] bit: the pass stores its slices for a later chunk pass of the
/// shell (else it composites them and accumulates the shell).
pub const CHUNK_STORE: u32 = 2;

/// What the assembly stage writes once per tet and frame and the raster stage reads (WGSL
/// `TetRecord`, 80 bytes). The tet's eye-space corners are not in it: the stages that draw or
/// bin tets read them through its vertex ids from the per-frame eye-space vertices
/// (`shaders/tet_corners.wgsl`); a degenerate tet's record is all zeros.
///
/// Barycentric coordinates along the ray `x = t d` (eye space, `d` unit) are
/// `lambda(t) = lambda_eye + t (grad_x d.x + grad_y d.y + grad_z d.z)`; the encoded scalar is
/// `scalar.w + t dot(scalar.xyz, d)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TetRecord {
    /// d lambda_i / d x_eye for i = 0..3.
    pub grad_x: [f32; 4],
    /// d lambda_i / d y_eye.
    pub grad_y: [f32; 4],
    /// d lambda_i / d z_eye.
    pub grad_z: [f32; 4],
    /// Barycentric coordinates of the eye (of the pivot where [`ViewUniforms::pivot_z`] is
    /// not 0).
    pub lambda_eye: [f32; 4],
    /// xyz: eye-space gradient of the encoded scalar; w: the encoded scalar extrapolated to
    /// the eye (the pivot).
    pub scalar: [f32; 4],
}
const _: () = assert!(size_of::<TetRecord>() == 80);

/// One transfer-function control point (WGSL `TfPoint`, 32 bytes), `s` normalized like the
/// encoded scalars: `u = (s - s_min) / (s_max - s_min)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TfPoint {
    /// Emitted colour (linear rgb, each in `[0, 1]`): the colour of a thick slab, not
    /// premultiplied by opacity.
    pub rgb: [f32; 3],
    /// Extinction per world unit.
    pub tau: f32,
    /// Normalized scalar value.
    pub s: f32,
    /// `1 / (next.s - s)`, 0 when the next point is at the same `s` (a step) or there is none.
    pub inv_width: f32,
    /// Zero: pads the point to 32 bytes, WGSL's array stride for it.
    pub _pad: [f32; 2],
}
const _: () = assert!(size_of::<TfPoint>() == 32);

/// The most control points the shells composite evaluates (a uniform array of 8 KiB).
pub(crate) const MAX_TF_POINTS: usize = 256;

/// The transfer function as a uniform block (WGSL `TfPoints`, 8,208 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct TfPoints {
    /// The first `count` entries are the control points in increasing `s`; the rest are zero.
    pub points: [TfPoint; MAX_TF_POINTS],
    /// Number of control points.
    pub count: u32,
    /// Zero: pads the struct to WGSL's 16-byte alignment.
    pub _pad: [u32; 3],
}
const _: () = assert!(size_of::<TfPoints>() == 32 * MAX_TF_POINTS + 16);

/// The most isovalues one iso renderer draws (`IsoSettings::isovalues` longer than this is
/// refused).
pub const MAX_ISOVALUES: usize = 16;

/// Per-frame isosurface constants (WGSL `Iso` in `shaders/iso_shared.wgsl`, 336 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct IsoUniforms {
    /// Surface colour of each isovalue (rgb; a unused).
    pub colors: [[f32; 4]; MAX_ISOVALUES],
    /// Normalized isovalues `(v - s_min) / (s_max - s_min)`, four to a vector.
    pub values: [[f32; 4]; MAX_ISOVALUES / 4],
    /// How many of `colors` and `values` are used (at most [`MAX_ISOVALUES`]).
    pub count: u32,
    /// 1 for smooth shading.
    pub smooth_shading: u32,
    /// `1 / (far - near)`, the distances from the eye `near` and `far` bounding the mesh's
    /// (`near` at most the nearest, `far` beyond the farthest): depth = (distance - near) /
    /// (far - near).
    pub inv_depth_range: f32,
    /// `ViewUniforms::pivot_z - near`, of the mesh's size: the fragment forms distance - near
    /// as (t_c - pivot_z) + t + depth_shift, t its hit's distance from t_c (the ray's point in
    /// the pivot's plane), so that no term of the eye's distance D rounds the depth; distance /
    /// D in f32 ties hits up to 6e-8 D apart (two surfaces 0.01 radii apart at 1e6 radii).
    pub depth_shift: f32,
}
const _: () = assert!(size_of::<IsoUniforms>() == 336);

/// Which dispatch of the iso gradient stage this is (WGSL `GradientPass` in
/// `shaders/iso_gradients.wgsl`, 16 bytes): the stage runs once per chunk of the mesh's tets,
/// and each vertex's running sums wait in its gradient slot between dispatches.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GradientPass {
    /// 1 for the first chunk: the sums start at zero instead of from the slot.
    pub first: u32,
    /// 1 for the last chunk: the slot gets the gradient instead of the sums.
    pub last: u32,
    /// Zero: pads the struct to the 16 bytes of a uniform binding.
    pub _pad: [u32; 2],
}
const _: () = assert!(size_of::<GradientPass>() == 16);

/// The cellproj raster's table constants (WGSL `CellProj` in `shaders/cellproj_raster.wgsl`,
/// 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CellProjUniforms {
    /// Scalar samples per table axis.
    pub table_size: u32,
    /// Length levels.
    pub table_lengths: u32,
    /// `(table_lengths - 1) / max_length`: length to level.
    pub inv_length_step: f32,
    /// Zero: pads the struct to the 16 bytes of a uniform binding.
    pub _pad: u32,
}
const _: () = assert!(size_of::<CellProjUniforms>() == 16);

/// The ray caster's constants (WGSL `Raycast` in `shaders/raycast_shared.wgsl`, 64 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RaycastUniforms {
    /// Boundary-face hits each pixel's entry list holds.
    pub capacity: u32,
    /// Tets one ray may step through.
    pub max_steps: u32,
    /// Boundary faces.
    pub boundary_count: u32,
    /// The eye is in a tet when it lies at most this far outside each face plane.
    pub eye_tol: f32,
    /// Tets per links window.
    pub link_chunk: u32,
    /// `--integrate table`: scalar samples per table axis.
    pub table_size: u32,
    /// `--integrate table`: length levels.
    pub table_lengths: u32,
    /// `--integrate table`: `(table_lengths - 1) / max_length`, length to level.
    pub inv_length_step: f32,
    /// The shells' walk sampler (`shaders/raycast_slices.wgsl`): slice `k` lies at
    /// `t_first + pivot_z + k dz` from the eye, `k < slices` (this `t_first` is the plan's less
    /// [`ViewUniforms::pivot_z`], in f64 before rounding: the traversal measures its rays from
    /// the pivot's plane); zero for the other integrators.
    pub t_first: f32,
    /// See `t_first`.
    pub dz: f32,
    /// See `t_first`.
    pub slices: u32,
    /// Early ray termination: a ray stops once its transmittance is below this (what lies
    /// behind adds at most this to any channel), `twin::TERMINATE`, for the ray caster's own
    /// integrators; for the walk sampler, at or below `1 - threshold` where a shell ends (-1
    /// with its early termination off: never).
    pub terminate: f32,
    /// 0: the traversal checks `terminate` after every segment (the ray caster's own
    /// integrators). The walk sampler's slice count per shell: its integrator checks it only
    /// where a shell ends, as the raster and compute samplers do.
    pub shell_slices: u32,
    /// A textured cage's traversal: the distance between samples along a ray (in the mesh's
    /// f32 frame, so per frame: the frame follows the positions); 0 without a texture.
    pub step: f32,
    /// Zero: pads the struct to a multiple of 16 bytes.
    pub _pad: [u32; 2],
}
const _: () = assert!(size_of::<RaycastUniforms>() == 64);

/// The ray caster's depth-peeling layer (WGSL `Layer` in `shaders/raycast_rays.wgsl`, 16
/// bytes); 0 for entry lists.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct LayerUniforms {
    /// The layer: 0 first.
    pub index: u32,
    /// 1: the tile list holds every tile ([`crate::gpu::raycast::RaycastSettings`]'s
    /// `skip_empty_tiles` off), 0: only those with work.
    pub all_tiles: u32,
    /// Zero: pads the struct to the 16 bytes of a uniform binding.
    pub _pad: [u32; 2],
}
const _: () = assert!(size_of::<LayerUniforms>() == 16);

/// Per tet, built once (WGSL `TetLinks`, 32 bytes): vertex indices, and across each face
/// `4 * neighbour + face` (`crate::mesh::topology::NO_NEIGHBOR` on the boundary).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct TetLinks {
    /// The tet's vertex indices.
    pub tet: [u32; 4],
    /// Across face `i` (opposite corner `i`): `4 * neighbour + face index in the neighbour`,
    /// or `NO_NEIGHBOR` on the boundary.
    pub next: [u32; 4],
}
const _: () = assert!(size_of::<TetLinks>() == 32);
