//! `--mode raycast`: GPU ray casting on compute shaders through face adjacency (Weiler et al.
//! 2003), one thread per ray in 8 x 8 pixel tiles, with partial pre-integration (Espinha &
//! Celes 2005), Weiler's 3D pre-integration table, or exact segment integration; rays enter
//! by per-pixel entry lists or by depth peeling of the boundary faces (Bernardon et al. 2004),
//! [`Entry`].
//!
//! Per frame:
//! 1. upload (`frame.rs`): frame constants, the TF, the ray caster's constants (and, on the
//!    first `partial` frame, the psi table, [`psi`]; with `table`, the 3D pre-integration
//!    table when the TF, the scalar range or the longest edge (grown) changed, built by
//!    cellproj's incremental builder, `gpu::cellproj::preint`); then the stages this frame
//!    runs that no frame built before (`pipelines.rs`, the `pipelines` stage of the timings);
//! 2. vertices (`shaders/raycast_vertices.wgsl`): once per vertex, its eye-space position and
//!    scalar from the current positions (a deforming mesh needs no preprocessing);
//! 3. planes (`shaders/raycast_planes.wgsl`): once per tet, its face planes from its vertices,
//!    for the eye's tet and the count of thin tets; run only where needed (`PlanesStage`):
//!    when the eye lies in the mesh's bounding box (grown by [`EYE_BOX_GROWTH`] eye
//!    tolerances), or when the thin tets were not counted since the positions last changed;
//! 4. entries, [`Entry::Lists`] (`shaders/raycast_entries.wgsl`): once per boundary face, its
//!    hit (t, face) into the list of every pixel whose ray enters the mesh through it
//!    (watertight edge tests, `raycast_cover.wgsl`); a full list records the longest list a
//!    pixel needed and the frame is rendered once again with lists that long;
//! 5. tiles (`shaders/raycast_tiles.wgsl`): the 8 x 8 pixel tiles where some ray has an entry
//!    (all when the eye is in a tet) into a list, the traversal's indirect dispatch: an empty
//!    tile costs the traversal nothing;
//! 6. traversal (`shaders/raycast_traverse.wgsl`): once per pixel of the listed tiles, from the
//!    eye's tet or the nearest entry, tet to tet through the face the ray leaves by ([`links`]:
//!    neighbour and face across, built once; the face planes and the linear scalar computed
//!    from the tet's vertices at each step), each segment integrated for the piecewise-linear
//!    TF ([`Segments`]: `integrate_segment.wgsl`, shared with cellproj, exact or with partial
//!    pre-integration; or the 3D table), re-entering at the next entry of its list after it
//!    leaves a non-convex mesh; early ray termination, and a step limit whose hits are counted;
//! 7. readback (`gpu/frame.rs`) with the GPU timestamps of stages 2-6 (on a hardware adapter;
//!    on a software one each stage is timed by draining the GPU after it).
//!
//! With [`Entry::Peel`] stage 4 is depth peeling (`shaders/raycast_peel.wgsl`), and stages 4-6
//! run once per layer: layer k holds each pixel's first boundary-face hit by which its ray
//! may enter after leaving the mesh in layer k - 1; only the tiles with such a hit run the
//! layer's traversal, which keeps each ray's state for the next layer; the frame ends when the
//! layer's peel found no pixel with a second hit (or no ray waits), read back after each layer.
//! Both methods choose the same entries and give the same picture, bit for bit.
//!
//! **Memory.** Per tet only its links (32 bytes, [`links`], in up to [`links::LINK_BINDINGS`]
//! storage bindings); per vertex the shared positions and scalars and the eye-space vertices
//! (36 bytes); per boundary face 4 bytes: 39-42 bytes per tet on lox, a 105k-tet grid and the
//! blunt fin ([`RaycastRenderer::bytes_per_tet`]). Planes are not stored: the traversal (and
//! an entry stage, for a boundary face's plane) computes a tet's four planes from its vertices
//! where it needs them (storing them, 80 bytes per tet more, was no faster on lavapipe;
//! docs/performance.md, "The ray caster's memory").
//!
//! **Robustness in f32.** The two tets sharing a face compute its plane from the same three
//! vertices in the same (global index) order, so the ray leaves one at exactly the t where it
//! enters the other; t never decreases along a ray; faces the ray runs along are never exits;
//! and the walk is topological, so a ray cannot fall through a shared face whatever rounding
//! does at edges and vertices. A thin tet (slivers, caps, needles, flat tets: its planes'
//! outward directions are rounding) is left by the face its edges' Pluecker products say the
//! ray passes (Platis & Theoharis 2003), computed alike in every tet sharing an edge; so is a
//! folded tet (an inverted tet of the data, reoriented on load, lies on its neighbours' side of
//! their shared faces: the ray moves outward through the face it came in by, [`twin::folded`]),
//! with an empty segment, into the tet beyond the other face the ray passes. CPU twin of the
//! arithmetic: [`twin`].

