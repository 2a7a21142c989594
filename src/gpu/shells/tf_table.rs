//! The transfer function as the composite stage reads it: control points with `s` normalized
//! like the encoded scalars, and a uniform table of bins over `[0, 1]`, each holding the exact
//! linear piece valid from its start to the next control point (see `gpu_data::TfBin`).

use crate::gpu::gpu_data::{TfBin, TfPoint};
use crate::tf::TransferFunction;

/// Bins of the table: 1024 keeps it in 48 KiB while a typical TF (up to tens of points) sends
/// only a few percent of samples to the search.
pub const TF_BINS: usize = 1024;

/// Control points and bins of `tf` for scalars normalized as `u = (s - lo) / span`.
pub fn tf_table(tf: &TransferFunction, lo: f64, span: f64) -> (Vec<TfPoint>, Vec<TfBin>) {
    let u: Vec<f64> = tf.points().iter().map(|p| (p.s - lo) / span).collect();
    let c: Vec<[f64; 4]> = tf
        .points()
        .iter()
        .zip(tf.taus())
        .map(|(p, &tau)| [p.color[0], p.color[1], p.color[2], tau])
        .collect();
    let points = u
        .iter()
        .zip(&c)
        .map(|(&s, c)| TfPoint {
            rgb: [c[0] as f32, c[1] as f32, c[2] as f32],
            tau: c[3] as f32,
            s: s as f32,
            _pad: [0.0; 3],
        })
        .collect();
    let last = u.len() - 1;
    let bins = (0..TF_BINS)
        .map(|i| {
            let start = i as f64 / TF_BINS as f64;
            let end = (i + 1) as f64 / TF_BINS as f64;
            // The first control point after `start`: the piece from `start` ends there.
            let j = u.partition_point(|&s| s <= start);
            let (value, slope) = if j == 0 || j > last {
                (c[j.min(last)], [0.0; 4])
            } else {
                let w = (start - u[j - 1]) / (u[j] - u[j - 1]);
                let value = [0, 1, 2, 3].map(|k| c[j - 1][k] + (c[j][k] - c[j - 1][k]) * w);
                let slope = [0, 1, 2, 3].map(|k| (c[j][k] - c[j - 1][k]) / (u[j] - u[j - 1]));
                (value, slope)
            };
            let split = if j <= last && u[j] < end { u[j] } else { 2.0 };
            TfBin {
                value: value.map(|v| v as f32),
                slope: slope.map(|v| v as f32),
                start: start as f32,
                split: split as f32,
                _pad: [0.0; 2],
            }
        })
        .collect();
    (points, bins)
}
