//! NIfTI-1 writer for the fuzz model: a header with mostly consistent fields (rank, sizes,
//! datatype and bitpix, spacing, scaling, vox_offset, magic), extension records, padding, voxel
//! bytes, optionally gzip-compressed.

use std::io::Write;

use arbitrary::Arbitrary;
use flate2::Compression;
use flate2::write::GzEncoder;
use tetvr::generate::volume::VolumeToTets;

use crate::Num;

/// NIfTI-1 datatype codes, the readable ones first; `Code` is any value.
const TYPES: [(i16, i16); 17] = [
    (2, 8),
    (4, 16),
    (8, 32),
    (16, 32),
    (64, 64),
    (256, 8),
    (512, 16),
    (768, 32),
    (1024, 64),
    (1280, 64),
    (32, 64),
    (128, 24),
    (2304, 32),
    (1792, 128),
    (1536, 128),
    (2048, 256),
    (1, 1),
];

#[derive(Arbitrary, Clone, Debug)]
pub struct Extension {
    pub size: Option<i32>,
    pub code: i32,
    pub len: u8,
}

#[derive(Arbitrary, Clone, Debug)]
pub struct Volume {
    pub dims: [u8; 3],
    /// dim[0] and dim[4..8] instead of 3 and 1s.
    pub rank: Option<(i16, [i16; 4])>,
    /// Index into the datatype table, or any code.
    pub datatype: Result<u8, i16>,
    pub bitpix: Option<i16>,
    pub big_endian: bool,
    pub spacing: [Num; 3],
    pub slope: Num,
    pub inter: Num,
    pub extensions: Vec<Extension>,
    pub extender: bool,
    /// Padding bytes before the voxels (vox_offset past the extensions).
    pub padding: u8,
    pub vox_offset: Option<f32>,
    pub pair_magic: bool,
    pub voxels: Vec<u8>,
    /// Voxel bytes dropped from (or, negative, added to) what the header needs.
    pub short_by: Option<i16>,
    pub gzip: bool,
    pub downsample: u8,
    pub threshold: Option<Num>,
}

impl Volume {
    /// The conversion options the fuzzer chose.
    pub fn options(&self) -> VolumeToTets {
        VolumeToTets {
            downsample: (self.downsample % 4) as u32,
            threshold: self.threshold.map(Num::value),
        }
    }

    fn type_and_bits(&self) -> (i16, i16) {
        let (code, bits) = match self.datatype {
            Ok(i) => TYPES[i as usize % TYPES.len()],
            Err(code) => (code, 32),
        };
        (code, self.bitpix.unwrap_or(bits))
    }
}

/// The volume as a `.nii` (or, with `gzip`, `.nii.gz`) file.
pub fn write(v: &Volume) -> Vec<u8> {
    let dims = v.dims.map(|d| (d % 12) as i16);
    let (rank, rest) = v.rank.unwrap_or((3, [1; 4]));
    let (code, bitpix) = v.type_and_bits();
    let mut ext = Vec::new();
    for e in &v.extensions {
        let size = e.size.unwrap_or(8 + 16 * (e.len as i32 % 4));
        ext.extend(pick(v.big_endian, size.to_le_bytes(), size.to_be_bytes()));
        ext.extend(pick(
            v.big_endian,
            e.code.to_le_bytes(),
            e.code.to_be_bytes(),
        ));
        ext.resize(ext.len() + (size.max(8) as usize - 8).min(64), 0);
    }
    let offset = 352 + ext.len() + v.padding as usize;
    let mut h = vec![0u8; 348];
    let mut put = |at: usize, le: &[u8], be: &[u8]| {
        h[at..at + le.len()].copy_from_slice(if v.big_endian { be } else { le })
    };
    put(0, &348i32.to_le_bytes(), &348i32.to_be_bytes());
    let dim = [
        rank, dims[0], dims[1], dims[2], rest[0], rest[1], rest[2], rest[3],
    ];
    for (k, d) in dim.iter().enumerate() {
        put(40 + 2 * k, &d.to_le_bytes(), &d.to_be_bytes());
    }
    put(70, &code.to_le_bytes(), &code.to_be_bytes());
    put(72, &bitpix.to_le_bytes(), &bitpix.to_be_bytes());
    for (k, s) in v.spacing.iter().enumerate() {
        let s = s.value() as f32;
        put(80 + 4 * k, &s.to_le_bytes(), &s.to_be_bytes());
    }
    let fields = [
        (108, v.vox_offset.unwrap_or(offset as f32)),
        (112, v.slope.value() as f32),
        (116, v.inter.value() as f32),
    ];
    for (at, f) in fields {
        put(at, &f.to_le_bytes(), &f.to_be_bytes());
    }
    h[344..348].copy_from_slice(if v.pair_magic { b"ni1\0" } else { b"n+1\0" });
    h.extend([v.extender as u8, 0, 0, 0]);
    h.extend(ext);
    h.resize(offset, 0xAB);
    h.extend(voxel_bytes(v, dims, bitpix));
    if !v.gzip {
        return h;
    }
    let mut enc = GzEncoder::new(Vec::new(), Compression::fast());
    enc.write_all(&h).expect("in memory");
    enc.finish().expect("in memory")
}

fn pick<const N: usize>(big: bool, le: [u8; N], be: [u8; N]) -> [u8; N] {
    if big { be } else { le }
}

/// The fuzzer's voxel bytes repeated to what the header needs, shortened by `short_by`.
fn voxel_bytes(v: &Volume, dims: [i16; 3], bitpix: i16) -> Vec<u8> {
    let voxels: i64 = dims.iter().map(|&d| d.max(0) as i64).product();
    let want = voxels * (bitpix.max(0) as i64 / 8) - v.short_by.map_or(0, |s| s as i64);
    let want = want.clamp(0, 1 << 20) as usize;
    if v.voxels.is_empty() {
        return vec![0; want];
    }
    (0..want).map(|i| v.voxels[i % v.voxels.len()]).collect()
}
