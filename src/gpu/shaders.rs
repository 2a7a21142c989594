//! The shader registry: WGSL sources, one file per stage in `shaders/`, composed at load time:
//! `shared.wgsl` (the view binding, structs and helpers) in front of each stage,
//! `invocation.wgsl` (an invocation's index in a dispatch over rows of workgroups) in front of
//! the assembly and the shells binning,
//! `shells_shared.wgsl` (the shells' own uniforms) in front of the shells stages,
//! `shells_span.wgsl` (the slice sampling) and `shells_tf.wgsl` (the composite) in front of
//! the stages of both shells samplers that use them, `tf_eval.wgsl` (the TF at one scalar) in
//! front of those and of the walk sampler's traversal, `raster.wgsl` (the volume raster
//! stages' varyings) in front of the shells and cellproj raster stages, plus a small generated
//! prelude where a stage depends on a pipeline variant. A textured cage's stages (issue 12)
//! add `texture_sample.wgsl` (trilinear reads of the volume, shared by the ray caster and
//! shells) and, in shells, `shells_texture.wgsl` (and `shells_raster_texture.wgsl`'s varyings
//! in place of `raster.wgsl`'s). Both isosurface stages (iso mode's raster, a textured cage's
//! isosurfaces) take `iso_shared.wgsl` (their constants and shading). [`registry`] lists every
//! module and variant the renderers load; `tests/shaders.rs` parses and validates each with
//! naga.

/// Structs mirroring [`crate::gpu::gpu_data`], the view uniform binding, the pixel ray.
pub const SHARED: &str = include_str!("../../shaders/shared.wgsl");
/// The segment integrator for the piecewise-linear TF (`fn integrate_segment`), shared by the
/// cellproj raster and the raycast traversal; a stage appends it after [`SHARED`], declares
/// `tf: TfPoints` and a `psi`, e.g. [`PSI_EXACT`].
pub const INTEGRATE_SEGMENT: &str = include_str!("../../shaders/integrate_segment.wgsl");

/// The exact mean transmittance as the segment integrator's `psi`.
pub const PSI_EXACT: &str =
    "fn psi(a: f32, b: f32) -> f32 {\n    return mean_transmittance(a, b);\n}\n";
const ASSEMBLE: &str = include_str!("../../shaders/assemble.wgsl");
/// An invocation's index in a dispatch spread over rows of 64-thread workgroups (`struct
/// Invocation`, `fn invocation_index`), in front of the assembly and the shells binning.
const INVOCATION: &str = include_str!("../../shaders/invocation.wgsl");
/// A tet's eye-space corners (`fn tet_corners`, bindings 13 and 16), in front of the stages
/// that draw or bin tets (shells, iso and cellproj raster).
const TET_CORNERS: &str = include_str!("../../shaders/tet_corners.wgsl");
/// The shells mode's own uniforms (slicing, per-shell constants), in front of its raster and
/// composite stages.
pub const SHELLS_SHARED: &str = include_str!("../../shaders/shells_shared.wgsl");
const SHELLS_SPAN: &str = include_str!("../../shaders/shells_span.wgsl");
const SHELLS_TF: &str = include_str!("../../shaders/shells_tf.wgsl");
/// The TF's evaluation at one scalar (`tf_value`, `tf_segment`, `tf_last`, called by the
/// generated [`tf_eval`]), shared by the shells composite, the fine stage and the walk
/// sampler's slices.
const TF_EVAL: &str = include_str!("../../shaders/tf_eval.wgsl");
const SHELLS_RASTER: &str = include_str!("../../shaders/shells_raster.wgsl");
const SHELLS_COMPOSITE: &str = include_str!("../../shaders/shells_composite.wgsl");
const SHELLS_TILES: &str = include_str!("../../shaders/shells_tiles.wgsl");
const SHELLS_FINE: &str = include_str!("../../shaders/shells_fine.wgsl");
const SHELLS_MARK: &str = include_str!("../../shaders/shells_mark.wgsl");
const SHELLS_BIN: &str = include_str!("../../shaders/shells_bin.wgsl");
/// Declarations the volume raster stages share (shells, cellproj).
pub(crate) const RASTER: &str = include_str!("../../shaders/raster.wgsl");
const ISO_RASTER: &str = include_str!("../../shaders/iso_raster.wgsl");
/// The isosurface constants, isovalue lookup and shading of both iso stages (`iso_raster`,
/// the textured cage's `raycast_texture_iso`).
const ISO_SHARED: &str = include_str!("../../shaders/iso_shared.wgsl");
const ISO_GRADIENTS: &str = include_str!("../../shaders/iso_gradients.wgsl");
const CELLPROJ_RASTER: &str = include_str!("../../shaders/cellproj_raster.wgsl");