mod frame;
pub mod links;
mod pipelines;
pub mod psi;
pub mod texture;
pub mod texture_iso;
pub mod twin;

use std::sync::Arc;

use glam::DVec3;

use crate::camera::Camera;
use crate::gpu::cellproj::preint::{LongestEdge, TableKey};
use crate::gpu::frame::{FrameResources, ImageReadback};
use crate::gpu::gpu_data::{LayerUniforms, TfPoints, ViewUniforms};
use crate::gpu::mesh::{GpuTetMesh, TetArray};
use crate::gpu::util::{
    KeptFrames, Work, captured, captured_frame, largest_binding, settings_error, uniform_buffer,
};
use crate::gpu::view::ViewFrame;
use crate::gpu::{GpuContext, Setting};
use crate::mesh::{TetMesh, checked_bounds};
use crate::render::{Frame, RenderError, Renderer};
use crate::tf::TransferFunction;

use pipelines::{Pipelines, SliceField};
use texture::{GpuTexture, TextureUse};
use texture_iso::{HitBuffers, TexturedIso};

/// How the traversal integrates each segment (both split it at the TF's control points).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Segments {
    /// Partial pre-integration: each piece's mean transmittance from the psi table ([`psi`]).
    #[default]
    Partial,
    /// Each piece's mean transmittance by Gauss-Legendre quadrature converged to f32.
    Exact,
    /// The whole segment from Weiler's 3D pre-integration table (front scalar, back scalar,
    /// length), rebuilt on the CPU when the TF changes.
    Table,
}

pub use crate::gpu::gpu_data::{RaycastUniforms, TetLinks};

/// A raycast frame: its per-pixel entry buffers grow with the image, its 3D pre-integration
/// table with the table size, its eye-space vertices with the mesh.
const FRAME: Work = Work {
    during: "a raycast frame",
    smaller: "render a smaller image (--size), a smaller pre-integration table (--table-size) \
              or a smaller mesh",
};
/// A ray caster's build over a mesh (its links and boundary).
const BUILD: Work = Work::of_mesh("building the raycast renderer");
/// A ray caster's build over a textured cage (the volume, its links and boundary).
const TEXTURED_BUILD: Work = Work::of_texture("building the raycast renderer of a textured cage");

/// How rays find the boundary faces they enter the mesh by (the same entries, the same
/// picture; only the cost differs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Entry {
    /// Per-pixel lists of every boundary-face hit, built in one pass.
    #[default]
    Lists = 0,
    /// Depth peeling of the boundary faces (Bernardon et al. 2004), one layer per pass.
    Peel = 1,
}

/// How the entries stage of [`Entry::Lists`] spreads a boundary face's pixels over threads
/// (`shaders/raycast_entries.wgsl`): the same hits, the same picture bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntryLanes {
    /// A workgroup of 64 threads per face (`main`): the few faces covering thousands of pixels
    /// keep no GPU waiting on one thread.
    Workgroup,
    /// One thread per face (`per_thread`): on software adapters, where a workgroup per face
    /// ran 64 invocations and a barrier for the few pixels most faces cover.
    Thread,
}

impl EntryLanes {
    /// [`Self::Thread`] on software adapters, else [`Self::Workgroup`].
    pub fn for_adapter(ctx: &GpuContext) -> Self {
        if ctx.is_software() {
            Self::Thread
        } else {
            Self::Workgroup
        }
    }

    /// The shader's entry point.
    pub(crate) fn entry_point(self) -> &'static str {
        match self {
            Self::Workgroup => "main",
            Self::Thread => "per_thread",
        }
    }

    /// Threads the stage runs per face.
    pub(crate) fn threads(self) -> u64 {
        match self {
            Self::Workgroup => 64,
            Self::Thread => 1,
        }
    }
}

/// Pixels along a screen tile's side: the traversal's workgroup is one tile.
pub const TILE: u32 = 8;

/// Bytes of a ray's state between depth-peeling layers (WGSL `RayState`).
pub const RAY_STATE_BYTES: u64 = 32;

/// Bytes of one boundary-face hit in a pixel's entry list (WGSL `entries`: a `vec2<u32>`).
pub const HIT_BYTES: u64 = 8;

