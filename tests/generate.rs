//! Generators: conformity, volume and non-convexity of the shapes, exact vertex placement of
//! volumes turned into tets, and the brain volume as a real mesh of millions of tets.

use std::path::PathBuf;
use std::time::Instant;

use glam::{DVec3, UVec3};
use proptest::prelude::*;
use tetvr::TetMesh;
use tetvr::generate::shapes::{
    box_with_hole, box_with_hole_within, ring, ring_cells, ring_volume, ring_within,
};
use tetvr::generate::volume::{VolumeError, VolumeToTets, nifti_to_tets};
use tetvr::generate::{Field, GenerateError, box_grid, fields, memory_needed};

mod common;

/// The MNI brain template of `../shared/data` (too large to ship); `None`, said on stderr by
/// `test`, in a clone without `shared/` beside it.
fn brain(test: &str) -> Option<PathBuf> {
    common::shared_data_dir(test)
        .map(|dir| dir.join("mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz"))
}

fn volume(m: &TetMesh) -> f64 {
    (0..m.tet_count()).map(|t| m.signed_volume(t)).sum()
}

/// Relative tolerance for summed tet volumes: a few ulps per tet, far below one tet's volume.
const VOLUME_RTOL: f64 = 1e-12;

#[test]
fn box_with_hole_is_conforming_non_convex_and_has_the_right_volume() {
    for (target, m) in [(1, 1u64), (1000, 2), (20_000, 5)] {
        let mesh = box_with_hole(target, Field::Gaussians).unwrap();
        assert_eq!(mesh.tet_count() as u64, 144 * m.pow(3));
        let adj = mesh.adjacency();
        assert_eq!(adj.non_manifold_faces, 0);
        // Outer box 6 n^2 quads minus the two openings m^2, plus 4 hole walls of m x n quads
        // (n = 3m): 64 m^2 quads, 2 triangles each. Any crack would add boundary faces.
        assert_eq!(adj.boundary.len() as u64, 128 * m * m);
        assert!(!adj.is_convex(mesh.positions()));
        assert!((volume(&mesh) - 64.0 / 9.0).abs() < VOLUME_RTOL * 8.0);
        assert_eq!(mesh.active_array().unwrap().name, "gaussians");
    }
}

#[test]
fn ring_is_conforming_closed_around_and_non_convex() {
    for target in [10, 5_000, 60_000] {
        let mesh = ring(target, Field::MarschnerLobb).unwrap();
        let c = ring_cells(target);
        assert_eq!(mesh.tet_count() as u32, 6 * c.x * c.y * c.z);
        // Every vertex is used: the seam at theta = 2 pi reuses the theta = 0 vertices.
        assert_eq!(mesh.vertex_count() as u32, (c.x + 1) * c.y * (c.z + 1));
        let adj = mesh.adjacency();
        assert_eq!(adj.non_manifold_faces, 0);
        // Inner and outer walls (around x axial quads) plus top and bottom (around x radial):
        // nothing at the seam.
        assert_eq!(adj.boundary.len() as u32, 2 * 2 * c.y * (c.z + c.x));
        assert!(!adj.is_convex(mesh.positions()));
        assert!((volume(&mesh) - ring_volume(c.y)).abs() < VOLUME_RTOL * ring_volume(c.y));
        assert!(mesh.signed_volume(0) > 0.0);
        let (lo, hi) = mesh.active_array().unwrap().range().unwrap();
        assert!(lo >= 0.0 && hi <= 1.0, "Marschner-Lobb stays in [0, 1]");
    }
    assert!(matches!(
        ring(u64::MAX, Field::Linear),
        Err(GenerateError::TooManyTets { .. })
    ));
}

