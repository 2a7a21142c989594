//! Isosurfaces as meshes for other tools: marching tetrahedra ([`marching`]) written as glTF
//! binary (`.glb`, [`write_glb`]), which any glTF viewer opens.
//!
//! Layout of the file: one node `isosurfaces` whose translation is the centre of the surfaces'
//! bounding box, with one child node and mesh per non-empty isovalue (`isosurface <v>`). Each
//! mesh has one triangle primitive with `POSITION` (f32, relative to that centre, so f32 keeps
//! its ~7 digits relative to the surfaces' extent even for meshes far from the origin),
//! `NORMAL` (f32, unit, towards increasing scalar) and `u32` indices, and a double-sided
//! material whose `baseColorFactor` is the isovalue's colour. Every buffer view holds 4-byte
//! elements, so all are 4-byte aligned; `POSITION` accessors carry `min`/`max` as the spec
//! requires.

pub mod marching;
mod orient;

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

use glam::DVec3;
use gltf::json;

use crate::mode::show_value;
use json::validation::Checked::Valid;
use json::validation::USize64;

pub use marching::{Surface, isosurfaces};

/// Why an isosurface could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The file could not be written.
    #[error("{path}: cannot write the glTF file: {source}")]
    Write {
        /// The output file.
        path: String,
        /// Why the system refused.
        source: std::io::Error,
    },
    /// No isovalue produced a triangle, or no surface was given at all.
    #[error("{}", empty_message(.isovalues, *.lo, *.hi))]
    Empty {
        /// The isovalues asked for (empty: no surface was given).
        isovalues: Vec<f64>,
        /// The scalar range's minimum.
        lo: f64,
        /// The scalar range's maximum.
        hi: f64,
    },
    /// The surfaces exceed what a .glb can hold.
    #[error(
        "the isosurfaces have {vertices} vertices and {bytes} bytes of geometry; a .glb holds at \
         most 4 GiB and u32 indices; export fewer isovalues or a coarser mesh"
    )]
    TooLarge {
        /// Vertices over all surfaces.
        vertices: usize,
        /// Bytes of geometry.
        bytes: usize,
    },
    /// The glTF encoder failed (the message is its own).
    #[error("encoding the glTF file failed: {0}")]
    Encode(String),
}

/// Why no isovalue of `isovalues` gave a triangle on a field ranging over `[lo, hi]`, and what
/// to give instead. Marching tetrahedra count a vertex at the isovalue as above it (see
/// [`marching`]): at the range's minimum every vertex is above, so the surface is empty; at its
/// maximum every crossing collapses onto a vertex that reaches it, so the triangles are
/// degenerate and dropped (unless the maximum is held over a whole face). A value inside the
/// range met only by tets where the field is constant or by flat tets, or lying between the
/// values of vertices no tet uses, gives nothing either: said so, with no midpoint suggested
/// (it may be the value that failed: the CLI's default). No isovalue at
/// all (no surface given to [`write_glb`]) is said as such, with a value to extract at.
fn empty_message(isovalues: &[f64], lo: f64, hi: f64) -> String {
    let list = |v: &[f64]| {
        v.iter()
            .map(|&v| show_value(v))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (lo_s, hi_s) = (show_value(lo), show_value(hi));
    // Halved apart: lo + hi overflows to infinity near f64::MAX.
    let mid = show_value(0.5 * lo + 0.5 * hi);
    if isovalues.is_empty() {
        let what = match lo == hi {
            true => format!(
                "the field is constant ({lo_s} everywhere), so no isovalue would cross it; \
                 export another array (--array NAME)"
            ),
            false => format!(
                "extract surfaces at isovalues strictly inside the scalar range [{lo_s}, \
                 {hi_s}], e.g. {mid} (`export::isosurfaces`; `tetvr iso-export --iso`) and \
                 export those"
            ),
        };
        return format!("no isosurface to export: no surface was given (no isovalue); {what}");
    }
    if lo == hi {
        // No value lies inside: suggesting one (the midpoint is the value that failed) misleads.
        return format!(
            "no isosurface to export at isovalue(s) {}: the field is constant ({lo_s} \
             everywhere), so no value crosses it; export another array (--array NAME)",
            list(isovalues)
        );
    }
    let why = if isovalues.iter().any(|&v| v == lo || v == hi) {
        format!(
            "a surface at an end of the scalar range [{lo_s}, {hi_s}] is empty (at the minimum \
             the whole field is at or above it) or degenerate (at the maximum it shrinks to the \
             points that reach it)"
        )
    } else if isovalues.iter().all(|&v| lo < v && v < hi) {
        // Inside the range, "they miss it" is false, and the midpoint may be what failed.
        return format!(
            "no isosurface to export at isovalue(s) {}: no tet's values cross them, although \
             the scalar range [{lo_s}, {hi_s}] holds them (the tets there have a constant field \
             or no volume, or the range comes from vertices no tet uses: `tetvr info` counts \
             zero-volume tets and unused vertices); choose other values",
            list(isovalues)
        );
    } else {
        format!(
            "they miss the scalar range [{lo_s}, {hi_s}] or only meet tets where the field is \
             constant"
        )
    };
    format!(
        "no isosurface to export at isovalue(s) {}: {why}; choose values strictly inside the \
         range, e.g. {mid}",
        list(isovalues),
    )
}

/// A surface to export with its colour (linear RGB in [0, 1]).
#[derive(Clone, Copy, Debug)]
pub struct Colored<'a> {
    /// The triangles.
    pub surface: &'a Surface,
    /// Their colour.
    pub color: [f32; 3],
}

