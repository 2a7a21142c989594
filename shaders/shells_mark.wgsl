// Early ray termination. After a shell's composite, `fs_mark` (one full-screen pass cut to the
// shell's scissor, depth test LESS against a buffer cleared to 1) writes depth 0 where the
// accumulated alpha reached the threshold; every later raster, clear and composite pass draws
// at depth 0 with test LESS, so finished pixels fail the test before their fragment shader
// runs. `tiles` flags the 16 x 16 pixel tiles that still hold an unfinished pixel, for the
// CPU to cut or skip later shells (gpu::shells::skips::TileMask); the generated prelude
// defines TILE (gpu::shells::skips::TILE).

// Accumulated alpha at which a pixel is finished (pipeline-overridable).
override threshold: f32 = 0.99999;

@group(0) @binding(0) var accum: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> unfinished: array<atomic<u32>>;

@vertex
fn vs_mark(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen at depth 0: (-1, -1), (3, -1), (-1, 3).
    let x = f32((vertex << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vertex & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_mark(@builtin(position) position: vec4<f32>) {
    if textureLoad(accum, vec2<i32>(position.xy), 0).a < threshold {
        discard;
    }
}

@compute @workgroup_size(8, 8)
fn tiles(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(accum);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    if textureLoad(accum, vec2<i32>(id.xy), 0).a < threshold {
        let tiles_x = (size.x + TILE - 1u) / TILE;
        atomicStore(&unfinished[(id.y / TILE) * tiles_x + id.x / TILE], 1u);
    }
}
