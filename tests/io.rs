//! File format tests: the shared real data sets, hand-written fixtures in every format and
//! encoding, a malformed corpus with the expected error places, and fuzzing of the readers.

use std::path::{Path, PathBuf};
use std::time::Instant;

use tetvr::io::{Format, load, load_bytes};

fn shared(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")).join(name)
}

/// Every shared data set loads with the vertex/tet counts and arrays that SOURCES.md lists.
#[test]
fn shared_data_sets_load_with_their_documented_counts() {
    // (file, vertices, tets, arrays in order with the active first, reoriented tets)
    let cases: [(&str, usize, usize, &[&str], usize); 7] = [
        ("lox_post_subset_tet.vtk", 2_288, 8_750, &["Pressure"], 0),
        (
            "disk_out_ref_tet.vtk",
            8_499,
            44_832,
            &["Temp", "Pres", "AsH3", "CH4", "GaMe3", "H2", "speed"],
            0,
        ),
        (
            "kiefer_bracket_tet.vtk",
            16_468,
            56_786,
            &["vonMises_psi"],
            0,
        ),
        (
            "fire_ug_tet.vtk",
            12_323,
            62_772,
            &["t", "mfrac", "speed"],
            0,
        ),
        (
            "bluntfin_tet.vtk",
            40_960,
            187_395,
            &[
                "Density",
                "Pressure",
                "Temperature",
                "VelocityMagnitude",
                "StagnationEnergy",
            ],
            0,
        ),
        (
            "combustor_tet.vtk",
            47_025,
            215_040,
            &["Density", "VelocityMagnitude"],
            2,
        ),
        (
            "oxygen_post_tet.vtk",
            109_744,
            513_375,
            &["Pressure", "VelocityMagnitude", "StagnationEnergy"],
            0,
        ),
    ];
    for (file, nv, nt, arrays, reoriented) in cases {
        let t0 = Instant::now();
        let l = load(&shared(file)).unwrap_or_else(|e| panic!("{e}"));
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        println!("{file}: {nv} vertices, {nt} tets loaded in {ms:.1} ms");
        assert_eq!(
            (l.mesh.vertex_count(), l.mesh.tet_count()),
            (nv, nt),
            "{file}"
        );
        let names: Vec<&str> = l.mesh.arrays().iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, arrays, "{file}");
        assert_eq!(l.report.reoriented, reoriented, "{file}");
        assert_eq!(l.report.format, Format::VtkLegacy);
    }
}