/// The memory check comes before any allocation and names what the mesh needs; 0 tets is
/// refused by every shape alike.
#[test]
fn generators_refuse_zero_tets_and_meshes_over_their_memory_limit() {
    let cells = UVec3::splat(10);
    let needed = memory_needed(6000, 11 * 11 * 11);
    assert_eq!(needed, 6000 * 24 + 5 * 1331);
    assert_eq!(
        fields::grid_within(Field::Linear, cells, "x", needed - 1).unwrap_err(),
        GenerateError::OverMemory {
            tets: 6000,
            needed,
            limit: needed - 1
        }
    );
    assert_eq!(
        fields::grid_within(Field::Linear, cells, "x", needed)
            .unwrap()
            .tet_count(),
        6000
    );
    assert!(matches!(
        box_with_hole_within(100_000, Field::Linear, 1 << 20),
        Err(GenerateError::OverMemory { .. })
    ));
    assert!(matches!(
        ring_within(100_000, Field::Linear, 1 << 20),
        Err(GenerateError::OverMemory { .. })
    ));
    assert_eq!(
        box_with_hole(0, Field::Linear).unwrap_err(),
        GenerateError::ZeroTets
    );
    assert_eq!(ring(0, Field::Linear).unwrap_err(), GenerateError::ZeroTets);
    // More cells than a u64 counts (2^96): refused, not an overflow panic (or, wrapped, a count
    // under the limits).
    assert!(matches!(
        fields::grid_within(Field::Linear, UVec3::splat(u32::MAX), "x", u64::MAX),
        Err(GenerateError::TooManyTets { .. })
    ));
}

