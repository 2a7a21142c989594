//! `--mode raycast-cpu`: the GPU ray caster's traversal and integrators in Rust, f32, on every
//! core (rayon over 16 x 16 pixel tiles), needing no adapter: what `auto` renders with when
//! the machine has no GPU or only a software one (see [`crate::mode`]).
//!
//! Once per mesh, the tets are renumbered along a Morton curve of their centroids
//! (`order.rs`), so that a ray's next tet is usually in cache; the pictures are those of the
//! file's numbering.
//!
//! Per frame (stages 1 and 2 only for a new view: their results are kept and reused while the
//! camera, the positions and the scalars stay the same, as when only the TF changes; the
//! `planes reused` count says so):
//! 1. planes (`scene.rs`): every vertex in eye space, then every tet's outward face planes and
//!    linear scalar from the current positions (the GPU's arithmetic, [`twin::planes`](crate::gpu::raycast::twin::planes): shared
//!    faces get bit-identical negated planes, thin tets a constant scalar), stored beside its
//!    links in one 112-byte record, and the eye's tet;
//! 2. entries (`scene.rs`): the boundary faces that face the eye, each set up once (plane,
//!    edge Pluecker normals) and binned to the tiles its projection covers;
//! 3. traverse (`trace.rs`): per pixel, the tile's faces its ray enters through (watertight edge
//!    tests, sorted by t then face code in the file's numbering), then the walk through face
//!    adjacency from the eye's tet or the first entry, each segment integrated by
//!    `integrate.rs` (partial pre-integration or exact), re-entering non-convex meshes at the
//!    next entry, with early ray termination and a counted step limit.
//!
//! Cell data ([`TetMesh::cell_scalars`]): each segment takes its tet's normalized value at both
//! ends (the GPU traversal's `CELLS`); the planes, and so the walk, are those of the per-vertex
//! field as for point data. Such a renderer refuses [`Renderer::update_scalars`]
//! (`gpu::mesh::cell_update_error`).
//!
//! The robustness rules are the GPU's (see [`crate::gpu::raycast`]); the exit and plane
//! arithmetic is its CPU twin's ([`crate::gpu::raycast::twin`]), so both paths walk the same tets.

mod integrate;
mod order;
mod scene;
mod texture;
mod trace;

use std::sync::Arc;
use std::time::Instant;

use bytemuck::bytes_of;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::camera::{Camera, check_frame_memory};
use crate::gpu::gpu_data::ViewUniforms;
use crate::gpu::mesh::cell_update_error;
use crate::gpu::raycast::{default_max_steps, links};
use crate::gpu::util::{F32Frame, far_eye, ms_since, scalar_frame, sphere_of};
use crate::gpu::view::ViewFrame;
use crate::image::Image;
use crate::mesh::{MeshError, TetMesh, check_values, checked_bounds};
use crate::render::{Frame, RenderError, Renderer, Timings};
use crate::texture::Volume;
use crate::texture::{check_step, sampling_step};
use crate::tf::TransferFunction;

use integrate::SegmentTf;
use scene::{Bins, TILE, Tet, TetPass};
use texture::{CpuTexture, TexturedField};

/// How the CPU ray caster integrates each segment (both split it at the TF's control points,
/// as the GPU's [`crate::gpu::raycast::Segments`]; the 3D table is the GPU's alone).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Segments {
    /// Partial pre-integration: each piece's mean transmittance from the psi table.
    #[default]
    Partial,
    /// Each piece's mean transmittance by quadrature converged to f32.
    Exact,
}

/// Settings of the CPU ray caster.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CpuRaycastSettings {
    /// Segment integration.
    pub segments: Segments,
    /// Tets one ray may step through; `None`: [`default_max_steps`] of the mesh.
    pub max_steps: Option<u32>,
}

/// The CPU ray caster; see the module docs.
pub struct CpuRaycastRenderer {
    settings: CpuRaycastSettings,
    /// The positions' frame: the f32 frame's scale, and in it the bounding-box centre and the
    /// bounding-sphere radius.
    f32_frame: F32Frame,
    origin: DVec3,
    radius: f64,
    /// Positions relative to `origin` in f32, as the GPU reads them.
    positions: Vec<Vec3>,
    /// Scalars normalized as `(s - scalar_min) / scalar_span`, f32.
    scalars: Vec<f32>,
    raw_scalars: Vec<f64>,
    /// Cell data: the value per tet (in Morton order), normalized as `scalars`; `None` for
    /// point data.
    cells: Option<Vec<f32>>,
    raw_cells: Option<Vec<f64>>,
    scalar_min: f64,
    scalar_span: f64,
    /// The tets' vertices in Morton order ([`order::Renumbering`]), their links and each
    /// one's index in the file.
    tet_ids: Vec<[u32; 4]>,
    topology: scene::Topology,
    /// Boundary face codes (`4 * tet + face`).
    boundary: Vec<u32>,
    /// Per view, kept to reuse their memory: eye-space positions, per-tet records.
    eye: Vec<Vec3>,
    tets: Vec<Tet>,
    /// The view `eye` and `tets` hold, with what the planes and entries found for it; `None`
    /// after the positions or scalars change.
    view: Option<ViewGeometry>,
    /// A textured cage's volume and texture coordinates ([`CpuRaycastRenderer::textured`]).
    texture: Option<CpuTexture>,
}

