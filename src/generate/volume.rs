//! Scalar volumes (NIfTI-1 `.nii` / `.nii.gz`) to tetrahedral meshes.
//!
//! Vertices are voxel centres; each cell between 8 neighbouring voxel centres is a hexahedron
//! split into 6 conforming tets ([`crate::mesh::split`]). The voxel `(i, j, k)` lies at
//! `(i, j, k) * pixdim[1..4]`, so voxel 0's centre is the origin and the mesh has the volume's
//! physical size; the file's qform/sform affine (orientation, origin) is deliberately not
//! applied, only the spacing. Intensities are the stored values with the header's
//! `scl_slope`/`scl_inter` applied, in one scalar array named `intensity`.
//!
//! tetvr reads the header itself and checks every field it uses before reading a voxel
//! (`volume/header.rs`): `bitpix` must match `datatype`, only real scalar types are read (RGB, complex
//! and the rest are refused by name), the voxels start at `vox_offset`, extension records must
//! have a valid size, and the mesh may have at most [`MAX_VOLUME_VERTICES`] vertices (a larger
//! volume is refused with the `--downsample` factor that fits). Voxels are read one row at a
//! time and box-averaged as they arrive, so memory is the mesh plus one row, whatever the file
//! claims; gzip is recognized by its magic bytes, not the file name.

mod header;

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;

use flate2::bufread::MultiGzDecoder;
use glam::{DVec3, UVec3};

use super::{GenerateError, hex_grid_mesh};
use crate::mesh::{MeshError, TetMesh};
use header::{HEADER_LEN, MIN_VOX_OFFSET, NotNifti1, RawHeader, TypeProblem, VoxelType};

/// The largest `vox_offset` accepted (2^53, far beyond any real file).
const MAX_VOX_OFFSET: f32 = 9_007_199_254_740_992.0;

/// The most mesh vertices (samples after downsampling) a volume may give: 2^24, a 256^3 grid
/// of up to 100 M tets (about 2.5 GB as a mesh). A 1024^3 volume fits with `--downsample 4`.
pub const MAX_VOLUME_VERTICES: u64 = 1 << 24;

/// How [`nifti_to_tets`] turns voxels into tets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeToTets {
    /// Box-average downsampling factor (at least 1): each vertex is the mean of a block of
    /// `downsample^3` voxels, placed at the block's centre. Blocks that would stick out of the
    /// volume at its upper ends are dropped.
    pub downsample: u32,
    /// Drop the cells whose 8 corner values are all below this value (the background).
    pub threshold: Option<f64>,
}

impl Default for VolumeToTets {
    /// Every voxel, every cell.
    fn default() -> Self {
        Self {
            downsample: 1,
            threshold: None,
        }
    }
}