const RAYCAST_SHARED: &str = include_str!("../../shaders/raycast_shared.wgsl");
const RAYCAST_RAYS: &str = include_str!("../../shaders/raycast_rays.wgsl");
const RAYCAST_COVER: &str = include_str!("../../shaders/raycast_cover.wgsl");
const RAYCAST_VERTICES: &str = include_str!("../../shaders/raycast_vertices.wgsl");
const RAYCAST_PLANES: &str = include_str!("../../shaders/raycast_planes.wgsl");
const RAYCAST_ENTRIES: &str = include_str!("../../shaders/raycast_entries.wgsl");
const RAYCAST_PEEL: &str = include_str!("../../shaders/raycast_peel.wgsl");
const RAYCAST_TILES: &str = include_str!("../../shaders/raycast_tiles.wgsl");
const RAYCAST_LISTS: &str = include_str!("../../shaders/raycast_lists.wgsl");
const RAYCAST_LAYERS: &str = include_str!("../../shaders/raycast_layers.wgsl");
const RAYCAST_TRAVERSE: &str = include_str!("../../shaders/raycast_traverse.wgsl");
const RAYCAST_PSI: &str = include_str!("../../shaders/raycast_psi.wgsl");
const RAYCAST_TABLE: &str = include_str!("../../shaders/raycast_table.wgsl");
/// The shells' walk sampler's segment integrator: the slices a segment holds.
const RAYCAST_SLICES: &str = include_str!("../../shaders/raycast_slices.wgsl");
/// The walk sampler's field for a textured cage: the segment's texture coordinates, the volume
/// at each slice's.
const RAYCAST_SLICES_TEXTURE: &str = include_str!("../../shaders/raycast_slices_texture.wgsl");
/// The walk sampler's field for the mesh's own scalars: per segment the tet's linear field along
/// the ray, `u(t) = a + t b` (`scalar_at`'s terms; b = 0 for cell data, the tet's value), per
/// slice its value at the slice.
const SLICE_SCALAR_LINEAR: &str = "struct SliceField {\n    a: f32,\n    b: f32,\n}\n\n\
    fn slice_field(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) \
    -> SliceField {\n    if CELLS {\n        return SliceField(clamp(cells[tet], 0.0, 1.0), 0.0);\n    \
    }\n    return SliceField(pl.scalar.w, dot(pl.scalar.xyz, d));\n}\n\n\
    fn sample_scalar(f: SliceField, t: f32) -> f32 {\n    \
    return clamp(f.a + t * f.b, 0.0, 1.0);\n}\n";

/// The traversal's `segment` for the integrators of `integrate_segment.wgsl`.
const SEGMENT_PIECEWISE: &str = "fn segment(u_front: f32, u_back: f32, len: f32) -> Acc {\n    \
    return integrate_segment(u_front, u_back, len);\n}\n";

/// The traversal's `tet_segment` for a linear field: the tet's scalars at the segment's ends
/// into the integrator's `segment`.
const TET_SEGMENT_LINEAR: &str = "fn tet_segment(tet: u32, ids: vec4<u32>, pl: TetPlanes, d: vec3<f32>, t0: f32, t1: f32) -> Acc {\n    \
    let u = segment_scalars(tet, pl, d, t0, t1);\n    \
    return segment(u.x, u.y, t1 - t0);\n}\n";