/// The counters the stages write (u32 each): thin tets (see [`twin::THIN`]), the eye's tet
/// (`u32::MAX`: none), the longest entry list a pixel needed when one overflowed (0: none
/// overflowed), rays stopped by the step limit.
pub const COUNTERS: usize = 4;

/// Bytes read back after each layer: the counters, the tiles run, the layer's progress.
const READ_BYTES: usize = 4 * COUNTERS + 16;

/// The label of the psi table's stand-in before a frame of partial segments uploads it.
const NO_PSI: &str = "raycast psi table (none yet)";

/// Settings of the ray caster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RaycastSettings {
    /// Segment integration.
    pub segments: Segments,
    /// How rays find their entries.
    pub entry: Entry,
    /// With [`Entry::Lists`]: boundary-face hits each pixel's entry list starts with (when a
    /// list overflows, grown to the next power of two at or above the longest list needed and
    /// the frame rendered once again; kept for later frames, unless one binding cannot hold
    /// them at the image's size: that frame is refused and the length is not kept).
    pub list_capacity: u32,
    /// Whether the traversal skips the tiles where no ray has an entry (on by default; off
    /// only to measure what the skip saves: the picture is the same).
    pub skip_empty_tiles: bool,
    /// Tets one ray may step through; `None`: [`default_max_steps`] of the mesh.
    pub max_steps: Option<u32>,
    /// [`Segments::Table`]: samples along each scalar axis (front, back), at least 2.
    pub table_size: u32,
    /// [`Segments::Table`]: length levels (the first of length 0), at least 2.
    pub table_lengths: u32,
    /// [`Entry::Lists`]: the entries stage's threads per face; `None`:
    /// [`EntryLanes::for_adapter`].
    pub entry_lanes: Option<EntryLanes>,
}

impl Default for RaycastSettings {
    fn default() -> Self {
        Self {
            segments: Segments::Partial,
            entry: Entry::default(),
            list_capacity: 4,
            skip_empty_tiles: true,
            max_steps: None,
            table_size: 128,
            table_lengths: 64,
            entry_lanes: None,
        }
    }
}

/// The default step limit for a mesh of `tets` tets: 64 times the tets along the edge of a cube
/// of that many (a ray across a regular grid crosses a few per cell), at least 4096.
pub fn default_max_steps(tets: usize) -> u32 {
    let side = (tets as f64).cbrt().ceil() as u32;
    side.saturating_mul(64).max(4096)
}

/// The eye-space z of the near plane of entry bounds, and the eye-in-tet tolerance: 1e-5 of
/// the bounding radius, above f32 rounding of eye-space coordinates.
fn near_tol(radius: f64) -> f32 {
    (1e-5 * radius) as f32
}

/// From how far, in bounding radii from the mesh centre, the ray casters (`--mode raycast`,
/// the shells' walk sampler, `raycast-cpu`) measure their rays from the pivot
/// (`ViewFrame::pivot_uniforms`, `shaders/raycast_shared.wgsl`) rather than from the eye.
/// Measured from the eye, f32 rounds eye-space vertices, planes and t to ~6e-8 D, an rmse of
/// about 5e-8 per radius of the eye's distance on the stress cube (6.3e-7 at 10 radii, 5.0e-6
/// at 1e2), against 2e-7 from the pivot at every distance from 1e2 to 1e6. Nearer than this,
/// where the two differ only by rounding, the eye stays the origin: the eye's own tet and the
/// near plane keep their arithmetic, and no near picture changes a bit (a needle of the
/// stress suite's 1e-12 case sends one ray the wrong way through its thin tets under either
/// rounding: `tests/stress.rs`).
pub const PIVOT_RADII: f64 = 10.0;

/// The ray casters' frame uniforms for `view` of a mesh with bounding sphere (`origin`,
/// `radius`): measured from the pivot where the eye is more than [`PIVOT_RADII`] radii from
/// the centre, else from the eye (`pivot_z` 0).
pub(crate) fn view_uniforms(
    view: &ViewFrame,
    origin: DVec3,
    radius: f64,
    near_z: f32,
    tets: u32,
) -> ViewUniforms {
    match (view.eye - origin).length() > PIVOT_RADII * radius {
        true => view.pivot_uniforms(origin, 0.0, near_z, tets),
        false => view.uniforms(origin, 0.0, near_z, tets),
    }
}

