//! The NIfTI-1 header, read and checked by tetvr itself before a single voxel is read: the
//! `nifti` crate panics or misreads on headers whose fields disagree (issue 13), so tetvr takes
//! only the fields it needs from the 348 bytes and refuses anything it cannot honour.
//!
//! Layout (NIfTI-1, either byte order, told by `sizeof_hdr`): `sizeof_hdr` i32 at 0, `dim`
//! 8 x i16 at 40, `datatype` i16 at 70, `bitpix` i16 at 72, `pixdim` 8 x f32 at 76,
//! `vox_offset` f32 at 108, `scl_slope` and `scl_inter` f32 at 112 and 116, `magic` at 344;
//! bytes 348..352 are the extender, whose first byte says whether extension records follow.

/// Bytes of the header proper; the extender follows.
pub(super) const HEADER_LEN: usize = 348;
/// Where the first extension record, or without one the voxels, may start.
pub(super) const MIN_VOX_OFFSET: u64 = 352;

/// The voxel types tetvr reads: one real number per voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum VoxelType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

/// What the `datatype` code names, when tetvr cannot read it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum TypeProblem {
    /// A NIfTI-1 type that is not one real scalar per voxel, with its name and bits.
    Unsupported(&'static str),
    /// A code NIfTI-1 does not define.
    Unknown,
}

impl VoxelType {
    /// The type for a NIfTI-1 `datatype` code.
    pub(super) fn from_code(code: i16) -> Result<Self, TypeProblem> {
        use VoxelType::*;
        Ok(match code {
            2 => U8,
            4 => I16,
            8 => I32,
            16 => F32,
            64 => F64,
            256 => I8,
            512 => U16,
            768 => U32,
            1024 => I64,
            1280 => U64,
            _ => return Err(unsupported_name(code)),
        })
    }

    /// Bytes per voxel.
    pub(super) fn size(self) -> usize {
        use VoxelType::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }

    /// The type's NIfTI name, for messages.
    pub(super) fn name(self) -> &'static str {
        use VoxelType::*;
        match self {
            U8 => "uint8",
            I8 => "int8",
            U16 => "uint16",
            I16 => "int16",
            U32 => "uint32",
            I32 => "int32",
            U64 => "uint64",
            I64 => "int64",
            F32 => "float32",
            F64 => "float64",
        }
    }

    /// Appends the values of `bytes` (whole voxels of this type) to `out`, as f64.
    pub(super) fn decode(self, bytes: &[u8], big_endian: bool, out: &mut Vec<f64>) {
        macro_rules! each {
            ($t:ty) => {
                out.extend(bytes.chunks_exact(size_of::<$t>()).map(|c| {
                    let c = c.try_into().expect("chunks_exact gives whole voxels");
                    let v = if big_endian {
                        <$t>::from_be_bytes(c)
                    } else {
                        <$t>::from_le_bytes(c)
                    };
                    v as f64
                }))
            };
        }
        use VoxelType::*;
        match self {
            U8 => each!(u8),
            I8 => each!(i8),
            U16 => each!(u16),
            I16 => each!(i16),
            U32 => each!(u32),
            I32 => each!(i32),
            U64 => each!(u64),
            I64 => each!(i64),
            F32 => each!(f32),
            F64 => each!(f64),
        }
    }
}

fn unsupported_name(code: i16) -> TypeProblem {
    TypeProblem::Unsupported(match code {
        0 => "unknown (DT_UNKNOWN)",
        1 => "binary (1 bit)",
        32 => "complex64",
        128 => "RGB24",
        1536 => "float128",
        1792 => "complex128",
        2048 => "complex256",
        2304 => "RGBA32",
        _ => return TypeProblem::Unknown,
    })
}

/// The header fields tetvr uses, as stored (nothing validated yet but the byte order).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct RawHeader {
    pub big_endian: bool,
    pub magic: [u8; 4],
    pub dim: [i16; 8],
    pub datatype: i16,
    pub bitpix: i16,
    pub pixdim: [f32; 8],
    pub vox_offset: f32,
    pub scl_slope: f32,
    pub scl_inter: f32,
}

/// Why the first 348 bytes are not a NIfTI-1 header at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum NotNifti1 {
    /// `sizeof_hdr` is 540: a NIfTI-2 file.
    Nifti2,
    /// `sizeof_hdr` as a little-endian i32, neither 348 nor 540 in either order.
    SizeofHdr(i32),
}

impl RawHeader {
    /// Reads the fields from the 348 header bytes.
    pub(super) fn parse(b: &[u8; HEADER_LEN]) -> Result<Self, NotNifti1> {
        let le = i32::from_le_bytes(b[0..4].try_into().expect("4 bytes"));
        let big_endian = match (le, le.swap_bytes()) {
            (348, _) => false,
            (_, 348) => true,
            (540, _) | (_, 540) => return Err(NotNifti1::Nifti2),
            _ => return Err(NotNifti1::SizeofHdr(le)),
        };
        let i16_at = |at: usize| {
            let c = [b[at], b[at + 1]];
            if big_endian {
                i16::from_be_bytes(c)
            } else {
                i16::from_le_bytes(c)
            }
        };
        let f32_at = |at: usize| {
            let c = [b[at], b[at + 1], b[at + 2], b[at + 3]];
            if big_endian {
                f32::from_be_bytes(c)
            } else {
                f32::from_le_bytes(c)
            }
        };
        Ok(Self {
            big_endian,
            magic: b[344..348].try_into().expect("4 bytes"),
            dim: std::array::from_fn(|k| i16_at(40 + 2 * k)),
            datatype: i16_at(70),
            bitpix: i16_at(72),
            pixdim: std::array::from_fn(|k| f32_at(76 + 4 * k)),
            vox_offset: f32_at(108),
            scl_slope: f32_at(112),
            scl_inter: f32_at(116),
        })
    }

    /// The voxel scaling `(slope, inter)`: identity where `scl_slope` is 0 or not finite (the
    /// NIfTI-1 rule for "no scaling", read as nibabel does); a non-finite `scl_inter` counts as 0.
    pub(super) fn scaling(&self) -> (f64, f64) {
        let slope = self.scl_slope as f64;
        if slope == 0.0 || !slope.is_finite() {
            return (1.0, 0.0);
        }
        let inter = self.scl_inter as f64;
        (slope, if inter.is_finite() { inter } else { 0.0 })
    }
}