const RAYCAST_TEXTURE_SAMPLE: &str = include_str!("../../shaders/raycast_texture_sample.wgsl");
const RAYCAST_TEXTURE: &str = include_str!("../../shaders/raycast_texture.wgsl");
/// Trilinear sampling of a cage's volume texture (`fn trilinear`), shared by the textured ray
/// caster and the textured shells stages; the stage declares `volume`.
const TEXTURE_SAMPLE: &str = include_str!("../../shaders/texture_sample.wgsl");
/// The textured shells sampling (`textured_values`, `tet_values`) and its bindings.
const SHELLS_TEXTURE: &str = include_str!("../../shaders/shells_texture.wgsl");
/// The textured shells raster stage's varyings (`shell_varyings`, `fragment_values`).
const SHELLS_RASTER_TEXTURE: &str = include_str!("../../shaders/shells_raster_texture.wgsl");

/// The shells raster stage's `shell_varyings` and `fragment_values` for the linear field of
/// the vertex scalars: raster.wgsl's varyings, shells_span.wgsl's `slice_values`.
const SHELLS_RASTER_LINEAR: &str = "fn shell_varyings(position: vec4<f32>, rec: TetRecord, tet: u32) -> Varyings {\n    \
    return varyings(position, rec);\n}\n\
    fn fragment_values(in: Varyings, d: vec3<f32>, span: vec4<f32>) -> array<vec4<f32>, TARGETS> {\n    \
    return slice_values(span);\n}\n";

/// The fine stage's `tet_values` for the linear field of the vertex scalars.
const SHELLS_FINE_LINEAR: &str = "fn tet_values(tet: u32, rec: SpanTet, d: vec3<f32>, span: vec4<f32>) -> array<vec4<f32>, TARGETS> {\n    \
    return slice_values(span);\n}\n";

/// How the shells stages read a sample's scalar: the linear field of the vertex scalars, or a
/// textured cage's volume (`shells_texture.wgsl`).
fn shells_sampling(textured: bool, raster: bool) -> String {
    match (textured, raster) {
        (false, false) => SHELLS_FINE_LINEAR.to_owned(),
        (false, true) => format!("{RASTER}\n{SHELLS_RASTER_LINEAR}"),
        (true, false) => format!("{TEXTURE_SAMPLE}\n{SHELLS_TEXTURE}"),
        (true, true) => format!("{TEXTURE_SAMPLE}\n{SHELLS_TEXTURE}\n{SHELLS_RASTER_TEXTURE}"),
    }
}

const RAYCAST_TEXTURE_ISO: &str = include_str!("../../shaders/raycast_texture_iso.wgsl");

/// The entry methods' `ray_end` hook for the integrators that find no surface hits (every one
/// but the textured isosurfaces', which stores the pixel's hit).
const NO_HITS: &str = "fn store_hit(pixel: u32) {}\n";