/// Why a volume could not be turned into tets; every message names the file.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum VolumeError {
    /// The file is missing or not NIfTI-1.
    #[error("{path}: cannot read it as NIfTI-1 (.nii or .nii.gz): {message}")]
    Read {
        /// The volume file.
        path: String,
        /// The reader's message.
        message: String,
    },
    /// The header is not one tetvr can read (magic, dimensions, offsets).
    #[error("{path}: not a NIfTI-1 volume tetvr can read: {message}")]
    BadHeader {
        /// The volume file.
        path: String,
        /// What is wrong with the header.
        message: String,
    },
    /// The voxel type is not one real number per voxel.
    #[error(
        "{path}: voxels of type {type_name} (datatype {datatype}) are not supported; tetvr reads one real number per voxel (uint8 to uint64, int8 to int64, float32, float64): convert the volume to one of those"
    )]
    UnsupportedType {
        /// The volume file.
        path: String,
        /// The header's datatype code.
        datatype: i16,
        /// The type's name.
        type_name: String,
    },
    /// `bitpix` disagrees with `datatype`.
    #[error(
        "{path}: header says bitpix {bitpix}, but datatype {datatype} ({type_name}) has {expected} bits per voxel; the header is inconsistent"
    )]
    BitpixMismatch {
        /// The volume file.
        path: String,
        /// The header's datatype code.
        datatype: i16,
        /// The type's name.
        type_name: String,
        /// The header's bitpix.
        bitpix: i16,
        /// The bits per voxel of the datatype.
        expected: usize,
    },
    /// An extension record is too small or runs past the voxel data's start.
    #[error(
        "{path}: extension record at byte {offset} has size {size}; a record holds its 8-byte size and code and must end by vox_offset {vox_offset}"
    )]
    BadExtension {
        /// The volume file.
        path: String,
        /// The record's byte offset in the file.
        offset: u64,
        /// Its declared size.
        size: i32,
        /// Where the header says the voxels start.
        vox_offset: u64,
    },
    /// The file ends before the voxel data the header declares.
    #[error(
        "{path}: the file ends after {found} bytes, but its header puts voxel data up to byte {expected} (vox_offset + voxels x bitpix / 8)"
    )]
    Truncated {
        /// The volume file.
        path: String,
        /// Bytes the header needs.
        expected: u64,
        /// Bytes the file has.
        found: u64,
    },
    /// The volume is not three-dimensional.
    #[error(
        "{path}: has dimensions {dims:?}; tetvr needs a 3D scalar volume (x, y, z, and any further dimension of size 1)"
    )]
    NotVolume3d {
        /// The volume file.
        path: String,
        /// Its dimensions.
        dims: Vec<usize>,
    },
    /// A downsample factor of 0.
    #[error("{path}: downsample factor {factor} is invalid; use 1 (every voxel) or more")]
    BadDownsample {
        /// The volume file.
        path: String,
        /// The factor given.
        factor: u32,
    },
    /// The volume itself has fewer than 2 voxels along some axis (a 2D image or a line), so no
    /// cell lies between voxel centres whatever the downsampling.
    #[error(
        "{path}: has {dims:?} voxels, fewer than 2 along an axis, so no cell lies between voxel centres; tetvr needs a 3D volume of at least 2 x 2 x 2 voxels (a 2D image cannot be tetrahedralized)"
    )]
    Flat {
        /// The volume file.
        path: String,
        /// Voxels along x, y, z.
        dims: [usize; 3],
    },
    /// Downsampling leaves no cell along some axis.
    #[error(
        "{path}: downsampling {dims:?} voxels by {factor} leaves fewer than 2 samples along an axis; use a smaller factor"
    )]
    TooSmall {
        /// The volume file.
        path: String,
        /// Voxels along x, y, z.
        dims: [usize; 3],
        /// The factor given.
        factor: u32,
    },
    /// The mesh would have more vertices than tetvr's limit.
    #[error(
        "{path}: too large: {dims:?} voxels downsampled by {factor} make {vertices} mesh vertices, more than tetvr's limit of {max}; use --downsample {suggested}"
    )]
    TooLarge {
        /// The volume file.
        path: String,
        /// Voxels along x, y, z.
        dims: [usize; 3],
        /// The factor given.
        factor: u32,
        /// Vertices the mesh would have.
        vertices: u64,
        /// The most tetvr makes.
        max: u64,
        /// The smallest factor that fits.
        suggested: u32,
    },
    /// The header's voxel spacing is zero or not finite.
    #[error("{path}: voxel spacing pixdim[1..4] = {spacing:?} must be non-zero and finite")]
    BadSpacing {
        /// The volume file.
        path: String,
        /// pixdim[1..4] of the header.
        spacing: [f32; 3],
    },
    /// A voxel value is NaN or infinite.
    #[error("{path}: voxel ({x}, {y}, {z}) has the non-finite value {value}")]
    NonFinite {
        /// The volume file.
        path: String,
        /// The voxel's x index.
        x: usize,
        /// The voxel's y index.
        y: usize,
        /// The voxel's z index.
        z: usize,
        /// Its value.
        value: f64,
    },
    /// The threshold is NaN or infinite.
    #[error("{path}: threshold {threshold} must be a finite number")]
    BadThreshold {
        /// The volume file.
        path: String,
        /// The threshold given.
        threshold: f64,
    },
    /// The threshold drops every cell.
    #[error(
        "{path}: every cell is below the threshold {threshold} (intensities range from {lo} to {hi}); lower it"
    )]
    AllBelowThreshold {
        /// The volume file.
        path: String,
        /// The threshold given.
        threshold: f64,
        /// The smallest intensity.
        lo: f64,
        /// The largest intensity.
        hi: f64,
    },
    /// The tets could not be made (too many of them).
    #[error("{path}: {source}")]
    Generate {
        /// The volume file.
        path: String,
        /// Why the generator refused.
        source: GenerateError,
    },
}