#[test]
fn field_grids_sample_the_field_at_the_vertices() {
    let mesh = fields::grid(Field::Gaussians, UVec3::new(4, 5, 6), "g").unwrap();
    for (p, &v) in mesh.positions().iter().zip(mesh.scalars().unwrap()) {
        assert_eq!(v, Field::Gaussians.eval(*p));
    }
    let (lo, hi) = (DVec3::new(0.0, 0.0, 0.0), DVec3::new(2.0, 4.0, 8.0));
    let mesh = box_grid(
        lo,
        hi,
        UVec3::splat(3),
        "c",
        Field::Constant(0.5).on_box(lo, hi),
    );
    assert!(mesh.scalars().unwrap().iter().all(|&v| v == 0.5));
    assert!(matches!(
        fields::grid(Field::Linear, UVec3::new(0, 1, 1), "x"),
        Err(GenerateError::NoCells { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any grid of any box fills the box exactly with conforming tets whose only boundary is the
    /// box's surface.
    #[test]
    fn box_grids_are_conforming_and_fill_their_box(
        cx in 1u32..6, cy in 1u32..6, cz in 1u32..6,
        lo in prop::array::uniform3(-10.0f64..10.0),
        size in prop::array::uniform3(0.1f64..5.0),
    ) {
        let (lo, size) = (DVec3::from(lo), DVec3::from(size));
        let mesh = box_grid(lo, lo + size, UVec3::new(cx, cy, cz), "l", Field::Linear.on_box(lo, lo + size));
        let adj = mesh.adjacency();
        prop_assert_eq!(adj.non_manifold_faces, 0);
        prop_assert_eq!(adj.boundary.len() as u32, 4 * (cx * cy + cy * cz + cx * cz));
        prop_assert!(adj.is_convex(mesh.positions()));
        let v = size.x * size.y * size.z;
        prop_assert!((volume(&mesh) - v).abs() < VOLUME_RTOL * v * 10.0);
        prop_assert!((0..mesh.tet_count()).all(|t| mesh.signed_volume(t) > 0.0));
    }

    /// The shapes are conforming and exact in volume at every size.
    #[test]
    fn shapes_are_conforming_at_any_size(target in 1u64..40_000) {
        let hole = box_with_hole(target, Field::Radial).unwrap();
        prop_assert_eq!(hole.adjacency().non_manifold_faces, 0);
        prop_assert!((volume(&hole) - 64.0 / 9.0).abs() < VOLUME_RTOL * 8.0);
        let r = ring(target, Field::Radial).unwrap();
        prop_assert_eq!(r.adjacency().non_manifold_faces, 0);
        let expected = ring_volume(ring_cells(target).y);
        prop_assert!((volume(&r) - expected).abs() < VOLUME_RTOL * expected);
    }
}

/// A scratch directory under the target dir, unique per test.
fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("generate")
        .join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `values(x, y, z)` on a `dims` grid with voxel size `spacing` as NIfTI-1 float32.
fn write_nifti(
    path: &PathBuf,
    dims: [usize; 3],
    spacing: [f32; 3],
    values: impl Fn(usize, usize, usize) -> f32,
) {
    let data =
        ndarray::Array3::from_shape_fn((dims[0], dims[1], dims[2]), |(x, y, z)| values(x, y, z));
    let header = nifti::NiftiHeader {
        pixdim: [1.0, spacing[0], spacing[1], spacing[2], 1.0, 1.0, 1.0, 1.0],
        ..Default::default()
    };
    nifti::writer::WriterOptions::new(path)
        .reference_header(&header)
        .write_nifti(&data)
        .unwrap();
}

fn value_at(x: usize, y: usize, z: usize) -> f32 {
    (x + 10 * y + 100 * z) as f32
}

#[test]
fn voxel_centres_become_vertices_with_their_values() {
    for file in ["small.nii", "small.nii.gz"] {
        let path = scratch("small").join(file);
        write_nifti(&path, [3, 2, 2], [2.0, 3.0, 0.5], value_at);
        let mesh = nifti_to_tets(&path, &VolumeToTets::default()).unwrap();
        assert_eq!(mesh.vertex_count(), 12);
        assert_eq!(mesh.tet_count(), 2 * 6);
        assert_eq!(mesh.active_array().unwrap().name, "intensity");
        for (p, &v) in mesh.positions().iter().zip(mesh.scalars().unwrap()) {
            let (x, y, z) = (p.x / 2.0, p.y / 3.0, p.z / 0.5);
            assert_eq!(
                v,
                value_at(x as usize, y as usize, z as usize) as f64,
                "{p}"
            );
            // Positions are exactly voxel index times spacing (all exact in binary).
            assert_eq!(
                DVec3::new(x.round(), y.round(), z.round()),
                DVec3::new(x, y, z)
            );
        }
        assert!((volume(&mesh) - 2.0 * 2.0 * 3.0 * 0.5).abs() < 1e-12);
    }
}

#[test]
fn threshold_drops_cells_and_their_unused_vertices() {
    let path = scratch("threshold").join("t.nii");
    write_nifti(&path, [4, 2, 2], [1.0; 3], value_at);
    // Only the cell between x = 2 and 3 has a corner above 112.5 (x = 3, y = z = 1: 113); the
    // cell between x = 1 and 2 tops out at 112.
    let opts = VolumeToTets {
        downsample: 1,
        threshold: Some(112.5),
    };
    let mesh = nifti_to_tets(&path, &opts).unwrap();
    assert_eq!(mesh.tet_count(), 6);
    assert_eq!(mesh.vertex_count(), 8);
    assert_eq!(
        mesh.bounds(),
        (DVec3::new(2.0, 0.0, 0.0), DVec3::new(3.0, 1.0, 1.0))
    );
    let all = VolumeToTets {
        downsample: 1,
        threshold: Some(1000.0),
    };
    let e = nifti_to_tets(&path, &all).unwrap_err();
    let VolumeError::AllBelowThreshold { lo, hi, .. } = e else {
        panic!("{e}")
    };
    assert_eq!((lo, hi), (0.0, 113.0));
}

#[test]
fn downsampling_averages_blocks_at_their_centres() {
    let path = scratch("down").join("d.nii");
    write_nifti(&path, [5, 4, 4], [1.0, 1.0, 2.0], value_at);
    let opts = VolumeToTets {
        downsample: 2,
        threshold: None,
    };
    let mesh = nifti_to_tets(&path, &opts).unwrap();
    // 5 / 2 = 2 blocks along x (the last voxel column is dropped), 2 along y and z.
    assert_eq!(mesh.vertex_count(), 8);
    for (p, &v) in mesh.positions().iter().zip(mesh.scalars().unwrap()) {
        // Block (i, j, k) covers voxels 2i..2i+1 etc.: centre 2i + 0.5 voxels, and the mean of
        // the linear field is its value there.
        let (x, y, z) = (p.x, p.y, p.z / 2.0);
        assert_eq!(v, x + 10.0 * y + 100.0 * z, "{p}");
        assert_eq!(x.fract(), 0.5);
    }
}

#[test]
fn volume_errors_name_the_file_and_the_fix() {
    let missing = scratch("errors").join("missing.nii.gz");
    let e = nifti_to_tets(&missing, &VolumeToTets::default()).unwrap_err();
    assert!(e.to_string().contains("missing.nii.gz"), "{e}");
    let path = scratch("errors").join("tiny.nii");
    write_nifti(&path, [3, 3, 3], [1.0; 3], value_at);
    let e = nifti_to_tets(
        &path,
        &VolumeToTets {
            downsample: 0,
            threshold: None,
        },
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("tiny.nii") && e.to_string().contains("downsample factor 0"),
        "{e}"
    );
    let e = nifti_to_tets(
        &path,
        &VolumeToTets {
            downsample: 2,
            threshold: None,
        },
    )
    .unwrap_err();
    assert!(matches!(e, VolumeError::TooSmall { factor: 2, .. }), "{e}");
    let e = nifti_to_tets(
        &path,
        &VolumeToTets {
            downsample: 1,
            threshold: Some(f64::NAN),
        },
    )
    .unwrap_err();
    assert!(matches!(e, VolumeError::BadThreshold { .. }), "{e}");
    // A 4D series with two time points is not one scalar volume.
    let series = scratch("errors").join("series.nii");
    let data = ndarray::Array4::<f32>::zeros((3, 3, 3, 2));
    nifti::writer::WriterOptions::new(&series)
        .write_nifti(&data)
        .unwrap();
    let e = nifti_to_tets(&series, &VolumeToTets::default()).unwrap_err();
    assert!(
        matches!(&e, VolumeError::NotVolume3d { dims, .. } if dims == &[3, 3, 3, 2]),
        "{e}"
    );
    assert!(e.to_string().contains("series.nii"), "{e}");
    // A 2D image (one slice) has no cell at any factor: the error says so, not "use a smaller
    // factor" (it was already 1), and the texture reader says the same.
    let slice = scratch("errors").join("slice.nii");
    write_nifti(&slice, [4, 4, 1], [1.0; 3], value_at);
    let e = nifti_to_tets(&slice, &VolumeToTets::default()).unwrap_err();
    assert!(
        matches!(&e, VolumeError::Flat { dims, .. } if dims == &[4, 4, 1]),
        "{e}"
    );
    let message = e.to_string();
    assert!(
        message.contains("slice.nii")
            && message.contains("2 x 2 x 2")
            && !message.contains("smaller factor"),
        "{message}"
    );
    let e = tetvr::texture::Volume::load(&slice, 1).unwrap_err();
    assert!(matches!(e, VolumeError::Flat { .. }), "{e}");
}

/// The brain's head occupies 22 % of the voxels (intensity >= 10; the background is exactly 0),
/// so threshold 10 keeps the head and drops the background.
const BRAIN_THRESHOLD: f64 = 10.0;

#[test]
fn brain_volume_at_half_resolution_is_a_conforming_mesh() {
    let Some(brain) = brain("brain_volume_at_half_resolution_is_a_conforming_mesh") else {
        return;
    };
    let opts = VolumeToTets {
        downsample: 2,
        threshold: Some(BRAIN_THRESHOLD),
    };
    let mesh = nifti_to_tets(&brain, &opts).unwrap();
    // 98 x 116 x 94 samples, 97 x 115 x 93 = 1,037,415 cells; the head is 22 % of the volume and
    // a shell of partly covered cells adds a few %: 20-35 % of 6 tets per cell.
    let cells = 97.0 * 115.0 * 93.0 * 6.0;
    let tets = mesh.tet_count() as f64;
    assert!((0.20 * cells..0.35 * cells).contains(&tets), "{tets} tets");
    let adj = mesh.adjacency();
    assert_eq!(adj.non_manifold_faces, 0);
    // 1 mm voxels: at most 2 * (98 - 1) + 1 mm wide etc.; the head fills most of the box.
    let (lo, hi) = mesh.bounds();
    assert!(lo.cmpge(DVec3::splat(0.5)).all() && hi.cmple(DVec3::new(196.5, 232.5, 188.5)).all());
    let (slo, shi) = mesh.active_array().unwrap().range().unwrap();
    assert!(
        slo >= 0.0 && shi <= 255.0,
        "uint8 intensities averaged stay in [0, 255]"
    );
}

/// The full-resolution brain: millions of tets. Run with `--ignored --nocapture` to measure.
#[test]
#[ignore = "measurement: about 12 M tets"]
fn brain_volume_at_full_resolution() {
    let Some(brain) = brain("brain_volume_at_full_resolution") else {
        return;
    };
    let opts = VolumeToTets {
        downsample: 1,
        threshold: Some(BRAIN_THRESHOLD),
    };
    let start = Instant::now();
    let mesh = nifti_to_tets(&brain, &opts).unwrap();
    println!(
        "brain downsample 1 threshold {BRAIN_THRESHOLD}: {} tets, {} vertices in {:.2} s",
        mesh.tet_count(),
        mesh.vertex_count(),
        start.elapsed().as_secs_f64()
    );
    // At least the head's 22 % of the 196 x 232 x 188 cells, 6 tets each.
    assert!(mesh.tet_count() as f64 > 0.22 * 196.0 * 232.0 * 188.0 * 6.0);
    let start = Instant::now();
    let adj = mesh.adjacency();
    println!(
        "adjacency: {} boundary faces, {} non-manifold, in {:.2} s",
        adj.boundary.len(),
        adj.non_manifold_faces,
        start.elapsed().as_secs_f64()
    );
    assert_eq!(adj.non_manifold_faces, 0);
}

/// Generation time of grids of 1 M and 10 M tets. Run with `--ignored --nocapture`.
#[test]
#[ignore = "measurement: 10 M tets"]
fn large_grid_generation_time() {
    for target in [1_000_000u64, 10_000_000] {
        let start = Instant::now();
        let cells = tetvr::generate::cells_for_tet_count(target);
        let mesh = fields::grid(Field::MarschnerLobb, cells, "ml").unwrap();
        println!(
            "grid {cells}: {} tets in {:.2} s",
            mesh.tet_count(),
            start.elapsed().as_secs_f64()
        );
        let start = Instant::now();
        let mesh = box_with_hole(target, Field::Gaussians).unwrap();
        println!(
            "box with hole: {} tets in {:.2} s",
            mesh.tet_count(),
            start.elapsed().as_secs_f64()
        );
        let start = Instant::now();
        let mesh = ring(target, Field::Gaussians).unwrap();
        println!(
            "ring: {} tets in {:.2} s",
            mesh.tet_count(),
            start.elapsed().as_secs_f64()
        );
        // Within the rounding of the cells per axis (cube root): 15 % either way.
        assert!((mesh.tet_count() as f64 / target as f64 - 1.0).abs() < 0.15);
    }
}

// Hostile NIfTI headers (issue 13): each is a valid file written by nifti::writer with one field
// changed, read back by tetvr. On the old reader (the nifti crate) these panicked, misread the
// voxels or allocated gigabytes; each must now be a clear error, or the right values.

/// Byte offsets of NIfTI-1 header fields (little-endian, as nifti::writer writes them).
const DIM: usize = 40;
const DATATYPE: usize = 70;
const BITPIX: usize = 72;
const VOX_OFFSET: usize = 108;
const EXTENDER: usize = 348;

/// A valid 3 x 3 x 3 float32 volume (`value_at`) as bytes, uncompressed, voxels at byte 352;
/// written once for every test of this file (tests run in parallel: one rewriting the file
/// while another reads it would hand the reader a partial file).
fn valid_nifti_bytes() -> Vec<u8> {
    static BYTES: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BYTES
        .get_or_init(|| {
            let path = scratch("hostile").join("valid.nii");
            write_nifti(&path, [3, 3, 3], [1.0; 3], value_at);
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(
                bytes.len(),
                352 + 27 * 4,
                "the writer puts the voxels at byte 352"
            );
            bytes
        })
        .clone()
}

fn set_i16(bytes: &mut [u8], at: usize, v: i16) {
    bytes[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

/// Converts `bytes` (written to a file, the way users run it) with `opts`.
fn convert_bytes(name: &str, bytes: &[u8], opts: &VolumeToTets) -> Result<TetMesh, VolumeError> {
    let path = scratch("hostile").join(name);
    std::fs::write(&path, bytes).unwrap();
    nifti_to_tets(&path, opts)
}

#[test]
fn nifti_bitpix_that_disagrees_with_datatype_is_an_error_naming_both() {
    for bitpix in [8, 16, 64, 0, -32] {
        let mut bytes = valid_nifti_bytes();
        set_i16(&mut bytes, BITPIX, bitpix);
        let e = convert_bytes("bitpix.nii", &bytes, &VolumeToTets::default()).unwrap_err();
        assert!(
            matches!(&e, VolumeError::BitpixMismatch { bitpix: b, expected: 32, .. } if *b == bitpix),
            "{e}"
        );
        let msg = e.to_string();
        assert!(
            msg.contains("bitpix") && msg.contains("float32") && msg.contains("bitpix.nii"),
            "{msg}"
        );
    }
}

#[test]
fn nifti_non_scalar_voxel_types_are_refused_by_name() {
    // (datatype, bitpix, name): RGB and complex types, with the bitpix that matches them and
    // enough voxel bytes, so only the type itself is wrong.
    let cases = [
        (128, 24, "RGB24"),
        (2304, 32, "RGBA32"),
        (32, 64, "complex64"),
        (1792, 128, "complex128"),
        (1, 1, "binary"),
        (1536, 128, "float128"),
    ];
    for (datatype, bitpix, name) in cases {
        let mut bytes = valid_nifti_bytes();
        set_i16(&mut bytes, DATATYPE, datatype);
        set_i16(&mut bytes, BITPIX, bitpix);
        bytes.resize(352 + 27 * 32, 0);
        let e = convert_bytes("type.nii", &bytes, &VolumeToTets::default()).unwrap_err();
        assert!(
            matches!(&e, VolumeError::UnsupportedType { datatype: d, type_name, .. } if *d == datatype && type_name.contains(name)),
            "{e}"
        );
        assert!(e.to_string().contains(name), "{e}");
    }
    let mut bytes = valid_nifti_bytes();
    set_i16(&mut bytes, DATATYPE, 777);
    let e = convert_bytes("type.nii", &bytes, &VolumeToTets::default()).unwrap_err();
    assert!(e.to_string().contains("datatype 777"), "{e}");
}

#[test]
fn nifti_vox_offset_skips_padding_before_the_voxels() {
    // 48 bytes of padding (NaN as float32) between the header and the voxels, vox_offset 400:
    // the voxels must be read from byte 400, never the padding.
    let valid = valid_nifti_bytes();
    let mut bytes = valid[..352].to_vec();
    bytes.extend(std::iter::repeat_n([0x00, 0x00, 0xC0, 0x7F], 12).flatten());
    bytes.extend(&valid[352..]);
    bytes[VOX_OFFSET..VOX_OFFSET + 4].copy_from_slice(&400f32.to_le_bytes());
    let mesh = convert_bytes("offset.nii", &bytes, &VolumeToTets::default()).unwrap();
    for (p, &v) in mesh.positions().iter().zip(mesh.scalars().unwrap()) {
        assert_eq!(
            v,
            value_at(p.x as usize, p.y as usize, p.z as usize) as f64,
            "{p}"
        );
    }
    // Inside the header, or not a whole byte: refused.
    for offset in [348.0f32, 0.0, 352.5, f32::NAN, 1e30] {
        bytes[VOX_OFFSET..VOX_OFFSET + 4].copy_from_slice(&offset.to_le_bytes());
        let e = convert_bytes("offset.nii", &bytes, &VolumeToTets::default()).unwrap_err();
        assert!(e.to_string().contains("vox_offset"), "{e}");
    }
}

#[test]
fn nifti_extension_records_of_size_zero_are_an_error_not_gigabytes() {
    // The extender announces extensions; the records in 352..vox_offset all claim size 0. The
    // old reader looped over them until the end of the file, keeping each one: 0.5 MB of such
    // records made 2 GB. 32,768 records (256 KiB) here.
    let valid = valid_nifti_bytes();
    let mut bytes = valid[..352].to_vec();
    bytes[EXTENDER] = 1;
    bytes.resize(352 + (1 << 18), 0);
    let offset = bytes.len() as f32;
    bytes[VOX_OFFSET..VOX_OFFSET + 4].copy_from_slice(&offset.to_le_bytes());
    bytes.extend(&valid[352..]);
    let start = Instant::now();
    let e = convert_bytes("ext0.nii", &bytes, &VolumeToTets::default()).unwrap_err();
    assert!(
        matches!(
            e,
            VolumeError::BadExtension {
                offset: 352,
                size: 0,
                ..
            }
        ),
        "{e}"
    );
    // Found at the first record: far under a second (measured: about a millisecond).
    assert!(start.elapsed().as_secs_f64() < 1.0);
    // A record that runs past vox_offset is refused too; a valid one is skipped.
    for (size, ok) in [(1i32 << 20, false), (16, true)] {
        bytes[352..356].copy_from_slice(&size.to_le_bytes());
        bytes[VOX_OFFSET..VOX_OFFSET + 4].copy_from_slice(&368f32.to_le_bytes());
        let mut file = bytes[..368].to_vec();
        file.extend(&valid[352..]);
        let result = convert_bytes("ext.nii", &file, &VolumeToTets::default());
        assert_eq!(result.is_ok(), ok, "{:?}", result.err());
    }
}

#[test]
fn nifti_volume_over_the_vertex_budget_names_the_downsample_factor_that_fits() {
    // A 1024^3 uint8 header (1 GiB of voxels; only the header is in the file): too many
    // vertices at full resolution, refused before any voxel is read, with the factor that fits
    // (1024^3 / 4^3 = 2^24 = the limit).
    let mut bytes = valid_nifti_bytes()[..352].to_vec();
    for k in 1..=3 {
        set_i16(&mut bytes, DIM + 2 * k, 1024);
    }
    set_i16(&mut bytes, DATATYPE, 2);
    set_i16(&mut bytes, BITPIX, 8);
    let e = convert_bytes("big.nii", &bytes, &VolumeToTets::default()).unwrap_err();
    assert!(
        matches!(
            e,
            VolumeError::TooLarge {
                suggested: 4,
                vertices: 1_073_741_824,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("--downsample 4"), "{e}");
    // With that factor the budget holds, and the missing voxels are what is wrong.
    let opts = VolumeToTets {
        downsample: 4,
        threshold: None,
    };
    let e = convert_bytes("big.nii", &bytes, &opts).unwrap_err();
    assert!(
        matches!(e, VolumeError::Truncated { expected, found: 352, .. } if expected == 352 + (1 << 30)),
        "{e}"
    );
}

#[test]
fn nifti_dim_errors_name_the_dimension_that_is_wrong() {
    for k in 1..=3 {
        let mut bytes = valid_nifti_bytes();
        set_i16(&mut bytes, DIM + 2 * k, 0);
        let e = convert_bytes("dim.nii", &bytes, &VolumeToTets::default()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(&format!("dim[{k}] is 0")), "{msg}");
        assert!(
            (1..=3)
                .filter(|&j| j != k)
                .all(|j| !msg.contains(&format!("dim[{j}]"))),
            "{msg}"
        );
    }
    let mut bytes = valid_nifti_bytes();
    set_i16(&mut bytes, DIM, 9);
    let e = convert_bytes("dim.nii", &bytes, &VolumeToTets::default()).unwrap_err();
    assert!(e.to_string().contains("dim[0]"), "{e}");
}

#[test]
fn nifti_truncated_voxels_and_non_nifti_files_are_errors() {
    let valid = valid_nifti_bytes();
    // Uncompressed: the file length is checked against the header before reading.
    let e = convert_bytes("short.nii", &valid[..400], &VolumeToTets::default()).unwrap_err();
    assert!(
        matches!(
            e,
            VolumeError::Truncated {
                expected: 460,
                found: 400,
                ..
            }
        ),
        "{e}"
    );
    // Gzip: found while streaming, at the row that is cut.
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(&mut gz, &valid[..400]).unwrap();
    let e = convert_bytes(
        "short.nii.gz",
        &gz.finish().unwrap(),
        &VolumeToTets::default(),
    )
    .unwrap_err();
    assert!(
        matches!(e, VolumeError::Truncated { expected: 460, .. }),
        "{e}"
    );
    for (bytes, what) in [(&b"hello"[..], "short"), (&[0u8; 400][..], "sizeof_hdr")] {
        let e = convert_bytes("junk.nii", bytes, &VolumeToTets::default()).unwrap_err();
        assert!(e.to_string().contains("junk.nii"), "{what}: {e}");
    }
    // Shorter than a header: said so, not "its header puts voxel data up to byte 348".
    let e = convert_bytes("junk.nii", b"hello", &VolumeToTets::default()).unwrap_err();
    assert!(
        e.to_string()
            .ends_with("not a NIfTI-1 volume tetvr can read: it has 5 bytes, fewer than the 348 of a NIfTI-1 header"),
        "{e}"
    );
}