/// Counts of what was written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExportCounts {
    /// Surfaces (glTF meshes) written.
    pub surfaces: usize,
    /// Vertices over all surfaces.
    pub vertices: usize,
    /// Triangles over all surfaces.
    pub triangles: usize,
}

/// The surfaces (empty ones are left out) as the bytes of a `.glb`, and what they hold; see
/// the module docs for the layout.
pub fn glb_bytes(surfaces: &[Colored]) -> Result<(Vec<u8>, ExportCounts), ExportError> {
    let kept: Vec<&Colored> = surfaces
        .iter()
        .filter(|c| !c.surface.triangles.is_empty())
        .collect();
    let (counts, bytes) = checked_size(&kept)?;
    let centre = centre(&kept);
    let mut doc = Document::new(bytes);
    let children = kept.iter().map(|c| doc.surface_node(c, centre)).collect();
    let data = doc.finish(children, centre)?;
    Ok((data, counts))
}

/// What `kept` (the non-empty surfaces) holds, and its bytes of geometry: 24 a vertex (f32
/// position and normal), 12 a triangle (u32 indices); [`ExportError::TooLarge`] past what a
/// `.glb` holds.
fn checked_size(kept: &[&Colored]) -> Result<(ExportCounts, usize), ExportError> {
    let vertices: usize = kept.iter().map(|c| c.surface.positions.len()).sum();
    let triangles: usize = kept.iter().map(|c| c.surface.triangles.len()).sum();
    let bytes = 24 * vertices + 12 * triangles;
    // The JSON chunk and headers add a few kilobytes per surface; keep well below u32::MAX.
    if bytes > (u32::MAX as usize) - (1 << 20) || vertices > u32::MAX as usize {
        return Err(ExportError::TooLarge { vertices, bytes });
    }
    let counts = ExportCounts {
        surfaces: kept.len(),
        vertices,
        triangles,
    };
    Ok((counts, bytes))
}

/// The centre of the surfaces' bounding box, rounded to f32 (the origin when there are none).
/// Rounded first: the file's translation is f32, and positions are stored relative to exactly
/// that translation, so translation + position is the f64 point to f32 rounding of the (small)
/// relative coordinates.
fn centre(kept: &[&Colored]) -> DVec3 {
    let (lo, hi) = kept
        .iter()
        .flat_map(|c| &c.surface.positions)
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    if lo.is_finite() {
        ((lo + hi) * 0.5).as_vec3().as_dvec3()
    } else {
        DVec3::ZERO
    }
}

/// The per-component minimum and maximum of `points` (the `min`/`max` a `POSITION` accessor
/// must carry).
fn bounds(points: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    points.iter().fold(
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
            )
        },
    )
}

/// A glTF document being built: the JSON root and the one binary buffer its views point into.
struct Document {
    root: json::Root,
    bin: Vec<u8>,
    buffer: json::Index<json::Buffer>,
}

/// The accessors of one surface's triangle primitive.
struct Accessors {
    positions: json::Index<json::Accessor>,
    normals: json::Index<json::Accessor>,
    indices: json::Index<json::Accessor>,
}

impl Document {
    /// An empty document whose buffer will hold `bytes` bytes.
    fn new(bytes: usize) -> Self {
        let mut root = json::Root::default();
        let buffer = root.push(json::Buffer {
            byte_length: USize64::from(bytes),
            extensions: None,
            extras: Default::default(),
            name: None,
            uri: None,
        });
        Self {
            root,
            bin: Vec::with_capacity(bytes),
            buffer,
        }
    }