/// Reads the NIfTI-1 volume at `path` (gzip-compressed or not) and splits it into tets as the
/// [module docs](self) describe, with `opts`' downsampling and threshold.
pub fn nifti_to_tets(path: impl AsRef<Path>, opts: &VolumeToTets) -> Result<TetMesh, VolumeError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    check_options(&name, opts)?;
    let (file, len) = open(path, &name)?;
    convert(file, len, &name, opts)
}

/// [`nifti_to_tets`] for a file already in memory; `name` stands for the file in messages.
pub fn nifti_bytes_to_tets(
    bytes: &[u8],
    name: &str,
    opts: &VolumeToTets,
) -> Result<TetMesh, VolumeError> {
    check_options(name, opts)?;
    convert(bytes, bytes.len() as u64, name, opts)
}

fn check_options(name: &str, opts: &VolumeToTets) -> Result<(), VolumeError> {
    if opts.downsample == 0 {
        return Err(VolumeError::BadDownsample {
            path: name.to_owned(),
            factor: 0,
        });
    }
    match opts.threshold {
        Some(threshold) if !threshold.is_finite() => Err(VolumeError::BadThreshold {
            path: name.to_owned(),
            threshold,
        }),
        _ => Ok(()),
    }
}

/// Reads a volume from `source` (`len` bytes, gzip told by its magic bytes) and meshes it.
fn convert(
    source: impl BufRead,
    len: u64,
    name: &str,
    opts: &VolumeToTets,
) -> Result<TetMesh, VolumeError> {
    let volume = read_any(source, len, name, opts)?;
    mesh_volume(volume, name, opts)
}

/// The box-averaged samples of the NIfTI-1 volume at `path` (checked as [`nifti_to_tets`]
/// checks it; `opts.threshold` is not used), for the 3D textures of [`crate::texture`].
pub(crate) fn read_samples_file(path: &Path, opts: &VolumeToTets) -> Result<Samples, VolumeError> {
    let name = path.display().to_string();
    check_options(&name, opts)?;
    let (file, len) = open(path, &name)?;
    read_any(file, len, &name, opts)
}

/// Checks the header of the NIfTI-1 volume at `path` as [`read_samples_file`] does with every
/// voxel kept, and the file's length against it when it is not gzipped, reading no voxel.
pub(crate) fn check_header_file(path: &Path) -> Result<(), VolumeError> {
    let name = path.display().to_string();
    let (file, len) = open(path, &name)?;
    let (mut stream, len) = unzipped(file, len, &name)?;
    read_layout(&mut stream, len, &name, &VolumeToTets::default()).map(|_| ())
}

/// The file at `path` (`name` in messages) and its length.
fn open(path: &Path, name: &str) -> Result<(BufReader<File>, u64), VolumeError> {
    let io_error = |e: io::Error| read_error(name, e);
    let file = File::open(path).map_err(io_error)?;
    let len = file.metadata().map_err(io_error)?.len();
    Ok((BufReader::new(file), len))
}

/// Reads a volume from `source` (`len` bytes, gzip told by its magic bytes).
fn read_any(
    source: impl BufRead,
    len: u64,
    name: &str,
    opts: &VolumeToTets,
) -> Result<Samples, VolumeError> {
    let (mut stream, len) = unzipped(source, len, name)?;
    read_volume(&mut stream, len, name, opts)
}

