//! The reference image cache of `tetvr bench`: exact reference images are costly (seconds to
//! minutes per view on large meshes), so each is computed once and kept on disk under a hash of
//! everything it depends on.
//!
//! **Key.** FNV-1a 64 ([`Fnv1a`]) of [`REFERENCE_VERSION`], the kind of truth (volume, or an
//! isosurface with its isovalues, colours and shading), the mesh's contents (positions, tets and
//! active scalars, bit for bit), the camera, the transfer function and the image size.
//! `std::hash::DefaultHasher` is not used: its output may change between Rust releases, which
//! would silently empty the cache.
//!
//! **File.** `<dir>/<key as 16 hex digits>.f32`: the 8-byte magic `TETVRREF`, then little-endian
//! `u32` format version, `u32` width, `u32` height, `u64` key, then the pixels as little-endian
//! `f32` RGBA, row-major. Raw floats rather than PNG: an 8-bit PNG would add up to 2e-3 of
//! quantization error, more than the modes being measured. A file whose header or length does
//! not match is treated as missing and rewritten.

use std::path::{Path, PathBuf};

use tetvr::image::Image;

/// Version of the reference renderer's output: bump it when a change to `reference` changes
/// its images, so cached ones are recomputed.
pub const REFERENCE_VERSION: u32 = 1;

const MAGIC: &[u8; 8] = b"TETVRREF";
const FORMAT_VERSION: u32 = 1;
const HEADER_BYTES: usize = 8 + 4 + 4 + 4 + 8;

/// The 64-bit FNV-1a hash (Fowler, Noll, Vo): tiny, stable across platforms and Rust versions.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    /// Hashes `bytes` into the state.
    pub fn bytes(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }

    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.bytes(&v.to_le_bytes())
    }

    /// Hashes the bits of `v` (so -0.0 and 0.0 differ, as they may in a picture).
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.u64(v.to_bits())
    }

    /// A string, with its length first so that consecutive strings cannot run together.
    pub fn str(&mut self, s: &str) -> &mut Self {
        self.u64(s.len() as u64).bytes(s.as_bytes())
    }

    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// Problems reading or writing the cache directory.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    #[error("{path}: cannot write the reference image cache: {source}; pass another --out")]
    Write {
        path: String,
        source: std::io::Error,
    },
}

/// A directory of cached reference images, counting hits and misses.
#[derive(Debug)]
pub struct ReferenceCache {
    dir: PathBuf,
    /// Images found on disk.
    pub hits: usize,
    /// Images computed (and then stored).
    pub misses: usize,
}

impl ReferenceCache {
    /// A cache in `dir` (created on the first store).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            hits: 0,
            misses: 0,
        }
    }

    /// The file that holds the image of `key`.
    pub fn path(&self, key: u64) -> PathBuf {
        self.dir.join(format!("{key:016x}.f32"))
    }

    /// The image stored under `key`, or `render()`'s result, stored for next time.
    pub fn get_or_render<E>(
        &mut self,
        key: u64,
        render: impl FnOnce() -> Result<Image, E>,
    ) -> Result<Image, E>
    where
        E: From<CacheError>,
    {
        let path = self.path(key);
        if let Some(image) = read(&path, key) {
            self.hits += 1;
            return Ok(image);
        }
        let image = render()?;
        self.misses += 1;
        write(&self.dir, &path, key, &image)?;
        Ok(image)
    }
}

fn read(path: &Path, key: u64) -> Option<Image> {
    let data = std::fs::read(path).ok()?;
    let u32_at = |i: usize| u32::from_le_bytes(data[i..i + 4].try_into().expect("4 bytes"));
    if data.len() < HEADER_BYTES || &data[..8] != MAGIC || u32_at(8) != FORMAT_VERSION {
        return None;
    }
    let (width, height) = (u32_at(12), u32_at(16));
    let stored_key = u64::from_le_bytes(data[20..28].try_into().expect("8 bytes"));
    let pixels = width as usize * height as usize;
    if stored_key != key || data.len() != HEADER_BYTES + pixels * 16 {
        return None;
    }
    let pixels = data[HEADER_BYTES..]
        .chunks_exact(16)
        .map(|p| {
            std::array::from_fn(|c| {
                f32::from_le_bytes(p[4 * c..4 * c + 4].try_into().expect("4 bytes"))
            })
        })
        .collect();
    Some(Image {
        width,
        height,
        pixels,
    })
}

fn write(dir: &Path, path: &Path, key: u64, image: &Image) -> Result<(), CacheError> {
    let fail = |source| CacheError::Write {
        path: path.display().to_string(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(fail)?;
    let mut data = Vec::with_capacity(HEADER_BYTES + image.pixels.len() * 16);
    data.extend_from_slice(MAGIC);
    data.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    data.extend_from_slice(&image.width.to_le_bytes());
    data.extend_from_slice(&image.height.to_le_bytes());
    data.extend_from_slice(&key.to_le_bytes());
    for p in &image.pixels {
        for c in p {
            data.extend_from_slice(&c.to_le_bytes());
        }
    }
    // Written beside and renamed, so an interrupted run never leaves a truncated image.
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, &data).map_err(fail)?;
    std::fs::rename(&tmp, path).map_err(fail)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_published_vectors() {
        // Test vectors of the FNV reference (http://www.isthe.com/chongo/tech/comp/fnv/).
        assert_eq!(Fnv1a::default().finish(), 0xcbf29ce484222325);
        assert_eq!(Fnv1a::default().bytes(b"a").finish(), 0xaf63dc4c8601ec8c);
        assert_eq!(
            Fnv1a::default().bytes(b"foobar").finish(),
            0x85944171f73967e8
        );
    }

    #[test]
    fn second_lookup_hits_and_is_bit_identical() {
        let dir = std::env::temp_dir().join(format!("tetvr-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut image = Image::new(3, 2);
        image.pixels[1] = [0.1, -0.0, f32::MIN_POSITIVE, 1.0 / 3.0];
        image.pixels[5] = [1e-30, 0.5, 0.25, 0.75];
        let mut cache = ReferenceCache::new(&dir);
        let first = cache
            .get_or_render(42, || Ok::<_, CacheError>(image.clone()))
            .unwrap();
        let second = cache
            .get_or_render(42, || -> Result<Image, CacheError> {
                panic!("a cached image must not be rendered again")
            })
            .unwrap();
        assert_eq!((cache.hits, cache.misses), (1, 1));
        let bits =
            |i: &Image| -> Vec<u32> { i.pixels.iter().flatten().map(|c| c.to_bits()).collect() };
        assert_eq!(bits(&first), bits(&image));
        assert_eq!(bits(&second), bits(&image));
        assert_eq!((second.width, second.height), (3, 2));
        // A corrupted file is a miss, not a wrong picture.
        std::fs::write(cache.path(42), b"TETVRREF short").unwrap();
        cache
            .get_or_render(42, || Ok::<_, CacheError>(image.clone()))
            .unwrap();
        assert_eq!((cache.hits, cache.misses), (1, 2));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
