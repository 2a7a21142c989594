//! Perspective pinhole camera and the pixel-centre ray convention every mode shares.
//!
//! Pixel `(x, y)`, x to the right and y down, has its ray through `(x + 0.5, y + 0.5)`; the ray
//! parameter `t` is the Euclidean distance from the eye along the normalized direction.

use glam::DVec3;

use crate::mesh::{box_diagonal, length_of};

/// A perspective camera: eye, target, up, vertical field of view, image size in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, world units.
    pub eye: DVec3,
    /// The point the camera looks at (the centre of the image).
    pub target: DVec3,
    /// Up direction (need not be orthogonal to the view direction, nor parallel to it).
    pub up: DVec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f64,
    /// Image width in pixels (at least 1).
    pub width: u32,
    /// Image height in pixels (at least 1).
    pub height: u32,
}

/// Problems with a camera or view specification.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum CameraError {
    #[error(
        "the eye and the target are the same point; move the eye (--eye) or the target (--target)"
    )]
    /// The eye and the target coincide: no viewing direction.
    EyeAtTarget,
    /// The up vector is zero or parallel to the viewing direction.
    #[error("the up vector is zero or parallel to the viewing direction; pick another --up")]
    BadUp,
    /// The field of view (degrees) is not in (0, 180).
    #[error("field of view {0} degrees is outside (0, 180); use e.g. --fov 30")]
    BadFov(f64),
    /// The eye distance (a multiple of the framing distance) is not positive and finite.
    #[error(
        "eye distance {0} must be a positive multiple of the distance that fits the mesh; use e.g. --distance 1"
    )]
    BadDistance(f64),
    /// The image has no pixels (width x height).
    #[error("image size {0}x{1} is empty; use e.g. --size 512x512")]
    EmptyImage(u32, u32),
    #[error(
        "unknown view '{0}'; use one of +x, -x, +y, -y, +z, -z, iso, or AZIMUTH,ELEVATION in degrees"
    )]
    /// A view name that is not one of the known directions.
    UnknownView(String),
    /// A CPU renderer's frame of `width` x `height` pixels needs `bytes` of memory, more than
    /// can be allocated: refused before allocating it.
    #[error(
        "a {width}x{height} image needs {bytes} bytes of memory to render on the CPU, more than \
         can be allocated; render a smaller image (e.g. --size 4096x4096)"
    )]
    ImageTooLarge {
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
        /// The bytes the frame needs.
        bytes: u128,
    },
    /// A position, direction or angle is NaN or infinite.
    #[error("the camera setting is not finite; check the numbers given")]
    NotFinite,
}

/// A viewing direction from the target towards the eye, as azimuth and elevation in degrees
/// (azimuth from +x towards +y, elevation towards +z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Degrees from +x towards +y.
    pub azimuth_deg: f64,
    /// Degrees above the xy plane, in [-90, 90].
    pub elevation_deg: f64,
}

impl View {
    /// The default view: from the (+x, +y, +z) octant, the classic isometric direction.
    pub const ISO: View = View {
        azimuth_deg: 45.0,
        elevation_deg: 35.264_389_682_754_654,
    };

    /// Parses `+x`, `-x`, `+y`, `-y`, `+z`, `-z`, `iso` or `AZIMUTH,ELEVATION`.
    pub fn parse(s: &str) -> Result<Self, CameraError> {
        let v = |azimuth_deg, elevation_deg| View {
            azimuth_deg,
            elevation_deg,
        };
        Ok(match s.trim() {
            "+x" | "x" => v(0.0, 0.0),
            "-x" => v(180.0, 0.0),
            "+y" | "y" => v(90.0, 0.0),
            "-y" => v(-90.0, 0.0),
            "+z" | "z" => v(-90.0, 90.0),
            "-z" => v(-90.0, -90.0),
            "iso" => Self::ISO,
            other => {
                let parts: Vec<f64> = other
                    .split(',')
                    .map(|p| p.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| CameraError::UnknownView(s.to_owned()))?;
                match parts[..] {
                    [a, e] if a.is_finite() && e.is_finite() => v(a, e),
                    _ => return Err(CameraError::UnknownView(s.to_owned())),
                }
            }
        })
    }