/// A volume's bytes, gunzipped when the file is gzipped.
type Unzipped<'a> = Stream<Box<dyn Read + 'a>>;

/// The volume's bytes from `source` (`len` bytes), gunzipped when they start with gzip's magic
/// bytes, and the length its voxels must fit in (unknown behind gzip).
fn unzipped<'a>(
    mut source: impl BufRead + 'a,
    len: u64,
    name: &str,
) -> Result<(Unzipped<'a>, Option<u64>), VolumeError> {
    let start = source.fill_buf().map_err(|e| read_error(name, e))?;
    Ok(match start.starts_with(&[0x1f, 0x8b]) {
        true => (Stream::new(Box::new(MultiGzDecoder::new(source))), None),
        false => (Stream::new(Box::new(source)), Some(len)),
    })
}

fn read_error(name: &str, e: io::Error) -> VolumeError {
    VolumeError::Read {
        path: name.to_owned(),
        message: e.to_string(),
    }
}

/// A reader that counts the bytes it gave, so a short file can say where it ended.
struct Stream<R> {
    inner: R,
    pos: u64,
}

impl<R: Read> Stream<R> {
    fn new(inner: R) -> Self {
        Self { inner, pos: 0 }
    }

    /// Reads `n` bytes into `buf` (resized to `n`: callers ask for at most one voxel row, 256
    /// KiB); fewer only at the end of the file, which is then a [`VolumeError::Truncated`]
    /// against `expected`.
    fn read(
        &mut self,
        n: usize,
        buf: &mut Vec<u8>,
        expected: u64,
        name: &str,
    ) -> Result<(), VolumeError> {
        buf.resize(n, 0);
        let mut got = 0;
        while got < n {
            match self.inner.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(k) => got += k,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(read_error(name, e)),
            }
        }
        self.pos += got as u64;
        if got < n {
            return Err(VolumeError::Truncated {
                path: name.to_owned(),
                expected,
                found: self.pos,
            });
        }
        Ok(())
    }

    /// Skips `n` bytes without keeping them.
    fn skip(&mut self, n: u64, expected: u64, name: &str) -> Result<(), VolumeError> {
        let got = io::copy(&mut (&mut self.inner).take(n), &mut io::sink())
            .map_err(|e| read_error(name, e))?;
        self.pos += got;
        if got < n {
            return Err(VolumeError::Truncated {
                path: name.to_owned(),
                expected,
                found: self.pos,
            });
        }
        Ok(())
    }
}

/// A checked header: what tetvr needs to read the voxels.
#[derive(Clone, Debug)]
struct Layout {
    raw: RawHeader,
    dims: [usize; 3],
    kind: VoxelType,
    vox_offset: u64,
}

impl Layout {
    /// Where the voxel data ends.
    fn end(&self) -> u64 {
        let voxels = self.dims.iter().map(|&d| d as u64).product::<u64>();
        self.vox_offset + voxels * self.kind.size() as u64
    }
}

/// The box-averaged samples (x fastest) of a volume, their dimensions and the voxel spacing.
pub(crate) struct Samples {
    pub(crate) values: Vec<f64>,
    pub(crate) dims: [usize; 3],
    pub(crate) spacing: DVec3,
}

/// Reads and checks the header, skips (and checks) the extensions, then reads the voxels.
fn read_volume<R: Read>(
    stream: &mut Stream<R>,
    len: Option<u64>,
    name: &str,
    opts: &VolumeToTets,
) -> Result<Samples, VolumeError> {
    let (layout, spacing) = read_layout(stream, len, name, opts)?;
    skip_extensions(stream, &layout, name)?;
    let (values, dims) = read_samples(stream, &layout, opts.downsample as usize, name)?;
    Ok(Samples {
        values,
        dims,
        spacing,
    })
}