impl CpuRaycastRenderer {
    /// Copies `mesh` (its active scalars) and builds its links; errors when it has no scalars.
    /// (A mesh's tets fit its face codes in a u32: [`crate::mesh::MAX_TETS`].)
    pub fn new(mesh: &TetMesh, settings: CpuRaycastSettings) -> Result<Self, RenderError> {
        let order = order::Renumbering::morton(mesh.positions(), mesh.tets());
        let tet_ids = order.apply(mesh.tets());
        let (links, boundary) = links::build(&tet_ids);
        let mut r = Self {
            settings,
            f32_frame: F32Frame { scale: 1.0 },
            origin: DVec3::ZERO,
            radius: 0.0,
            positions: Vec::new(),
            scalars: Vec::new(),
            raw_scalars: mesh.scalars()?.to_vec(),
            cells: None,
            raw_cells: mesh.cell_scalars().map(|c| order.apply(c)),
            scalar_min: 0.0,
            scalar_span: 1.0,
            tet_ids,
            topology: scene::Topology {
                links,
                original: order.original,
            },
            boundary,
            eye: Vec::new(),
            tets: Vec::new(),
            view: None,
            texture: None,
        };
        r.set_positions(mesh.positions(), mesh.bounds())?;
        r.normalize_scalars()?;
        Ok(r)
    }

    /// The CPU ray caster of a textured cage (issue 12): `cage`'s vertices carry `texcoords`,
    /// and each tet segment is stepped through `volume` every `step` world units (`None`: the
    /// textured reference's default), as the GPU's [`RaycastRenderer::textured`] does; the TF
    /// applies to the volume's values.
    ///
    /// [`RaycastRenderer::textured`]: crate::gpu::RaycastRenderer::textured
    pub fn textured(
        cage: &TetMesh,
        texcoords: &[DVec3],
        volume: Arc<Volume>,
        step: Option<f64>,
        settings: CpuRaycastSettings,
    ) -> Result<Self, RenderError> {
        if texcoords.len() != cage.vertex_count() || cage.cell_scalars().is_some() {
            return Err(RenderError::Settings(format!(
                "a textured cage needs one texture coordinate per vertex ({} for {} vertices) \
                 and point data, not cell data",
                texcoords.len(),
                cage.vertex_count()
            )));
        }
        let step = sampling_step(step, &volume, cage)?;
        let mut r = Self::new(cage, settings)?;
        r.texture = Some(CpuTexture {
            volume,
            texcoords: texcoords.iter().map(|t| t.as_vec3()).collect(),
            step,
        });
        Ok(r)
    }

    /// The settings in use.
    pub fn settings(&self) -> CpuRaycastSettings {
        self.settings
    }

    /// `positions`, whose bounding box is `bounds`, in their f32 frame relative to the box's
    /// centre, as the GPU has them; an error, and nothing changed, when the frame cannot hold
    /// them ([`F32Frame::of`]).
    fn set_positions(
        &mut self,
        positions: &[DVec3],
        bounds: (DVec3, DVec3),
    ) -> Result<(), RenderError> {
        let frame = F32Frame::of(bounds)?;
        self.f32_frame = frame;
        (self.origin, self.radius) = sphere_of((frame.point(bounds.0), frame.point(bounds.1)));
        let o = self.origin;
        self.positions = (positions.par_iter())
            .map(|&p| (frame.point(p) - o).as_vec3())
            .collect();
        Ok(())
    }

    /// Normalizes the vertex scalars and any cell values into [0, 1] over both's range; an
    /// error, and nothing changed, where that range overflows ([`scalar_frame`]).
    fn normalize_scalars(&mut self) -> Result<(), MeshError> {
        (self.scalar_min, self.scalar_span) = match &self.raw_cells {
            Some(c) => scalar_frame(&[self.raw_scalars.as_slice(), c].concat())?,
            None => scalar_frame(&self.raw_scalars)?,
        };
        let frame = (self.scalar_min, self.scalar_span);
        self.scalars = normalized(&self.raw_scalars, frame);
        self.cells = (self.raw_cells.as_deref()).map(|c| normalized(c, frame));
        Ok(())
    }