/// The ray caster's stages as it loads them (entry point `main` in each): vertices; planes;
/// entries; the two depth-peeling passes (least t, then least face code); the tile list from
/// entry lists and from peeled hits; the traversal with entry lists and with depth peeling,
/// each with every integrator (`Segments`: exact, partial, table); then both traversals for a
/// textured cage (the volume texture stepped through, `raycast_texture.wgsl`), and both for
/// its isosurfaces (`raycast_texture_iso.wgsl`). The shells' walk sampler's traversals are
/// [`raycast_slices`].
pub fn raycast_stages() -> [(&'static str, String); 17] {
    let common = format!("{SHARED}\n{RAYCAST_SHARED}\n{RAYCAST_RAYS}");
    let psi = format!(
        "// Generated: samples per psi table axis.\nconst PSI_SIZE: u32 = {}u;\n{RAYCAST_PSI}",
        crate::gpu::raycast::psi::PSI_SIZE
    );
    let exact = format!("{PSI_EXACT}\n{SEGMENT_PIECEWISE}\n{TET_SEGMENT_LINEAR}\n{NO_HITS}");
    let partial = format!("{psi}\n{SEGMENT_PIECEWISE}\n{TET_SEGMENT_LINEAR}\n{NO_HITS}");
    let table = format!("{PSI_EXACT}\n{RAYCAST_TABLE}\n{TET_SEGMENT_LINEAR}\n{NO_HITS}");
    let sample = format!("{PSI_EXACT}\n{RAYCAST_TEXTURE_SAMPLE}\n{TEXTURE_SAMPLE}");
    let textured = format!("{sample}\n{RAYCAST_TEXTURE}\n{NO_HITS}");
    let textured_iso = format!("{sample}\n{ISO_SHARED}\n{RAYCAST_TEXTURE_ISO}");
    // Every traversal has integrate_segment.wgsl (its `Acc`); the integrator gives `segment`.
    let traverse = |name, entries: &str, integrator: &str| {
        let integrate = INTEGRATE_SEGMENT;
        let source = format!("{common}\n{integrate}\n{integrator}\n{entries}\n{RAYCAST_TRAVERSE}");
        (name, source)
    };
    let peel = |pick: bool| {
        let prelude = format!("// Generated: which pass.\nconst PICK: bool = {pick};");
        format!("{common}\n{prelude}\n{RAYCAST_COVER}\n{RAYCAST_PEEL}")
    };
    let tiles = |stride: u32| {
        let prelude = format!("// Generated: u32s per pixel.\nconst STRIDE: u32 = {stride}u;");
        format!("{common}\n{prelude}\n{RAYCAST_TILES}")
    };
    [
        ("raycast_vertices", format!("{common}\n{RAYCAST_VERTICES}")),
        ("raycast_planes", format!("{common}\n{RAYCAST_PLANES}")),
        (
            "raycast_entries",
            format!("{common}\n{RAYCAST_COVER}\n{RAYCAST_ENTRIES}"),
        ),
        ("raycast_peel (least t)", peel(false)),
        ("raycast_peel (least face)", peel(true)),
        ("raycast_tiles (entry lists)", tiles(1)),
        ("raycast_tiles (peeled hits)", tiles(2)),
        traverse("raycast_traverse (lists, exact)", RAYCAST_LISTS, &exact),
        traverse("raycast_traverse (lists, partial)", RAYCAST_LISTS, &partial),
        traverse("raycast_traverse (lists, table)", RAYCAST_LISTS, &table),
        traverse("raycast_traverse (peel, exact)", RAYCAST_LAYERS, &exact),
        traverse("raycast_traverse (peel, partial)", RAYCAST_LAYERS, &partial),
        traverse("raycast_traverse (peel, table)", RAYCAST_LAYERS, &table),
        traverse(
            "raycast_traverse (lists, textured)",
            RAYCAST_LISTS,
            &textured,
        ),
        traverse(
            "raycast_traverse (peel, textured)",
            RAYCAST_LAYERS,
            &textured,
        ),
        traverse(
            "raycast_traverse (lists, textured iso)",
            RAYCAST_LISTS,
            &textured_iso,
        ),
        traverse(
            "raycast_traverse (peel, textured iso)",
            RAYCAST_LAYERS,
            &textured_iso,
        ),
    ]
}

/// The shells' walk sampler's traversals, with entry lists and with depth peeling (entry point
/// `main` in each): each segment composites the slices it holds (`raycast_slices.wgsl`), the TF
/// evaluated as the shells composite does for `tf_points` control points (`tf_eval`:
/// constant indices up to [`UNROLLED_TF_POINTS`], measured 1.6 times faster than the loop on
/// lavapipe, else a loop; 0 selects the loop); `textured`: at the volume texture of a textured
/// cage (`raycast_slices_texture.wgsl`, bindings 17 and 18) instead of the mesh's field.
pub fn raycast_slices(tf_points: u32, textured: bool) -> (String, String) {
    let common = format!("{SHARED}\n{RAYCAST_SHARED}\n{RAYCAST_RAYS}\n{INTEGRATE_SEGMENT}");
    let (scalar, field) = match textured {
        true => (
            format!("{RAYCAST_TEXTURE_SAMPLE}\n{TEXTURE_SAMPLE}\n{RAYCAST_SLICES_TEXTURE}"),
            ", textured",
        ),
        false => (SLICE_SCALAR_LINEAR.to_string(), ""),
    };
    let integrator = format!(
        "{PSI_EXACT}\n{scalar}\n{}{TF_EVAL}\n{RAYCAST_SLICES}\n{NO_HITS}",
        tf_eval(tf_points)
    );
    let name = format!("raycast_traverse (lists, slices, {tf_points} TF points{field})");
    let source = format!("{common}\n{integrator}\n{RAYCAST_LISTS}\n{RAYCAST_TRAVERSE}");
    (name, source)
}

/// The TF variant of `tf_eval` a transfer function of `points` control points uses: its
/// count when unrolled, else 0 (the loop).
pub fn tf_variant(points: u32) -> u32 {
    if points <= UNROLLED_TF_POINTS {
        points
    } else {
        0
    }
}

/// The most colour targets a raster variant may write (WebGPU's cap on colour attachments).
pub const MAX_TARGETS: u32 = 8;

/// The assembly stage every mode shares (compute entry points `vertices`, `main`, and
/// `main_cells` for a field constant per tet).
pub fn assemble() -> String {
    format!("{SHARED}\n{INVOCATION}\n{ASSEMBLE}")
}

/// The shells raster stage writing `targets` (1..=[`MAX_TARGETS`]) vec4 colour targets, i.e.
/// `4 * targets` slices (entry points `vs_faces`, `vs_near`, `fs_slices`, and `vs_clear`,
/// `fs_clear`, which zero the slices within the shell's scissor rectangle).
pub fn shells_raster(targets: u32) -> String {
    shells_raster_variant(targets, false)
}

/// [`shells_raster`] for a textured cage: each sample reads the volume texture at its texture
/// coordinate (`shells_texture.wgsl`, bindings 14-15; the tets' vertex ids are
/// `tet_corners.wgsl`'s, binding 13).
pub fn shells_raster_textured(targets: u32) -> String {
    shells_raster_variant(targets, true)
}

fn shells_raster_variant(targets: u32, textured: bool) -> String {
    let targets = targets.clamp(1, MAX_TARGETS);
    let sampling = shells_sampling(textured, true);
    let fields: String = (0..targets)
        .map(|i| format!("    @location({i}) t{i}: vec4<f32>,\n"))
        .collect();
    let values: Vec<String> = (0..targets).map(|i| format!("v[{i}]")).collect();
    format!(
        "{SHARED}\n{TET_CORNERS}\n{SHELLS_SHARED}\n{sampling}\n// Generated: the raster variant with {targets} colour targets.\n\
         const TARGETS: u32 = {targets}u;\n\
         struct SliceOut {{\n{fields}}}\n\
         fn slice_out(v: array<vec4<f32>, TARGETS>) -> SliceOut {{\n    return SliceOut({});\n}}\n\
         {SHELLS_SPAN}\n{SHELLS_RASTER}",
        values.join(", ")
    )
}

/// Transfer functions with at most this many control points get a composite variant that
/// walks their segments with constant indices; larger ones share a looping variant.
pub const UNROLLED_TF_POINTS: u32 = 32;

/// The shells composite stage reading `targets` layers (1..=[`MAX_TARGETS`]) of 4 slices, for
/// a transfer function of `tf_points` control points (entry points `vs_fullscreen`,
/// `fs_composite`). The generated `load_layers` reads the layers with constant indices (a loop
/// over a dynamic layer index is an order of magnitude slower on lavapipe), and `tf_eval` walks
/// the TF's segments with constant indices when `tf_points <= UNROLLED_TF_POINTS` (dynamic
/// indices make every lane gather the control points); `tf_points` only selects the variant.
pub fn shells_composite(targets: u32, tf_points: u32) -> String {
    let targets = targets.clamp(1, MAX_TARGETS);
    let loads: Vec<String> = (0..targets)
        .map(|i| format!("textureLoad(slices, xy, {i}, 0)"))
        .collect();
    let tf_eval = tf_eval(tf_points);
    format!(
        "{SHARED}\n{SHELLS_SHARED}\n// Generated: the composite variant reading {targets} layers, TF of {tf_points} \
         points.\nconst TARGETS: u32 = {targets}u;\n\
         fn load_layers(xy: vec2<i32>) -> array<vec4<f32>, TARGETS> {{\n    \
         return array<vec4<f32>, TARGETS>({});\n}}\n{tf_eval}{TF_EVAL}\n{SHELLS_TF}\n{SHELLS_COMPOSITE}",
        loads.join(", ")
    )
}

/// `tf_eval(u)` for a transfer function of `tf_points` control points: its segments walked
/// with constant indices when `tf_points <= UNROLLED_TF_POINTS` (dynamic indices make every
/// lane gather the control points), else a loop over `tf.count` points.
fn tf_eval(tf_points: u32) -> String {
    if (1..=UNROLLED_TF_POINTS).contains(&tf_points) {
        let steps: String = (0..tf_points - 1)
            .map(|k| format!("    out = tf_segment(out, u, {k}u);\n"))
            .collect();
        format!(
            "fn tf_eval(u: f32) -> vec4<f32> {{\n    var out = tf_value(0u);\n{steps}    \
             return tf_last(out, u, {}u);\n}}\n",
            tf_points - 1
        )
    } else {
        "fn tf_eval(u: f32) -> vec4<f32> {\n    var out = tf_value(0u);\n    \
         for (var k = 0u; k + 1u < tf.count; k++) {\n        \
         out = tf_segment(out, u, k);\n    }\n    \
         return tf_last(out, u, tf.count - 1u);\n}\n"
            .to_owned()
    }
}

/// Screen tile side of the compute sampler: a tile is one workgroup of the fine stage, one
/// thread per pixel. Measured on lavapipe (2 cores, blunt fin 512x512, medians of 5 warm
/// frames, A-B-B-A): 8 pixels 501-506 ms, 4 pixels 533-536 ms, 16 pixels 1350-1520 ms (each
/// pixel walks its whole tile's list, and small tets' boxes cover a larger share of a small
/// tile).
pub const SHELLS_TILE: u32 = 8;

/// The compute sampler's coarse stage (entry points `count`, `scan`, `scatter`), binning a
/// shell's tets to tiles of [`SHELLS_TILE`] pixels.
pub fn shells_tiles() -> String {
    format!(
        "{SHARED}\n{TET_CORNERS}\n{SHELLS_SHARED}\n// Generated: the tile side in pixels.\n\
         const TILE: u32 = {SHELLS_TILE}u;\n{SHELLS_TILES}"
    )
}

/// The compute sampler's fine stage (entry point `main`) sampling `4 * targets` slices per
/// shell (`targets` in 1..=[`MAX_TARGETS`]), compositing with a transfer function of
/// `tf_points` control points as [`shells_composite`] does.
pub fn shells_fine(targets: u32, tf_points: u32) -> String {
    shells_fine_variant(targets, tf_points, false)
}

/// [`shells_fine`] for a textured cage: each sample reads the volume texture at its texture
/// coordinate (`shells_texture.wgsl`, bindings 14-15; the tets' vertex ids are
/// `tet_corners.wgsl`'s, binding 13).
pub fn shells_fine_textured(targets: u32, tf_points: u32) -> String {
    shells_fine_variant(targets, tf_points, true)
}

fn shells_fine_variant(targets: u32, tf_points: u32, textured: bool) -> String {
    let targets = targets.clamp(1, MAX_TARGETS);
    format!(
        "{SHARED}\n{TET_CORNERS}\n{SHELLS_SHARED}\n// Generated: the fine variant sampling {targets} vec4 of \
         slices, TF of {tf_points} points, tiles of {SHELLS_TILE} pixels.\n\
         const TILE: u32 = {SHELLS_TILE}u;\nconst TARGETS: u32 = {targets}u;\n{}\
         {SHELLS_SPAN}\n{}\n{TF_EVAL}\n{SHELLS_TF}\n{SHELLS_FINE}",
        tf_eval(tf_points),
        shells_sampling(textured, false)
    )
}

/// The shells early-ray-termination stage (entry points `vs_mark`, `fs_mark`, and the compute
/// entry point `tiles`), with the tile size of [`crate::gpu::shells::skips::TILE`]. The
/// threshold is the pipeline-overridable constant `threshold`.
pub(crate) fn shells_mark() -> String {
    format!(
        "// Generated: the tile side in pixels.\nconst TILE: u32 = {}u;\n{SHELLS_MARK}",
        crate::gpu::shells::skips::TILE
    )
}

/// The iso raster stage (entry points `vs_faces`, `fs_iso`).
pub fn iso_raster() -> String {
    format!("{SHARED}\n{TET_CORNERS}\n{ISO_SHARED}\n{ISO_RASTER}")
}

/// The iso smooth-shading gradient stage (standalone; compute entry point `main`).
pub fn iso_gradients() -> String {
    ISO_GRADIENTS.to_owned()
}

/// The cellproj raster stage (entry points `vs_faces`, `fs_table`, `fs_exact`).
pub fn cellproj_raster() -> String {
    format!(
        "{SHARED}\n{TET_CORNERS}\n{RASTER}\n{INTEGRATE_SEGMENT}\n{PSI_EXACT}\n{CELLPROJ_RASTER}"
    )
}

/// The shells' GPU binning (entry points `count`, `scan`, `scatter`): its uniforms
/// ([`crate::gpu::gpu_data::BinUniforms`]) declared in it, `invocation.wgsl` in front.
pub fn shells_bin() -> String {
    format!("{INVOCATION}\n{SHELLS_BIN}")
}

/// Every WGSL module the renderers load, each variant once, with its name and its entry points
/// in source order.
pub fn registry() -> Vec<(String, String, &'static [&'static str])> {
    let mut out: Vec<(String, String, &'static [&'static str])> = vec![
        (
            "assemble".into(),
            assemble(),
            &["vertices", "main", "main_cells"],
        ),
        (
            "shells_mark".into(),
            shells_mark(),
            &["vs_mark", "fs_mark", "tiles"],
        ),
        (
            "shells_tiles".into(),
            shells_tiles(),
            &["count", "scan", "scatter"],
        ),
        (
            "shells_bin".into(),
            shells_bin(),
            &["count", "scan", "scatter"],
        ),
        ("iso_raster".into(), iso_raster(), &["vs_faces", "fs_iso"]),
        ("iso_gradients".into(), iso_gradients(), &["main"]),
        (
            "cellproj_raster".into(),
            cellproj_raster(),
            &["vs_faces", "fs_table", "fs_exact"],
        ),
    ];
    for (name, source) in raycast_stages() {
        // The entries stage's second entry point: one thread per face (`EntryLanes::Thread`).
        let entries = if name == "raycast_entries" {
            ["main", "per_thread"].as_slice()
        } else {
            &["main"]
        };
        out.push((name.into(), source, entries));
    }
    // The walk sampler's traversals: every unrolled TF variant, and the looping one (0), of
    // the mesh's field and of a textured cage's.
    for tf_points in 0..=UNROLLED_TF_POINTS {
        for textured in [false, true] {
            let (name, source) = raycast_slices(tf_points, textured);
            out.push((name, source, ["main"].as_slice()));
        }
    }
    for targets in 1..=MAX_TARGETS {
        let raster = ["vs_faces", "vs_near", "fs_slices", "vs_clear", "fs_clear"].as_slice();
        let name = format!("shells_raster ({targets} targets)");
        out.push((name, shells_raster(targets), raster));
        let name = format!("shells_raster ({targets} targets, textured)");
        out.push((name, shells_raster_textured(targets), raster));
        // Every unrolled TF variant, and the looping one (0).
        for tf_points in 0..=UNROLLED_TF_POINTS {
            let name = format!("shells_composite ({targets} layers, {tf_points} TF points)");
            let entries = ["vs_fullscreen", "fs_composite"].as_slice();
            out.push((name, shells_composite(targets, tf_points), entries));
            let name = format!("shells_fine ({targets} vec4 of slices, {tf_points} TF points)");
            out.push((name, shells_fine(targets, tf_points), ["main"].as_slice()));
            let name =
                format!("shells_fine ({targets} vec4 of slices, {tf_points} TF points, textured)");
            let source = shells_fine_textured(targets, tf_points);
            out.push((name, source, ["main"].as_slice()));
        }
    }
    out
}