/// Reads and checks the header: its fields, the voxel spacing, the volume's size after `opts`'
/// downsampling, and the file's length `len` when known; the layout and spacing.
fn read_layout<R: Read>(
    stream: &mut Stream<R>,
    len: Option<u64>,
    name: &str,
    opts: &VolumeToTets,
) -> Result<(Layout, DVec3), VolumeError> {
    let mut buf = Vec::new();
    // A file shorter than a header is no NIfTI file: its "voxel data" has no header to end.
    (stream.read(HEADER_LEN, &mut buf, HEADER_LEN as u64, name)).map_err(|e| match e {
        VolumeError::Truncated { found, .. } => bad_header(
            name,
            format!("it has {found} bytes, fewer than the {HEADER_LEN} of a NIfTI-1 header"),
        ),
        e => e,
    })?;
    let bytes = buf
        .as_slice()
        .try_into()
        .expect("read gives the whole header");
    let raw = RawHeader::parse(bytes).map_err(|e| bad_header(name, not_nifti1_message(e)))?;
    let layout = check_header(raw, name)?;
    let spacing = check_spacing(&layout.raw, name)?;
    check_budget(layout.dims, opts.downsample, name)?;
    if let Some(found) = len.filter(|&len| len < layout.end()) {
        return Err(VolumeError::Truncated {
            path: name.to_owned(),
            expected: layout.end(),
            found,
        });
    }
    Ok((layout, spacing))
}

fn bad_header(name: &str, message: String) -> VolumeError {
    VolumeError::BadHeader {
        path: name.to_owned(),
        message,
    }
}

fn not_nifti1_message(e: NotNifti1) -> String {
    match e {
        NotNifti1::Nifti2 => {
            "sizeof_hdr is 540, a NIfTI-2 file; tetvr reads NIfTI-1 (convert it, e.g. with nibabel)"
                .to_owned()
        }
        NotNifti1::SizeofHdr(v) => format!("sizeof_hdr is {v}, expected 348 (a NIfTI-1 header)"),
    }
}

/// Checks the magic, the dimensions, the voxel type against `bitpix`, and `vox_offset`.
fn check_header(raw: RawHeader, name: &str) -> Result<Layout, VolumeError> {
    match &raw.magic {
        b"n+1\0" => {}
        b"ni1\0" => return Err(bad_header(name, "magic \"ni1\" marks the header of a .hdr/.img pair; tetvr reads single-file .nii or .nii.gz volumes".to_owned())),
        m => return Err(bad_header(name, format!("magic is {:?}, expected \"n+1\" (a single-file NIfTI-1 volume)", String::from_utf8_lossy(m)))),
    }
    let dims = check_dims(&raw.dim, name)?;
    let kind = check_type(raw.datatype, raw.bitpix, name)?;
    let vox_offset = raw.vox_offset;
    // Below 2^53 the end of the data (vox_offset + at most 2^49 voxel bytes) fits in u64.
    let valid = MIN_VOX_OFFSET as f32..MAX_VOX_OFFSET;
    if !(vox_offset.fract() == 0.0 && valid.contains(&vox_offset)) {
        return Err(bad_header(
            name,
            format!(
                "vox_offset is {vox_offset}; the voxels of a .nii start at a whole byte offset from {MIN_VOX_OFFSET} to 2^53"
            ),
        ));
    }
    Ok(Layout {
        dims,
        kind,
        vox_offset: vox_offset as u64,
        raw,
    })
}

/// `dim[0]` (the rank) and each `dim[k]` up to it; a 3D volume with any further size 1.
fn check_dims(dim: &[i16; 8], name: &str) -> Result<[usize; 3], VolumeError> {
    let rank = dim[0];
    if !(1..=7).contains(&rank) {
        return Err(bad_header(
            name,
            format!("dim[0] (the number of dimensions) is {rank}; it must be 1 to 7"),
        ));
    }
    let sizes = &dim[1..=rank as usize];
    if let Some(k) = sizes.iter().position(|&d| d < 1) {
        return Err(bad_header(
            name,
            format!(
                "dim[{}] is {}; each size up to dim[0] = {rank} must be at least 1",
                k + 1,
                sizes[k]
            ),
        ));
    }
    let sizes: Vec<usize> = sizes.iter().map(|&d| d as usize).collect();
    if sizes.len() < 3 || sizes[3..].iter().any(|&d| d != 1) {
        return Err(VolumeError::NotVolume3d {
            path: name.to_owned(),
            dims: sizes,
        });
    }
    Ok([sizes[0], sizes[1], sizes[2]])
}