/// The eye's tet is searched for only when the eye lies in the mesh's bounding box grown by
/// this many eye tolerances (`near_tol`). The search takes a tet whose four planes each lie
/// at most the tolerance from the eye: the tet scaled about its incentre, which reaches
/// `tolerance R / r` beyond a corner at distance `R` from the incentre (`r`: the inradius;
/// R / r is 3 for a regular tet, under 5 for a grid's); 64 leaves room for worse shapes and
/// f32 rounding of eye-space vertices (far below the tolerance). A sliver at the boundary
/// with R / r above 64 (thin tets are only those under 1e-5) can reach further, so an eye just
/// outside the box could be taken into it by the full search; such an eye is outside every
/// tet, and skipping the search lets its rays enter through the boundary faces, as they do
/// for any eye outside the mesh (the CPU ray caster still searches, so the two can differ
/// there).
pub const EYE_BOX_GROWTH: f64 = 64.0;

/// When the planes stage runs, what it is for: its two results change with different things.
/// The eye's tet only matters when the eye may be inside the mesh; the thin tets are counted in
/// eye space (f32), where a tet at the threshold may count in one view and not in another, so
/// the count reported is the one of the last frame that ran the stage, at least once per
/// position update (exact per mesh, positions and view for tets clear of the threshold,
/// e.g. the blunt fin's coincident corners).
#[derive(Clone, Copy, Debug, Default)]
struct PlanesStage {
    /// The thin tets counted and the positions version they were counted for.
    thin: Option<(u64, u32)>,
    /// The positions version the current frame counts for, when it runs the stage.
    now: Option<u64>,
}

/// The ray caster; see the module docs.
pub struct RaycastRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The adapter's name and limits (for [`Self::set_entry`]'s check).
    adapter: String,
    limits: wgpu::Limits,
    settings: RaycastSettings,
    mesh: Arc<GpuTetMesh>,
    pipelines: Pipelines,
    frame: FrameResources,
    frame_buf: wgpu::Buffer,
    tf_buf: wgpu::Buffer,
    params_buf: wgpu::Buffer,
    /// The depth-peeling layer ([`LayerUniforms`]).
    layer_buf: wgpu::Buffer,
    /// Per layer: rays that wait for a later layer, and whether a pixel had a second hit.
    progress: wgpu::Buffer,
    /// [`COUNTERS`] u32s, and their mappable copy followed by the layer's tile count and
    /// [`Self::progress`] (one readback per layer).
    counters: wgpu::Buffer,
    counters_read: wgpu::Buffer,
    /// The links in windows of `link_chunk` tets ([`links::chunking`]).
    links: TetArray,
    link_chunk: u64,
    /// Eye-space position and normalized scalar per vertex, written each frame.
    verts: wgpu::Buffer,
    boundary: wgpu::Buffer,
    boundary_count: u32,
    /// The psi table ([`psi::table`]), uploaded on the first partial frame; 16 bytes before.
    psi: wgpu::Buffer,
    /// The 3D pre-integration table (`Segments::Table`) and what it was built for; 16 bytes
    /// before the first table frame.
    preint: wgpu::Buffer,
    preint_key: Option<TableKey>,
    max_edge: LongestEdge,
    /// Hits each pixel's list holds now.
    capacity: u32,
    /// The eye-in-tet tolerance of the current frame ([`near_tol`]).
    eye_tol: f32,
    /// The current frame's pivot distance ([`ViewUniforms::pivot_z`]): the walk's slices are
    /// measured from it.
    pivot_z: f32,
    /// Whether this frame runs the planes stage, and what it counted last.
    planes: PlanesStage,
    targets: Option<Targets>,
    /// A textured cage's volume and texture coordinates ([`RaycastRenderer::textured`]).
    texture: Option<GpuTexture>,
    /// A textured cage's isovalues ([`RaycastRenderer::textured_iso`]).
    iso: Option<TexturedIso>,
    /// The shells' walk sampler's slices ([`RaycastRenderer::sliced`]); `None` for the ray
    /// caster's own integrators.
    slicing: Option<Slicing>,
}

/// Where the shells' walk sampler's slices lie for one frame: slice `k` at distance
/// `t_first + k dz` from the eye, `k < count` (`crate::gpu::shells`' plan); and where its rays
/// stop: before the first slice of a shell of `shell_slices` (at least 1) once their
/// transmittance is below `terminate` (`shaders/raycast_slices.wgsl`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Slicing {
    pub t_first: f64,
    pub dz: f64,
    pub count: u32,
    pub shell_slices: u32,
    pub terminate: f32,
}