    /// Stages 1 and 2 for view `f`: eye-space positions and per-tet records into `self.eye`
    /// and `self.tets`, then the entry bins; their times into `timings`. The eye-in-tet
    /// tolerance is `f.near_z`, as on the GPU.
    fn view_geometry(&mut self, f: ViewUniforms, timings: &mut Timings) -> ViewGeometry {
        let t = Instant::now();
        scene::eye_positions(&f, &self.positions, &mut self.eye);
        let pass = scene::tets(
            &self.eye,
            &self.scalars,
            &self.topology,
            f.near_z,
            f.pivot_z,
            &mut self.tets,
        );
        timings.stage("planes", ms_since(t));
        let t = Instant::now();
        let bins = scene::bins(&f, &self.boundary, &self.tets, &self.topology, &self.eye);
        timings.stage("entries", ms_since(t));
        ViewGeometry {
            frame: f,
            pass,
            bins,
        }
    }

    fn frame(&mut self, camera: &Camera, tf: &TransferFunction) -> Frame {
        let start = Instant::now();
        let mut timings = Timings {
            clock: "wall clock",
            ..Timings::default()
        };
        // The eye-in-tet tolerance: 1e-5 of the bounding radius (the GPU's).
        let eye_tol = (1e-5 * self.radius) as f32;
        // From a far eye, measured from a pivot near the mesh, as the GPU's ray caster.
        let f = crate::gpu::raycast::view_uniforms(
            &ViewFrame::new(camera),
            self.origin,
            self.radius,
            eye_tol,
            self.topology.links.len() as u32,
        );
        let reused = (self.view.as_ref()).is_some_and(|v| bytes_of(&v.frame) == bytes_of(&f));
        let view = match self.view.take() {
            Some(v) if reused => v,
            _ => self.view_geometry(f, &mut timings),
        };
        let (pass, bins) = (view.pass, &view.bins);
        let t = Instant::now();
        let seg = SegmentTf::new(
            tf,
            self.scalar_min,
            self.scalar_span,
            self.settings.segments,
        );
        timings.stage("tf", ms_since(t));
        let t = Instant::now();
        let field = self.texture.as_ref().map(|texture| TexturedField {
            texture,
            step: self.f32_frame.length(texture.step) as f32,
            tf,
            eye: &self.eye,
        });
        let sc = trace::Scene {
            frame: &f,
            tets: &self.tets,
            ids: &self.tet_ids,
            cells: self.cells.as_deref(),
            eye: &self.eye,
            bins,
            eye_tet: pass.eye_tet,
            eye_tol,
            max_steps: (self.settings.max_steps)
                .unwrap_or_else(|| default_max_steps(self.topology.links.len())),
            texture: field.as_ref(),
        };
        let (image, work) = render_tiles(&sc, &seg, camera.width, camera.height);
        timings.stage("traverse", ms_since(t));
        timings.stage("total", ms_since(start));
        timings.count("tets", self.topology.links.len() as u64);
        timings.count("boundary faces", self.boundary.len() as u64);
        timings.count("faces in tiles", bins.len() as u64);
        timings.count("thin tets", pass.thin);
        timings.count("planes reused", reused as u64);
        timings.count(
            "eye in a tet",
            (pass.eye_tet != crate::mesh::topology::NO_NEIGHBOR) as u64,
        );
        timings.count("tet steps", work.steps);
        timings.count("rays at step limit", work.stopped);
        timings.count("threads", rayon::current_num_threads() as u64);
        self.view = Some(view);
        Frame { image, timings }
    }
}

/// What stages 1 and 2 found for one view (`frame`); `eye` and `tets` of the renderer hold the
/// rest.
struct ViewGeometry {
    frame: ViewUniforms,
    pass: TetPass,
    bins: Bins,
}

/// `values` as `(s - lo) / span` in f32, `(lo, span)` the scalar frame.
fn normalized(values: &[f64], (lo, span): (f64, f64)) -> Vec<f32> {
    values
        .par_iter()
        .map(|&s| ((s - lo) / span) as f32)
        .collect()
}