/// The voxel type of `datatype`, which `bitpix` must agree with.
fn check_type(datatype: i16, bitpix: i16, name: &str) -> Result<VoxelType, VolumeError> {
    let kind = VoxelType::from_code(datatype).map_err(|problem| VolumeError::UnsupportedType {
        path: name.to_owned(),
        datatype,
        type_name: match problem {
            TypeProblem::Unsupported(type_name) => type_name.to_owned(),
            TypeProblem::Unknown => "unknown (not a NIfTI-1 datatype code)".to_owned(),
        },
    })?;
    let expected = kind.size() * 8;
    if bitpix as usize != expected || bitpix < 0 {
        return Err(VolumeError::BitpixMismatch {
            path: name.to_owned(),
            datatype,
            type_name: kind.name().to_owned(),
            bitpix,
            expected,
        });
    }
    Ok(kind)
}

fn check_spacing(raw: &RawHeader, name: &str) -> Result<DVec3, VolumeError> {
    let spacing = [raw.pixdim[1], raw.pixdim[2], raw.pixdim[3]];
    if spacing.iter().any(|s| !(s.is_finite() && *s != 0.0)) {
        return Err(VolumeError::BadSpacing {
            path: name.to_owned(),
            spacing,
        });
    }
    Ok(DVec3::from(spacing.map(|s| s.abs() as f64)))
}

/// Samples per axis after downsampling by `factor` (incomplete blocks dropped).
fn sample_dims(dims: [usize; 3], factor: usize) -> [usize; 3] {
    dims.map(|d| d / factor)
}

/// At least 2 voxels and 2 samples per axis and at most [`MAX_VOLUME_VERTICES`] in all.
fn check_budget(dims: [usize; 3], factor: u32, name: &str) -> Result<(), VolumeError> {
    let vertices = |f: u32| {
        sample_dims(dims, f as usize)
            .iter()
            .map(|&d| d as u64)
            .product::<u64>()
    };
    if dims.iter().any(|&d| d < 2) {
        return Err(VolumeError::Flat {
            path: name.to_owned(),
            dims,
        });
    }
    if sample_dims(dims, factor as usize).iter().any(|&d| d < 2) {
        return Err(VolumeError::TooSmall {
            path: name.to_owned(),
            dims,
            factor,
        });
    }
    if vertices(factor) > MAX_VOLUME_VERTICES {
        return Err(VolumeError::TooLarge {
            path: name.to_owned(),
            dims,
            factor,
            vertices: vertices(factor),
            max: MAX_VOLUME_VERTICES,
            suggested: (factor..)
                .find(|&f| vertices(f) <= MAX_VOLUME_VERTICES)
                .expect("a factor as large as the largest dimension leaves at most 1 vertex"),
        });
    }
    Ok(())
}

/// Reads the extender and checks and skips the extension records, up to `vox_offset`.
fn skip_extensions<R: Read>(
    stream: &mut Stream<R>,
    layout: &Layout,
    name: &str,
) -> Result<(), VolumeError> {
    let (end, vox_offset) = (layout.end(), layout.vox_offset);
    let mut buf = Vec::new();
    stream.read(4, &mut buf, end, name)?;
    if buf[0] != 0 {
        while stream.pos + 8 <= vox_offset {
            let offset = stream.pos;
            stream.read(8, &mut buf, end, name)?;
            let size = i32::from_le_bytes(buf[0..4].try_into().expect("4 bytes"));
            let size = if layout.raw.big_endian {
                size.swap_bytes()
            } else {
                size
            };
            if size < 8 || offset + size as u64 > vox_offset {
                return Err(VolumeError::BadExtension {
                    path: name.to_owned(),
                    offset,
                    size,
                    vox_offset,
                });
            }
            stream.skip(size as u64 - 8, end, name)?;
        }
    }
    stream.skip(vox_offset - stream.pos, end, name)
}