/// Per image size and entry method: the output, its readback, the per-pixel entry buffers,
/// the tile list (a clone shares them).
#[derive(Clone)]
struct Targets {
    width: u32,
    height: u32,
    image: wgpu::Texture,
    readback: ImageReadback,
    pixels: PixelBuffers,
    /// The traversal's indirect dispatch, the list's length, and the tiles listed
    /// (`shaders/raycast_tiles.wgsl`).
    tiles: wgpu::Buffer,
    /// A textured cage's isosurface hits per pixel ([`RaycastRenderer::textured_iso`]).
    hits: Option<HitBuffers>,
}

/// The per-pixel buffers of an entry method.
#[derive(Clone)]
enum PixelBuffers {
    /// The hits each pixel's list has, and `capacity` hits per pixel.
    Lists {
        counts: wgpu::Buffer,
        entries: wgpu::Buffer,
        capacity: u32,
    },
    /// The layer's peeled hit (two u32s per pixel), and the rays' states between layers.
    Peel {
        hits: wgpu::Buffer,
        rays: wgpu::Buffer,
    },
}

impl PixelBuffers {
    fn size(&self) -> u64 {
        match self {
            Self::Lists {
                counts, entries, ..
            } => counts.size() + entries.size(),
            Self::Peel { hits, rays } => hits.size() + rays.size(),
        }
    }
}

impl RaycastRenderer {
    /// Builds the links and the boundary over a mesh already on the GPU (the pipelines are
    /// built by the first frame that runs each, `pipelines.rs`).
    pub fn with_mesh(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: RaycastSettings,
    ) -> Result<Self, RenderError> {
        check_limits(ctx, settings.entry, None)?;
        captured(&ctx.device, BUILD, || {
            Self::build(ctx, mesh, settings, None, false)
        })
    }

    /// The traversal of the shells' walk sampler over a mesh already on the GPU (its limits
    /// checked by the shells renderer, [`Setting::Shells`]): each segment composites the
    /// slices it holds (`shaders/raycast_slices.wgsl`) instead of integrating the TF,
    /// `settings.segments` unused; frames come from [`Self::render_slices`].
    /// With `texture` (a textured cage's, over `mesh` as its cage), the slices read its volume
    /// (`shaders/raycast_slices_texture.wgsl`).
    pub(crate) fn sliced(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: RaycastSettings,
        texture: Option<GpuTexture>,
    ) -> Result<Self, RenderError> {
        let textured = texture.map(|t| (t, TextureUse::Volume));
        let mut r = Self::build(ctx, mesh, settings, textured, true)?;
        r.slicing = Some(Slicing::default());
        Ok(r)
    }

    /// A frame of the walk sampler ([`Self::sliced`]) with the slices of `slicing`; `camera`,
    /// `tf` and the slices in the mesh's f32 frame, as the shells renderer has them.
    pub(crate) fn render_slices(
        &mut self,
        camera: &Camera,
        tf: &TransferFunction,
        slicing: Slicing,
    ) -> Result<Frame, RenderError> {
        if self.slicing.is_none() {
            return Err(RenderError::Internal(
                "slices rendered by a ray caster built without them",
            ));
        }
        self.slicing = Some(slicing);
        self.frame(camera, Some(tf))
    }

    /// The ray caster of a textured cage (issue 12): `cage`'s vertices carry `texcoords`, and
    /// each tet segment is stepped through `volume` every `step` world units (`None`: the
    /// textured reference's default) instead of integrating the cage's own scalars
    /// (`shaders/raycast_texture.wgsl`); [`Renderer::update_positions`] moves the volume with
    /// the cage. The TF applies to the volume's values; `settings.segments` is not used.
    pub fn textured(
        ctx: &GpuContext,
        cage: &TetMesh,
        texcoords: &[DVec3],
        volume: &crate::texture::Volume,
        step: Option<f64>,
        settings: RaycastSettings,
    ) -> Result<Self, RenderError> {
        check_limits(ctx, settings.entry, Some(TextureUse::Volume))?;
        captured(&ctx.device, TEXTURED_BUILD, || {
            let texture = GpuTexture::for_cage(ctx, cage, volume, texcoords, step)?;
            let textured = Some((texture, TextureUse::Volume));
            Self::build(ctx, GpuTetMesh::new(ctx, cage)?, settings, textured, false)
        })
    }

