//! Times `Adjacency::build` (faces bucketed by smallest vertex) against the sort it replaced
//! (one parallel sort of every face's vertex triple), and checks that both give the same
//! neighbours, boundary faces and non-manifold count.
//!
//! `cargo run --example adjacency_bench -- [runs] [what...]`: each `what` is a tet
//! count (a `box_grid` of about that many tets) or a mesh file; default 1000000, 15100000 and
//! bluntfin. Per mesh, `runs` runs of each (default 3), alternating so both see the same load;
//! the medians are printed.

use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;
use tetvr::generate::{box_grid, cells_for_tet_count};
use tetvr::mesh::topology::FACES;
use tetvr::mesh::{Adjacency, NO_NEIGHBOR};
use tetvr::{TetMesh, io};

type Error = Box<dyn std::error::Error>;

/// The previous `Adjacency::build`: all face keys in one parallel sort. Returns the
/// neighbours, the boundary slots (`4 * tet + face`, ascending) and the non-manifold count.
fn sort_build(tets: &[[u32; 4]]) -> (Vec<[u32; 4]>, Vec<u32>, usize) {
    let mut keys: Vec<([u32; 3], u32)> = tets
        .par_iter()
        .enumerate()
        .flat_map_iter(|(t, tet)| {
            FACES.iter().enumerate().map(move |(f, lf)| {
                let mut k = lf.map(|i| tet[i]);
                k.sort_unstable();
                (k, (t * 4 + f) as u32)
            })
        })
        .collect();
    keys.par_sort_unstable();
    let mut neighbors = vec![[NO_NEIGHBOR; 4]; tets.len()];
    let (mut boundary, mut non_manifold) = (Vec::new(), 0);
    for group in keys.chunk_by(|x, y| x.0 == y.0) {
        match group {
            [(_, a), (_, b)] => {
                neighbors[(a / 4) as usize][(a % 4) as usize] = b / 4;
                neighbors[(b / 4) as usize][(b % 4) as usize] = a / 4;
            }
            [(_, a)] => boundary.push(*a),
            _ => {
                non_manifold += 1;
                boundary.extend(group.iter().map(|k| k.1));
            }
        }
    }
    boundary.par_sort_unstable();
    (neighbors, boundary, non_manifold)
}

fn load(what: &str) -> Result<TetMesh, Error> {
    Ok(match what.parse::<u64>() {
        Ok(n) => box_grid(DVec3::ZERO, DVec3::ONE, cells_for_tet_count(n), "g", |p| {
            p.x
        }),
        Err(_) => io::load(Path::new(what))?.mesh,
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Error> {
    let mut args = std::env::args().skip(1).peekable();
    let runs = match args.peek().and_then(|a| a.parse::<usize>().ok()) {
        Some(r) if r < 100 => {
            args.next();
            r
        }
        _ => 3,
    };
    let mut what: Vec<String> = args.collect();
    if what.is_empty() {
        what = ["1000000", "15100000", "../shared/data/bluntfin_tet.vtk"]
            .map(String::from)
            .into();
    }
    println!("{} rayon threads", rayon::current_num_threads());
    for w in &what {
        let mesh = load(w)?;
        let tets = mesh.tets();
        let (mut new, mut old) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            let t0 = Instant::now();
            let adj = Adjacency::build(tets);
            new.push(t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            let (neighbors, boundary, non_manifold) = sort_build(tets);
            old.push(t0.elapsed().as_secs_f64());
            let slots: Vec<u32> = adj
                .boundary
                .iter()
                .map(|b| 4 * b.tet + b.face as u32)
                .collect();
            let same = adj.neighbors == neighbors
                && slots == boundary
                && adj.non_manifold_faces == non_manifold;
            if !same {
                return Err(format!("{w}: the bucketed build differs from the sort").into());
            }
        }
        println!(
            "{w}: {} tets, {} vertices: bucketed {:.3} s, sort {:.3} s (medians of {runs}; identical results)",
            tets.len(),
            mesh.positions().len(),
            median(new),
            median(old),
        );
    }
    Ok(())
}