    /// Unit vector from the target towards the eye.
    pub fn direction(self) -> DVec3 {
        let (a, e) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        );
        DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
    }

    /// Up vector for this view: +z, except when looking along z, where it is +y rotated by
    /// the azimuth so that top-down views keep a predictable orientation.
    pub fn up(self) -> DVec3 {
        if (self.elevation_deg.abs() - 90.0).abs() < 1e-6 {
            let a = self.azimuth_deg.to_radians();
            -DVec3::new(a.cos(), a.sin(), 0.0) * self.elevation_deg.signum()
        } else {
            DVec3::Z
        }
    }
}

impl Camera {
    /// Frames the box `[lo, hi]` from `view`: the target is the box centre and the eye is far
    /// enough that the box's bounding sphere fits the vertical field of view, times
    /// `distance_factor` (1 fits exactly; smaller moves closer, below ~0.5 the eye can be inside).
    pub fn framing(
        lo: DVec3,
        hi: DVec3,
        view: View,
        distance_factor: f64,
        fov_y_deg: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let target = (lo + hi) * 0.5;
        let radius = (box_diagonal(lo, hi) * 0.5).max(f64::MIN_POSITIVE);
        let distance = radius / (fov_y_deg.to_radians() * 0.5).sin() * distance_factor;
        Self {
            eye: target + view.direction() * distance,
            target,
            up: view.up(),
            fov_y_deg,
            width,
            height,
        }
    }

    /// Checks that the camera defines rays: a distinct target, a usable up vector, a sane FOV.
    pub fn validate(&self) -> Result<(), CameraError> {
        if !(self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && self.fov_y_deg.is_finite())
        {
            return Err(CameraError::NotFinite);
        }
        if self.width == 0 || self.height == 0 {
            return Err(CameraError::EmptyImage(self.width, self.height));
        }
        check_fov(self.fov_y_deg)?;
        let f = self.target - self.eye;
        if f == DVec3::ZERO {
            return Err(CameraError::EyeAtTarget);
        }
        if !f.is_finite() {
            return Err(CameraError::NotFinite);
        }
        if self.forward().cross(self.up).length() < 1e-9 {
            return Err(CameraError::BadUp);
        }
        Ok(())
    }

    /// Orthonormal camera basis `(right, up, forward)`; `forward` points from the eye into the
    /// scene, `right` to the image's +x and `up` to the image's -y. Assumes [`Self::validate`].
    pub fn basis(&self) -> (DVec3, DVec3, DVec3) {
        let forward = self.forward();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        (right, up, forward)
    }

    /// The unit vector from the eye to the target at any scale: the difference over its
    /// length taken without squaring it ([`length_of`]; squared, eye and target 1e-160 or
    /// 1e160 apart made it NaN or zero).
    fn forward(&self) -> DVec3 {
        let f = self.target - self.eye;
        f / length_of(f)
    }

    /// `tan(fov_y / 2)`: the image plane's half height at distance 1.
    pub(crate) fn tan_half_fov(&self) -> f64 {
        (self.fov_y_deg.to_radians() * 0.5).tan()
    }

    pub(crate) fn aspect(&self) -> f64 {
        self.width as f64 / self.height as f64
    }

    /// The normalized direction of pixel `(x, y)`'s ray through the pixel centre.
    pub fn ray_dir(&self, x: u32, y: u32) -> DVec3 {
        let (right, up, forward) = self.basis();
        self.ray_dir_in(right, up, forward, x, y)
    }

    /// [`Self::ray_dir`] with a precomputed [`Self::basis`] (for per-pixel loops).
    pub fn ray_dir_in(&self, right: DVec3, up: DVec3, forward: DVec3, x: u32, y: u32) -> DVec3 {
        let th = self.tan_half_fov();
        let u = (2.0 * (x as f64 + 0.5) / self.width as f64 - 1.0) * th * self.aspect();
        let v = (1.0 - 2.0 * (y as f64 + 0.5) / self.height as f64) * th;
        (forward + right * u + up * v).normalize()
    }
}