    fn build(
        ctx: &GpuContext,
        mesh: Arc<GpuTetMesh>,
        settings: RaycastSettings,
        textured: Option<(GpuTexture, TextureUse)>,
        sliced: bool,
    ) -> Result<Self, RenderError> {
        let nt = mesh.tet_count() as u64;
        let nv = mesh.read().positions.len() as u64;
        // The limits first, then the face adjacency (seconds on a mesh of tens of millions of
        // tets), so a mesh that does not fit is refused at once.
        check_fits(&ctx.limits, nv, &settings)?;
        let chunking = links::chunking(nt, &ctx.limits)?;
        check_cells(&mesh)?;
        let m = mesh.read();
        let topology = links::Topology::build(&m.tets);
        check_boundary(&ctx.limits, topology.boundary.len() as u64)?;
        let links = mesh.tet_array("raycast links", chunking, nt, links::LINK_BYTES)?;
        // The walk sampler's slices read a textured cage's volume themselves: no textured
        // traversal of the ray caster's own.
        let field = match (sliced, &textured) {
            (false, _) => None,
            (true, None) => Some(SliceField::Mesh),
            (true, Some(_)) => Some(SliceField::Texture),
        };
        let own_texture = (!sliced).then_some(textured.as_ref()).flatten();
        // Computed tet by tet into the upload's pieces: no whole copy of the links (3.2 GB
        // for 100M tets) on the host.
        links.write_with(mesh.uploader(), nt as usize, |t| topology.link(&m.tets, t));
        let boundary_faces = topology.boundary.len();
        let boundary = frame::storage(&ctx.device, "raycast boundary", 4 * boundary_faces);
        (mesh.uploader()).slice(&boundary, 0, &topology.boundary);
        drop((topology, m));
        let device = ctx.device.clone();
        let uniform = |label: &str, bytes: usize| uniform_buffer(&device, label, bytes);
        Ok(Self {
            pipelines: Pipelines::new(
                &device,
                nt.div_ceil(chunking.chunk).max(1),
                mesh.has_cells(),
                own_texture.map(|(_, used)| *used),
                field,
                (settings.entry_lanes).unwrap_or_else(|| EntryLanes::for_adapter(ctx)),
            ),
            frame: FrameResources::new(ctx),
            frame_buf: uniform("raycast frame", size_of::<ViewUniforms>()),
            tf_buf: uniform("raycast tf", size_of::<TfPoints>()),
            params_buf: uniform("raycast constants", size_of::<RaycastUniforms>()),
            layer_buf: uniform("raycast layer", size_of::<LayerUniforms>()),
            progress: frame::storage(&device, "raycast layer progress", 16),
            counters: frame::storage(&device, "raycast counters", 4 * COUNTERS),
            counters_read: frame::mappable(&device, "raycast counters readback", READ_BYTES),
            links,
            link_chunk: chunking.chunk,
            verts: frame::storage(&device, "raycast eye-space vertices", 16 * nv as usize),
            boundary,
            boundary_count: boundary_faces as u32,
            psi: frame::storage(&device, NO_PSI, 16),
            preint: frame::storage(&device, "raycast 3D table (none yet)", 16),
            preint_key: None,
            max_edge: LongestEdge::default(),
            capacity: settings.list_capacity.max(1),
            eye_tol: 0.0,
            pivot_z: 0.0,
            planes: PlanesStage::default(),
            queue: ctx.queue.clone(),
            adapter: ctx.info.name.clone(),
            limits: ctx.limits.clone(),
            device,
            settings,
            mesh,
            targets: None,
            texture: textured.map(|(t, _)| t),
            iso: None,
            slicing: None,
        })
    }

    /// Uploads the mesh and builds the renderer over it ([`Self::with_mesh`]).
    /// An adapter short of a limit is refused before anything is uploaded.
    pub fn new(ctx: &GpuContext, mesh: &TetMesh, s: RaycastSettings) -> Result<Self, RenderError> {
        check_limits(ctx, s.entry, None)?;
        captured(&ctx.device, BUILD, || {
            Self::build(ctx, GpuTetMesh::new(ctx, mesh)?, s, None, false)
        })
    }

    /// The settings in use.
    pub fn settings(&self) -> RaycastSettings {
        self.settings
    }

    /// Switches the segment integrator (the psi table is uploaded on the next frame that
    /// needs it).
    pub fn set_segments(&mut self, segments: Segments) {
        self.settings.segments = segments;
    }

    /// Switches how rays find their entries (the per-pixel buffers follow on the next frame);
    /// [`GpuError::Limit`](crate::gpu::GpuError::Limit), and no switch, where the adapter's
    /// limits are short of the new method's stages ([`Setting::Raycast`]).
    pub fn set_entry(&mut self, entry: Entry) -> Result<(), RenderError> {
        let texture = match (&self.iso, &self.texture) {
            (Some(_), _) => Some(TextureUse::Isosurfaces),
            (None, Some(_)) => Some(TextureUse::Volume),
            (None, None) => None,
        };
        let setting = Setting::Raycast { entry, texture };
        setting.check(&self.adapter, &self.limits)?;
        self.settings.entry = entry;
        Ok(())
    }

