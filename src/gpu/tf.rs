//! The transfer function as the GPU stages read it: control points with the scalars
//! normalized like the GPU's ([`crate::gpu::mesh::MeshData::gpu_scalars`]).

use bytemuck::Zeroable;

use crate::gpu::gpu_data::{MAX_TF_POINTS, TfPoint, TfPoints};
use crate::gpu::util::settings_error;
use crate::render::RenderError;
use crate::tf::TransferFunction;

/// `tf`'s control points for scalars normalized as `u = (s - lo) / span`.
pub fn tf_points(tf: &TransferFunction, lo: f64, span: f64) -> Result<TfPoints, RenderError> {
    let p = tf.points();
    if p.len() > MAX_TF_POINTS {
        return Err(settings_error(format!(
            "the transfer function has {} control points; the GPU modes evaluate at most \
             {MAX_TF_POINTS}: resample it",
            p.len()
        )));
    }
    let mut out = TfPoints::zeroed();
    out.count = p.len() as u32;
    for (k, (q, &tau)) in p.iter().zip(tf.taus()).enumerate() {
        let u = (q.s - lo) / span;
        let next = p.get(k + 1).map(|n| (n.s - lo) / span);
        out.points[k] = TfPoint {
            rgb: q.color.map(|c| c as f32),
            tau: tau as f32,
            s: u as f32,
            inv_width: match next {
                Some(v) if v > u => (1.0 / (v - u)) as f32,
                _ => 0.0,
            },
            _pad: [0.0; 2],
        };
    }
    Ok(out)
}
