// The isosurface declarations shared by iso mode's raster stage (iso_raster.wgsl) and the
// textured cage's isosurface integrator (raycast_texture_iso.wgsl): the per-frame constants,
// the isovalue lookup and the headlight Blinn-Phong shading of reference::iso::shade. Each
// stage declares `iso: Iso` at its own binding.

// Per-frame isosurface constants; see gpu::gpu_data::IsoUniforms.
struct Iso {
    colors: array<vec4<f32>, 16>,
    values: array<vec4<f32>, 4>,
    count: u32,
    smooth_shading: u32,
    inv_depth_range: f32,
    depth_shift: f32,
}

// Headlight Blinn-Phong, the constants of reference::iso::shade.
const AMBIENT: f32 = 0.15;
const DIFFUSE: f32 = 0.75;
const SPECULAR: f32 = 0.25;
const SHININESS: f32 = 32.0;

fn iso_value(k: u32) -> f32 {
    return iso.values[k / 4u][k % 4u];
}

// The colour of a surface of colour `base` whose unit normal makes |cos| = ndv with the ray.
fn headlight(base: vec3<f32>, ndv: f32) -> vec3<f32> {
    return clamp(base * (AMBIENT + DIFFUSE * ndv) + SPECULAR * pow(ndv, SHININESS), vec3<f32>(0.0),
        vec3<f32>(1.0));
}