    /// Bytes per tet of what scales with the mesh: the links, the boundary, the vertex
    /// buffers (positions, scalars, eye-space vertices) and, for cell data, the tets' values.
    pub fn bytes_per_tet(&self) -> f64 {
        let cells = self.mesh.uploaded_cells().map_or(0, TetArray::size);
        let mesh = self.mesh.positions().size() + self.mesh.scalars().size() + cells;
        let own = self.links.size() + self.verts.size() + self.boundary.size();
        (mesh + own) as f64 / self.mesh.tet_count().max(1) as f64
    }
}

/// An error unless `ctx`'s limits offer what the ray caster with `entry` over `texture`'s
/// field (`None`: the mesh's) needs ([`Setting::Raycast`]); checked before anything is
/// uploaded.
pub(crate) fn check_limits(
    ctx: &GpuContext,
    entry: Entry,
    texture: Option<TextureUse>,
) -> Result<(), RenderError> {
    Ok(ctx.check_setting(Setting::Raycast { entry, texture })?)
}

/// Uploads a cell-data mesh's values per tet, which the traversal binds as one window; an
/// error when they do not fit one buffer (they take an eighth of the links' bytes, so a mesh
/// whose links fit the ray caster's windows never gets it).
fn check_cells(mesh: &GpuTetMesh) -> Result<(), RenderError> {
    match mesh.cells()? {
        Some(cells) if cells.buffer_count() > 1 => Err(settings_error(format!(
            "the ray caster (--mode raycast, and shells' --sampler walk) binds the {} tets' cell values (4 bytes each) as one buffer, and \
             this adapter's buffers hold less; use --mode cellproj, or shells' --sampler raster, for this mesh",
            mesh.tet_count()
        ))),
        _ => Ok(()),
    }
}

/// An error unless the ray caster's buffers sized before its first frame fit an adapter with
/// `limits`: the eye-space positions of `vertices` vertices, the links of `tets` tets and,
/// at a `width` x `height` image, the per-pixel buffers of `settings.entry` (lists at their
/// first length). What the walk sampler needs beyond its stages' limits, weighed before a
/// mesh's face adjacency is built (`sampler: auto`, [`crate::scene::Scene::auto_sampler`]);
/// the boundary faces (one binding: only a soup of loose tets comes near it) and the lists a
/// frame grows to are not.
pub fn fits(
    limits: &wgpu::Limits,
    tets: u64,
    vertices: u64,
    (width, height): (u32, u32),
    settings: &RaycastSettings,
) -> Result<(), RenderError> {
    check_fits(limits, vertices, settings)?;
    links::chunking(tets, limits)?;
    let capacity = settings.list_capacity.max(1);
    frame::check_pixel_buffers(limits, settings.entry, capacity, width, height).map(|_| ())
}

/// An error unless the `faces` boundary faces (4 bytes each) fit the one storage binding the
/// entry stages read them from (a grid of 100M tets has 0.8M; only a soup of loose tets
/// comes near a binding).
fn check_boundary(limits: &wgpu::Limits, faces: u64) -> Result<(), RenderError> {
    let max = largest_binding(limits);
    if 4 * faces > max {
        return Err(settings_error(format!(
            "the ray caster (--mode raycast, and shells' --sampler walk) binds the mesh's \
             {faces} boundary faces (4 bytes each) as one storage binding, and this adapter \
             binds at most {max} bytes; use --mode cellproj, or shells' --sampler raster, for \
             this mesh"
        )));
    }
    Ok(())
}

/// An error unless the eye-space vertices fit one storage binding and the table has at least
/// 2 samples per axis (the links: [`links::chunking`]; the table's size: `frame.rs`).
fn check_fits(
    limits: &wgpu::Limits,
    vertices: u64,
    s: &RaycastSettings,
) -> Result<(), RenderError> {
    let max = largest_binding(limits);
    if vertices * 16 > max {
        return Err(settings_error(format!(
            "the ray caster (--mode raycast, and shells' --sampler walk) keeps its {vertices} vertices' eye-space positions (16 bytes each) \
             in one storage binding, and this adapter binds at most {max} bytes; use --mode \
             cellproj, or shells' --sampler raster, for this mesh"
        )));
    }
    if s.table_size < 2 || s.table_lengths < 2 {
        return Err(settings_error(format!(
            "the pre-integration table needs at least 2 samples per axis, not {} scalars x {} \
             lengths",
            s.table_size, s.table_lengths
        )));
    }
    Ok(())
}