/// Reads the voxels row by row (x rows, then y, then z) and averages `f^3` blocks as they
/// arrive; returns the samples (x fastest) and their dimensions. Every voxel, dropped blocks
/// included, must be finite.
fn read_samples<R: Read>(
    stream: &mut Stream<R>,
    layout: &Layout,
    f: usize,
    name: &str,
) -> Result<(Vec<f64>, [usize; 3]), VolumeError> {
    let [nx, ny, nz] = layout.dims;
    let out = sample_dims(layout.dims, f);
    let (slope, inter) = layout.raw.scaling();
    let norm = 1.0 / (f * f * f) as f64;
    let row_bytes = nx * layout.kind.size();
    let (mut raw, mut row) = (Vec::new(), Vec::new());
    let mut layer = vec![0.0; out[0] * out[1]];
    let mut samples = Vec::with_capacity(out.iter().product());
    for z in 0..nz {
        for y in 0..ny {
            stream.read(row_bytes, &mut raw, layout.end(), name)?;
            row.clear();
            layout.kind.decode(&raw, layout.raw.big_endian, &mut row);
            row.iter_mut().for_each(|v| *v = *v * slope + inter);
            if let Some(x) = row.iter().position(|v| !v.is_finite()) {
                let (path, value) = (name.to_owned(), row[x]);
                return Err(VolumeError::NonFinite {
                    path,
                    x,
                    y,
                    z,
                    value,
                });
            }
            if z < out[2] * f && y < out[1] * f {
                let sums = &mut layer[out[0] * (y / f)..][..out[0]];
                for (x, v) in row[..out[0] * f].iter().enumerate() {
                    sums[x / f] += v;
                }
            }
        }
        if z < out[2] * f && z % f == f - 1 {
            samples.extend(layer.iter().map(|s| s * norm));
            layer.fill(0.0);
        }
    }
    Ok((samples, out))
}

/// The tets of the samples' grid, thresholded as `opts` asks.
fn mesh_volume(samples: Samples, name: &str, opts: &VolumeToTets) -> Result<TetMesh, VolumeError> {
    let Samples {
        values,
        dims,
        spacing,
    } = samples;
    let factor = opts.downsample;
    // At most 2^24 samples in all (checked), so each axis fits in u32.
    let sdims = UVec3::new(dims[0] as u32, dims[1] as u32, dims[2] as u32);
    let at = |v: UVec3| {
        values[v.x as usize + sdims.x as usize * (v.y as usize + sdims.y as usize * v.z as usize)]
    };
    let keep = |c: UVec3| match opts.threshold {
        None => true,
        Some(t) => (0..8u32).any(|k| at(c + UVec3::new(k & 1, (k >> 1) & 1, k >> 2)) >= t),
    };
    // A block's centre in voxel units: the mean of its voxels' indices.
    let half = (factor as f64 - 1.0) / 2.0;
    let position = |v: UVec3| (v.as_dvec3() * factor as f64 + half) * spacing;
    // At most 2^24 samples make at most 6 * 2^24 tets, 2.3 GiB by `memory_needed`: the default
    // limit always holds, so `generate nifti` takes no --max-memory.
    hex_grid_mesh(
        sdims - UVec3::ONE,
        false,
        keep,
        position,
        at,
        "intensity",
        super::default_max_memory(),
    )
    .map_err(|e| match e {
        GenerateError::Mesh(MeshError::NoTets) => {
            let (lo, hi) = values
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            VolumeError::AllBelowThreshold {
                path: name.to_owned(),
                threshold: opts.threshold.unwrap_or(f64::NEG_INFINITY),
                lo,
                hi,
            }
        }
        source => VolumeError::Generate {
            path: name.to_owned(),
            source,
        },
    })
}