/// An error unless a CPU renderer's frame of `width` x `height` pixels, `bytes_per_pixel` in
/// all (the image and its working buffers), can be allocated now: tried, not taken (reserved
/// address space, no page touched). Unchecked, a size beyond memory aborted the process in
/// the allocator (`u32::MAX` x 2 pixels), or beyond the address space panicked.
pub(crate) fn check_frame_memory(
    width: u32,
    height: u32,
    bytes_per_pixel: u64,
) -> Result<(), CameraError> {
    let bytes = width as u128 * height as u128 * bytes_per_pixel as u128;
    let fits = usize::try_from(bytes).is_ok_and(|b| Vec::<u8>::new().try_reserve_exact(b).is_ok());
    match fits {
        true => Ok(()),
        false => Err(CameraError::ImageTooLarge {
            width,
            height,
            bytes,
        }),
    }
}

/// An error unless the field of view `fov` (degrees) is in (0, 180): [`Camera::validate`]'s
/// rule, also checked on its own before a camera exists (a scene's, before its mesh is read).
pub(crate) fn check_fov(fov: f64) -> Result<(), CameraError> {
    match fov > 0.0 && fov < 180.0 {
        true => Ok(()),
        false => Err(CameraError::BadFov(fov)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(w: u32, h: u32) -> Camera {
        Camera {
            eye: DVec3::new(0.0, -5.0, 0.0),
            target: DVec3::ZERO,
            up: DVec3::Z,
            fov_y_deg: 90.0,
            width: w,
            height: h,
        }
    }

    #[test]
    fn a_camera_at_any_scale_is_valid_and_frames_its_box() {
        // Eye, target and box scaled by a power of ten: the same rays (to rounding, 1e-15)
        // and the eye framing the scaled box at the scaled distance. Squared, the view
        // direction was zero above 1e154 (refused as a bad up vector) and its length 0 below
        // 1e-154 (refused as an eye at the target), and the framing's radius infinite or 0.
        let c = cam(4, 4);
        let framed = Camera::framing(-DVec3::ONE, DVec3::ONE, View::ISO, 1.0, 45.0, 4, 4);
        for scale in [1e-300, 1e-200, 1e200, 1e300] {
            let s = Camera {
                eye: c.eye * scale,
                target: c.target * scale,
                ..c
            };
            s.validate().unwrap();
            assert!(
                (s.ray_dir(1, 2) - c.ray_dir(1, 2)).length() < 1e-15,
                "{scale:e}"
            );
            let (lo, hi) = (-DVec3::ONE * scale, DVec3::ONE * scale);
            let f = Camera::framing(lo, hi, View::ISO, 1.0, 45.0, 4, 4);
            f.validate().unwrap();
            let error = f.eye / scale - framed.eye;
            assert!(
                error.length() < 1e-14 * framed.eye.length(),
                "{scale:e}: {f:?}"
            );
        }
    }

    #[test]
    fn centre_pixel_looks_at_target_and_axes_follow_image() {
        let c = cam(3, 3);
        assert!((c.ray_dir(1, 1) - DVec3::Y).length() < 1e-12);
        // x to the right is +x in the world here; y down in the image is -z in the world.
        assert!(c.ray_dir(2, 1).x > 0.0);
        assert!(c.ray_dir(1, 2).z < 0.0);
        // 90 degree FOV, 3 pixels: the top row centre is at v = 2/3.
        let d = c.ray_dir(1, 0);
        assert!((d.z / d.y - 2.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn framing_fits_the_bounding_sphere() {
        let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
        for name in ["+x", "-x", "+y", "-y", "+z", "-z", "iso", "30,20"] {
            let v = View::parse(name).unwrap();
            let c = Camera::framing(lo, hi, v, 1.0, 30.0, 64, 64);
            c.validate().unwrap();
            let dist = c.eye.length();
            let r = 3f64.sqrt();
            assert!(
                (r / dist - 15f64.to_radians().sin()).abs() < 1e-12,
                "{name}"
            );
        }
        assert!(View::parse("sideways").is_err());
    }

    #[test]
    fn invalid_cameras_are_errors() {
        let mut c = cam(4, 4);
        c.up = DVec3::Y;
        assert_eq!(c.validate(), Err(CameraError::BadUp));
        c = cam(0, 4);
        assert_eq!(c.validate(), Err(CameraError::EmptyImage(0, 4)));
        c = cam(4, 4);
        c.target = c.eye;
        assert_eq!(c.validate(), Err(CameraError::EyeAtTarget));
    }
}