impl KeptFrames for RaycastRenderer {
    fn mesh(&self) -> &GpuTetMesh {
        &self.mesh
    }

    /// The targets, the 3D table (its buffer made again, not reused at its size), the psi
    /// table (a frame of partial segments uploads it again) and the statistics buffers.
    fn forget_frame(&mut self) {
        self.targets = None;
        self.preint_key = None;
        self.psi = frame::storage(&self.device, NO_PSI, 16);
        self.frame.forget();
    }
}

impl Renderer for RaycastRenderer {
    /// `iso` for a textured cage's isosurfaces, else `raycast`.
    fn name(&self) -> &'static str {
        match self.iso {
            Some(_) => "iso",
            None => "raycast",
        }
    }

    /// The picture; for a textured cage's isosurfaces the shaded surfaces, `tf` unused (the
    /// colours come with the isovalues).
    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        let frame = self.mesh.frame();
        // A lost device fails here as an error, not as wgpu's panic.
        let work = match self.iso {
            Some(_) => texture_iso::FRAME,
            None => FRAME,
        };
        captured_frame(self, work, |r| {
            r.frame(&frame.camera(camera), Some(&frame.tf(tf)?))
        })
    }

    /// Refused, and nothing moved, where a textured cage's step would sample the moved cage
    /// too finely (`texture::check_step`).
    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        if let Some(step) = self.texture.as_ref().and_then(|t| t.step) {
            let count = self.mesh.read().positions.len();
            crate::texture::check_step(step, checked_bounds(positions, count)?)?;
        }
        self.mesh.update_positions(positions)
    }

    /// Refused for a textured cage, whose field is its texture.
    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        if self.texture.is_some() {
            return Err(settings_error(
                "a textured cage renders its volume texture; vertex scalars cannot be updated",
            ));
        }
        self.mesh.update_scalars(scalars)
    }

    fn gpu_memory(&self) -> u64 {
        let buffers: u64 = [
            &self.frame_buf,
            &self.tf_buf,
            &self.params_buf,
            &self.layer_buf,
            &self.progress,
            &self.counters,
            &self.counters_read,
            &self.boundary,
            &self.verts,
            &self.psi,
            &self.preint,
        ]
        .iter()
        .map(|b| b.size())
        .sum();
        let targets = self.targets.as_ref().map_or(0, |t| {
            t.pixels.size()
                + t.tiles.size()
                + t.readback.size()
                + 16 * t.width as u64 * t.height as u64
                + t.hits.as_ref().map_or(0, HitBuffers::size)
        });
        let texture = self.texture.as_ref().map_or(0, GpuTexture::bytes)
            + self
                .iso
                .as_ref()
                .map_or(0, |i| i.uniforms.size() + i.ranges.size());
        self.mesh.gpu_memory() + buffers + self.links.size() + self.frame.size() + targets + texture
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::h200::{self, GRID_100M_TETS, GRID_100M_VERTICES};

    #[test]
    fn the_100m_grid_fits_the_ray_caster_under_the_h200_s_limits() {
        let limits = h200::limits();
        let settings = RaycastSettings::default();
        check_fits(&limits, GRID_100M_VERTICES, &settings).unwrap();
        // Eye-space vertices in one binding of 2147483644 bytes: 134,217,727 at most.
        assert!(check_fits(&limits, 134_217_727, &settings).is_ok());
        assert!(check_fits(&limits, 134_217_728, &settings).is_err());
        // The grid's boundary: 6 sides of 255 x 255 squares of 2 triangles (3 MB); a binding
        // holds 536,870,911 faces, not one more.
        check_boundary(&limits, 6 * 255 * 255 * 2).unwrap();
        assert!(check_boundary(&limits, 536_870_911).is_ok());
        let err = check_boundary(&limits, 536_870_912)
            .unwrap_err()
            .to_string();
        assert!(err.contains("536870912 boundary faces"), "{err}");
        assert!(err.contains("--mode cellproj"), "{err}");
        // The step limit: 64 x 464 (the cube root of the tets, rounded up), far above the
        // ~1,800 tets a ray crosses along the grid's diagonal (255 sqrt 3 cubes, about 4 tets
        // each).
        assert_eq!(default_max_steps(GRID_100M_TETS as usize), 29_696);
    }
}