    /// Appends `data` to the buffer behind a new view for `target`.
    fn view(
        &mut self,
        data: &[u8],
        target: json::buffer::Target,
    ) -> json::Index<json::buffer::View> {
        let view = self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64::from(data.len()),
            byte_offset: Some(USize64::from(self.bin.len())),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        });
        self.bin.extend_from_slice(data);
        view
    }

    /// A new accessor of `count` elements over the whole of `view`.
    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        bounds: Option<([f32; 3], [f32; 3])>,
    ) -> json::Index<json::Accessor> {
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min: bounds.map(|b| json::Value::from(b.0.to_vec())),
            max: bounds.map(|b| json::Value::from(b.1.to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// The surface's geometry in the buffer (positions relative to `centre`, unit normals,
    /// indices; three views) and its accessors.
    fn geometry(&mut self, s: &Surface, centre: DVec3) -> Accessors {
        use json::accessor::{ComponentType as C, Type as T};
        use json::buffer::Target;
        let pos: Vec<[f32; 3]> = s
            .positions
            .iter()
            .map(|&p| (p - centre).as_vec3().to_array())
            .collect();
        let normals: Vec<[f32; 3]> = s
            .normals
            .iter()
            .map(|n| n.as_vec3().normalize_or_zero().to_array())
            .collect();
        let pv = self.view(bytemuck::cast_slice(&pos), Target::ArrayBuffer);
        let nv = self.view(bytemuck::cast_slice(&normals), Target::ArrayBuffer);
        let iv = self.view(
            bytemuck::cast_slice(&s.triangles),
            Target::ElementArrayBuffer,
        );
        let triangles = s.triangles.len();
        Accessors {
            positions: self.accessor(pv, pos.len(), C::F32, T::Vec3, Some(bounds(&pos))),
            normals: self.accessor(nv, normals.len(), C::F32, T::Vec3, None),
            indices: self.accessor(iv, 3 * triangles, C::U32, T::Scalar, None),
        }
    }

    /// A double-sided material named `name` of the colour `color` (clamped to [0, 1]).
    fn material(&mut self, name: &str, color: [f32; 3]) -> json::Index<json::Material> {
        let [r, g, b] = color.map(|v| v.clamp(0.0, 1.0));
        self.root.push(json::Material {
            double_sided: true,
            name: Some(name.to_owned()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([r, g, b, 1.0]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.6),
                ..Default::default()
            },
            ..Default::default()
        })
    }

    /// One surface as a node with its mesh (geometry, accessors, material), named after its
    /// isovalue.
    fn surface_node(&mut self, c: &Colored, centre: DVec3) -> json::Index<json::Node> {
        let a = self.geometry(c.surface, centre);
        let name = format!("isosurface {}", c.surface.isovalue);
        let material = self.material(&name, c.color);
        let mesh = self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(name.clone()),
            primitives: vec![json::mesh::Primitive {
                attributes: BTreeMap::from([
                    (Valid(json::mesh::Semantic::Positions), a.positions),
                    (Valid(json::mesh::Semantic::Normals), a.normals),
                ]),
                extensions: None,
                extras: Default::default(),
                indices: Some(a.indices),
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        });
        self.root.push(json::Node {
            mesh: Some(mesh),
            name: Some(name),
            ..Default::default()
        })
    }

    /// The scene (a top node at `centre` over `children`) and the document encoded as `.glb`
    /// bytes.
    fn finish(
        mut self,
        children: Vec<json::Index<json::Node>>,
        centre: DVec3,
    ) -> Result<Vec<u8>, ExportError> {
        let top = self.root.push(json::Node {
            children: Some(children),
            name: Some("isosurfaces".into()),
            translation: Some(centre.as_vec3().to_array()),
            ..Default::default()
        });
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: Some("tetvr isosurfaces".into()),
            nodes: vec![top],
        });
        self.root.scene = Some(scene);
        self.root.asset.generator = Some(format!("tetvr {}", env!("CARGO_PKG_VERSION")));
        let json_text = self
            .root
            .to_string()
            .map_err(|e| ExportError::Encode(e.to_string()))?;
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                // to_vec computes and writes the real length.
                length: 0,
            },
            json: Cow::Owned(json_text.into_bytes()),
            bin: Some(Cow::Owned(self.bin)),
        };
        glb.to_vec().map_err(|e| ExportError::Encode(e.to_string()))
    }
}

/// Writes the surfaces to `path` as a `.glb` (see [`glb_bytes`]); an error if every surface is
/// empty, or none is given (`range` is the scalar range, for the message).
pub fn write_glb(
    path: &Path,
    surfaces: &[Colored],
    range: (f64, f64),
) -> Result<ExportCounts, ExportError> {
    if surfaces.iter().all(|c| c.surface.triangles.is_empty()) {
        return Err(ExportError::Empty {
            isovalues: surfaces.iter().map(|c| c.surface.isovalue).collect(),
            lo: range.0,
            hi: range.1,
        });
    }
    let (data, counts) = glb_bytes(surfaces)?;
    std::fs::write(path, data).map_err(|source| ExportError::Write {
        path: path.display().to_string(),
        source,
    })?;
    Ok(counts)
}