/// Every tile's rays in parallel (scratch for the entries reused per worker), then the tiles
/// into an image; and what the rays did.
fn render_tiles(
    sc: &trace::Scene,
    tf: &SegmentTf,
    width: u32,
    height: u32,
) -> (Image, trace::Work) {
    let tiles = sc.bins.tiles;
    let area = (TILE * TILE) as usize;
    let mut buf = vec![[0.0f32; 4]; (tiles.x * tiles.y) as usize * area];
    let work = (buf.par_chunks_mut(area).enumerate())
        .map_init(trace::Scratch::default, |s, (k, out)| {
            trace::tile(sc, tf, k, out, s)
        })
        .sum();
    let mut image = Image::new(width, height);
    let tile = TILE as usize;
    (image.pixels.par_chunks_mut(width as usize).enumerate()).for_each(|(y, row)| {
        for (x, px) in row.iter_mut().enumerate() {
            let k = (y / tile) * tiles.x as usize + x / tile;
            *px = buf[k * area + (y % tile) * tile + x % tile];
        }
    });
    (image, work)
}

impl Renderer for CpuRaycastRenderer {
    fn name(&self) -> &'static str {
        "raycast-cpu"
    }

    fn render(&mut self, camera: &Camera, tf: &TransferFunction) -> Result<Frame, RenderError> {
        camera.validate()?;
        // The tiles' pixels and the image's, 16 bytes each.
        check_frame_memory(camera.width, camera.height, 32)?;
        let tf = self.f32_frame.tf(tf)?;
        let camera = self.f32_frame.camera(camera);
        let sphere = (self.origin, self.radius);
        far_eye::check("raycast-cpu", far_eye::RAYCAST, camera.eye, sphere)?;
        Ok(self.frame(&camera, &tf))
    }

    /// Refused, and nothing moved, where a textured cage's step would sample the moved cage
    /// too finely (`texture::check_step`).
    fn update_positions(&mut self, positions: &[DVec3]) -> Result<(), RenderError> {
        let bounds = checked_bounds(positions, self.positions.len())?;
        if let Some(t) = &self.texture {
            check_step(t.step, bounds)?;
        }
        self.set_positions(positions, bounds)?;
        self.view = None;
        Ok(())
    }

    fn update_scalars(&mut self, scalars: &[f64]) -> Result<(), RenderError> {
        if self.cells.is_some() {
            return Err(cell_update_error());
        }
        if self.texture.is_some() {
            return Err(RenderError::Settings(
                "a textured cage renders its volume texture; vertex scalars cannot be updated"
                    .into(),
            ));
        }
        check_values("scalars", scalars, self.raw_scalars.len())?;
        // Checked before anything changes: refused, the renderer keeps its scalars.
        scalar_frame(scalars)?;
        self.raw_scalars.copy_from_slice(scalars);
        self.normalize_scalars()?;
        self.view = None;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::View;
    use crate::generate::fields::{Field, grid};

    fn reused(frame: &Frame) -> u64 {
        (frame.timings.counters.iter())
            .find(|c| c.0 == "planes reused")
            .map_or(u64::MAX, |c| c.1)
    }

    /// A second frame of the same view reuses the planes and entries and draws the same bits;
    /// a new view, or new scalars, draws what a renderer built for it draws (the same bits).
    #[test]
    fn a_view_is_reused_only_while_nothing_changed() {
        let mut mesh = grid(Field::Gaussians, glam::UVec3::splat(6), "g").unwrap();
        let (lo, hi) = mesh.bounds();
        let tf = TransferFunction::default_for_range(0.0, 1.0, mesh.diagonal() / 10.0).unwrap();
        let view = |azimuth_deg| View {
            azimuth_deg,
            elevation_deg: 20.0,
        };
        let cams = [30.0, 75.0].map(|a| Camera::framing(lo, hi, view(a), 1.0, 30.0, 40, 40));
        let fresh = |mesh: &TetMesh, camera: &Camera| {
            let mut r = CpuRaycastRenderer::new(mesh, Default::default()).unwrap();
            r.render(camera, &tf).unwrap().image.pixels
        };
        let mut r = CpuRaycastRenderer::new(&mesh, Default::default()).unwrap();
        let first = r.render(&cams[0], &tf).unwrap();
        let again = r.render(&cams[0], &tf).unwrap();
        assert_eq!((reused(&first), reused(&again)), (0, 1));
        assert_eq!(again.image.pixels, first.image.pixels);
        let turned = r.render(&cams[1], &tf).unwrap();
        assert_eq!(reused(&turned), 0);
        assert_eq!(turned.image.pixels, fresh(&mesh, &cams[1]));
        let scalars: Vec<f64> = mesh.scalars().unwrap().iter().map(|s| s * s).collect();
        r.update_scalars(&scalars).unwrap();
        let rescaled = r.render(&cams[1], &tf).unwrap();
        assert_eq!(reused(&rescaled), 0);
        mesh.set_scalars(scalars).unwrap();
        assert_eq!(rescaled.image.pixels, fresh(&mesh, &cams[1]));
        assert_ne!(rescaled.image.pixels, turned.image.pixels);
    }
}
