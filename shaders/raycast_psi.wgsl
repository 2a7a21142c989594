// The traversal's `psi` for partial pre-integration (Espinha & Celes 2005): the mean
// transmittance of a piece from Moreland & Angel's table, PSI_SIZE x PSI_SIZE samples over
// gamma = sqrt(A) / (1 + sqrt(A)) for each end's optical depth, interpolated bilinearly. PSI_SIZE is
// generated in front of this file. CPU twin: gpu::raycast::psi::lookup.

@group(0) @binding(12) var<storage, read> psi_table: array<f32>;

fn psi_at(x: u32, y: u32) -> f32 {
    return psi_table[y * PSI_SIZE + x];
}

fn psi(a: f32, b: f32) -> f32 {
    let n = f32(PSI_SIZE - 1u);
    let r = sqrt(vec2<f32>(a, b));
    let g = r / (1.0 + r) * n;
    let i = min(vec2<u32>(floor(g)), vec2<u32>(PSI_SIZE - 2u));
    let w = g - vec2<f32>(i);
    let lo = mix(psi_at(i.x, i.y), psi_at(i.x + 1u, i.y), w.x);
    let hi = mix(psi_at(i.x, i.y + 1u), psi_at(i.x + 1u, i.y + 1u), w.x);
    return mix(lo, hi, w.y);
}
