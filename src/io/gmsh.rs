//! Gmsh `.msh`: versions 2.2 (ASCII and binary), 4.0 (ASCII) and 4.1 (ASCII and binary).
//!
//! Node tags may be sparse and in any order. Elements: 4-node tets, 8-node hexahedra, 6-node
//! prisms and 5-node pyramids are read (Gmsh's first-order node order for these is the same as
//! VTK's Hexahedron/Wedge/Pyramid: bottom face counter-clockwise then top face, or base then
//! apex; see "Node ordering" in the Gmsh manual), 10-node tets through their four corner nodes
//! (listed first by both Gmsh and VTK); points, lines, triangles and quads of any order are
//! skipped and counted; any other 3D element is an error.
//!
//! Views: `$NodeData` blocks become point arrays and `$ElementData` blocks cell arrays, named by
//! their first string tag (the view's name); vector and tensor data are kept whole, with a
//! `"<name> magnitude"` scalar for node data. Blocks with the same name fill the same array:
//! partitions add their nodes or elements, and a later time step overwrites an earlier one (the
//! last step wins). Every node must have a value in the end, and every element that makes tets;
//! elements tetvr skips (boundary triangles) need none. The first view is the active field.
//! Binary views store node and element tags as 4-byte ints (as Gmsh writes them).
//!
//! Mesh blocks may repeat: a view appended to a mesh file (`gmsh.view.write(view, file,
//! append=True)`, File > Export with "append") writes `$MeshFormat`, `$Entities`, `$Nodes` and
//! `$Elements` again before its data. A repeat identical to the first is skipped; one that
//! differs is an error naming both places. Other sections are skipped.
//!
//! A block's values are kept as (node, values) entries until the end, when each array is laid
//! out per node: memory follows the values in the file, not blocks x nodes (a file of many
//! empty 9-component blocks reserves nothing).

use std::collections::HashMap;

use super::text::Cursor;
use super::{
    Assembler, Budget, Fields, Format, LoadError, LoadErrorKind, Loaded, Location, Scalar, shown,
};
use crate::mesh::DataArray;
use crate::mesh::name::shown_name;
use crate::mesh::split::CellKind;
use glam::DVec3;

#[derive(Clone, Copy, PartialEq)]
enum Version {
    V2,
    V40,
    V41,
}

/// Number of nodes of a Gmsh element type, and its dimension.
fn element_info(ty: i64) -> Option<(usize, u8)> {
    Some(match ty {
        15 => (1, 0),
        1 => (2, 1),
        8 => (3, 1),
        26 => (4, 1),
        27 => (5, 1),
        28 => (6, 1),
        2 => (3, 2),
        3 => (4, 2),
        9 => (6, 2),
        10 => (9, 2),
        16 => (8, 2),
        20 => (9, 2),
        21 => (10, 2),
        22 => (12, 2),
        23 | 24 => (15, 2),
        25 => (21, 2),
        4 => (4, 3),
        5 => (8, 3),
        6 => (6, 3),
        7 => (5, 3),
        11 => (10, 3),
        12 => (27, 3),
        13 => (18, 3),
        14 => (14, 3),
        17 => (20, 3),
        18 => (15, 3),
        19 => (13, 3),
        29 => (20, 3),
        30 => (35, 3),
        31 => (56, 3),
        92 => (64, 3),
        93 => (125, 3),
        _ => return None,
    })
}

fn solid_kind(ty: i64) -> Option<CellKind> {
    Some(match ty {
        4 => CellKind::Tetra,
        5 => CellKind::Hexahedron,
        6 => CellKind::Wedge,
        7 => CellKind::Pyramid,
        11 => CellKind::QuadraticTetra,
        _ => return None,
    })
}

/// Node tag to 0-based index.
enum NodeMap {
    Dense(Vec<u32>),
    Sparse(HashMap<u64, u32>),
}

impl NodeMap {
    fn get(&self, tag: u64) -> Option<u32> {
        match self {
            NodeMap::Dense(v) => v.get(tag as usize).copied().filter(|&i| i != u32::MAX),
            NodeMap::Sparse(m) => m.get(&tag).copied(),
        }
    }
}

struct Reader<'a> {
    c: Cursor<'a>,
    version: Version,
    /// `Some(big_endian)` for binary files.
    binary: Option<bool>,
    /// Width of `size_t` in 4.1 binary files.
    size_t: usize,
}

impl<'a> Reader<'a> {
    fn i32(&mut self, section: &str) -> Result<i64, LoadError> {
        let b = self.c.take(4, section)?;
        let a = [b[0], b[1], b[2], b[3]];
        Ok(if self.binary == Some(true) {
            i32::from_be_bytes(a)
        } else {
            i32::from_le_bytes(a)
        } as i64)
    }

    fn size_t(&mut self, section: &str) -> Result<u64, LoadError> {
        let ty = if self.size_t == 4 {
            Scalar::U32
        } else {
            Scalar::U64
        };
        let b = self.c.take(ty.size(), section)?;
        Ok(ty.decode(b, self.binary == Some(true))[0] as u64)
    }

    /// An integer: binary `int` or `size_t`, or an ASCII token.
    fn int(&mut self, wide: bool, what: &str, section: &str) -> Result<i64, LoadError> {
        match self.binary {
            Some(_) if wide => {
                let at = self.c.pos;
                let v = self.size_t(section)?;
                i64::try_from(v).map_err(|_| self.c.err(at, format!("{what} {v} is too large")))
            }
            Some(_) => self.i32(section),
            None => self.c.parse::<i64>(what),
        }
    }

    fn count(&mut self, wide: bool, what: &str, section: &str) -> Result<usize, LoadError> {
        let at = self.c.pos;
        let v = self.int(wide, what, section)?;
        usize::try_from(v).map_err(|_| self.c.err(at, format!("{what} is negative ({v})")))
    }

    fn expect_end(&mut self, end: &str) -> Result<(), LoadError> {
        let (at, t) = self.c.expect(end)?;
        if t != end.as_bytes() {
            return Err(self
                .c
                .err(at, format!("expected {end}, found '{}'", shown(t))));
        }
        Ok(())
    }

    /// Coordinates x, y, z (and `extra` parametric ones, dropped) of one node.
    fn coords(&mut self, extra: usize, node: usize) -> Result<DVec3, LoadError> {
        let describe = |_: usize, x: f64| format!("node {node} has the non-finite coordinate {x}");
        let v = self.c.values(
            3 + extra,
            Scalar::F64,
            self.binary,
            "$Nodes",
            Some(&describe),
        )?;
        Ok(DVec3::new(v[0], v[1], v[2]))
    }
}

/// The values of one view as read: node (or element) indices and `nc` values for each, in
/// file order.
struct ViewArray {
    name: String,
    nc: usize,
    /// Node or element indices.
    nodes: Vec<u32>,
    values: Vec<f64>,
}

/// The arrays so far, found by name in constant time (files may hold many thousand blocks).
#[derive(Default)]
struct ViewArrays {
    list: Vec<ViewArray>,
    slots: HashMap<String, usize>,
}

impl ViewArray {
    /// The values laid out per node or element, `n` of them (the last value given for one
    /// wins); NaN where none was given (values read are finite).
    fn dense(self, n: usize, budget: &Budget) -> Result<Vec<f64>, LoadError> {
        let nc = self.nc;
        let shown_n = shown_name(&self.name);
        budget.charge_items(n.saturating_mul(nc), 8, || {
            format!("view '{shown_n}' for {n} nodes or elements")
        })?;
        let mut out = vec![f64::NAN; n * nc];
        for (k, &i) in self.nodes.iter().enumerate() {
            let i = i as usize;
            out[i * nc..(i + 1) * nc].copy_from_slice(&self.values[k * nc..(k + 1) * nc]);
        }
        Ok(out)
    }
}

/// Sections that describe the mesh: a repeat of one must be identical to the first.
const MESH_SECTIONS: [&[u8]; 9] = [
    b"$MeshFormat",
    b"$PhysicalNames",
    b"$Entities",
    b"$PartitionedEntities",
    b"$Nodes",
    b"$Elements",
    b"$Periodic",
    b"$GhostElements",
    b"$Parametrizations",
];

/// What the sections read so far hold.
#[derive(Default)]
struct Sections<'b> {
    /// Positions, node tags in file order, and tags to indices.
    nodes: Option<(Vec<DVec3>, Vec<u64>, NodeMap)>,
    /// The cells, with the element tags in file order.
    elements: Option<(Assembler<'b>, Vec<u64>)>,
    /// Element tags to indices, built at the first `$ElementData`.
    element_map: Option<NodeMap>,
    arrays: ViewArrays,
    cell_arrays: ViewArrays,
    /// Whether the first view read is element data.
    first_view_cells: Option<bool>,
    /// Each mesh section's first byte range, for comparing repeats.
    spans: HashMap<&'static [u8], (usize, usize)>,
    skipped: Vec<String>,
}

pub(super) fn read(data: &[u8], name: &str, budget: &Budget) -> Result<Loaded, LoadError> {
    let c = Cursor::new(data, name, None, budget);
    let start = c.pos
        + (data[c.pos..].iter())
            .take_while(|b| b.is_ascii_whitespace())
            .count();
    let mut r = mesh_format(c)?;
    r.expect_end("$EndMeshFormat")?;
    let mut s = Sections::default();
    s.spans.insert(MESH_SECTIONS[0], (start, r.c.pos));
    while let Some((at, t)) = r.c.token() {
        r.section(&mut s, at, t)?;
    }
    let end = data.len();
    let (positions, tags, _) = s
        .nodes
        .ok_or_else(|| r.c.err(end, "the file has no $Nodes section"))?;
    let (asm, elem_tags) = s
        .elements
        .ok_or_else(|| r.c.err(end, "the file has no $Elements section"))?;
    let mut fields = Fields {
        skipped: s.skipped,
        cell_first: s.first_view_cells == Some(true),
        ..Fields::default()
    };
    for a in s.arrays.list {
        let (aname, nc) = (a.name.clone(), a.nc);
        let v = a.dense(tags.len(), budget)?;
        missing_value(&v, nc, |_| true).map_or(Ok(()), |i| {
            Err(no_value(name, "$NodeData", &aname, "node", tags[i]))
        })?;
        fields.point(&aname, v, nc);
    }
    for a in s.cell_arrays.list {
        let (aname, nc) = (a.name.clone(), a.nc);
        let v = a.dense(elem_tags.len(), budget)?;
        missing_value(&v, nc, |i| asm.makes_tets(i)).map_or(Ok(()), |i| {
            Err(no_value(
                name,
                "$ElementData",
                &aname,
                "element",
                elem_tags[i],
            ))
        })?;
        fields.cells.push(DataArray::new(aname, nc, v));
    }
    asm.finish(name, Format::Gmsh, positions, fields)
}

/// The first tuple of `values` (`nc` per item) without a value (NaN marks those: values read
/// are finite) among the items `needed`.
fn missing_value(values: &[f64], nc: usize, needed: impl Fn(usize) -> bool) -> Option<usize> {
    (values.iter().step_by(nc).enumerate())
        .find_map(|(i, v)| (v.is_nan() && needed(i)).then_some(i))
}

/// The error for view `aname` of `section` without a value for the `item` of tag `tag`.
fn no_value(file: &str, section: &str, aname: &str, item: &str, tag: u64) -> LoadError {
    LoadError::new(
        file,
        None,
        LoadErrorKind::Malformed(format!(
            "{section} '{}' gives no value for {item} {tag}",
            shown_name(aname)
        )),
    )
}

/// `$MeshFormat`'s line: the version, ASCII or binary (with binary's endianness marker) and
/// the data size; the reader set up for the rest of the file.
fn mesh_format<'a>(mut c: Cursor<'a>) -> Result<Reader<'a>, LoadError> {
    let (at, t) = c.expect("$MeshFormat")?;
    if t != b"$MeshFormat" {
        return Err(c.err_line(
            at,
            format!(
                "not a Gmsh file: expected $MeshFormat, found '{}'",
                shown(t)
            ),
        ));
    }
    let (vat, vtok) = c.expect("the format version")?;
    let version = match vtok {
        b"2" | b"2.0" | b"2.1" | b"2.2" => Version::V2,
        b"4" | b"4.0" => Version::V40,
        b"4.1" => Version::V41,
        _ => {
            return Err(LoadError::unsupported(
                c.name,
                Location::Line(c.line_of(vat)),
                format!(
                    "MSH version '{}' is not supported; tetvr reads 2.2, 4.0 (ASCII) and 4.1",
                    shown(vtok)
                ),
            ));
        }
    };
    let file_type: u32 = c.parse("the file type (0 ASCII, 1 binary)")?;
    let size_t: usize = c.parse("the data size")?;
    c.finish_line();
    let binary = match file_type {
        0 => None,
        1 => Some(endianness(&mut c, version, vat)?),
        _ => {
            return Err(c.err_line(
                vat,
                format!("file type {file_type} is neither 0 (ASCII) nor 1 (binary)"),
            ));
        }
    };
    if version == Version::V41 && binary.is_some() && size_t != 4 && size_t != 8 {
        return Err(c.err_line(vat, format!("data size {size_t} is not 4 or 8")));
    }
    c.by_byte = binary.is_some();
    Ok(Reader {
        c,
        version,
        binary,
        size_t,
    })
}

/// A binary file's endianness marker, the integer 1: true for big endian. `vat` is where the
/// version is, for the error on binary MSH 4.0.
fn endianness(c: &mut Cursor, version: Version, vat: usize) -> Result<bool, LoadError> {
    if version == Version::V40 {
        return Err(LoadError::unsupported(
            c.name,
            Location::Line(c.line_of(vat)),
            "binary MSH 4.0 is not supported; re-save as MSH 4.1 (gmsh -format msh41)",
        ));
    }
    let at = c.pos;
    let b = c.take(4, "$MeshFormat")?;
    let a = [b[0], b[1], b[2], b[3]];
    if u32::from_le_bytes(a) == 1 {
        Ok(false)
    } else if u32::from_be_bytes(a) == 1 {
        Ok(true)
    } else {
        Err(c.err_byte(at, "the binary endianness marker is not the integer 1"))
    }
}

impl<'a> Reader<'a> {
    /// One section, its keyword `t` at `at` read. A mesh section seen before must repeat the
    /// first exactly.
    fn section(&mut self, s: &mut Sections<'a>, at: usize, t: &[u8]) -> Result<(), LoadError> {
        if let Some(&first) = s.spans.get(t) {
            return self.repeat(at, t, first);
        }
        match t {
            b"$Nodes" => {
                s.nodes = Some(read_nodes(self)?);
                self.expect_end("$EndNodes")?;
            }
            b"$Elements" => {
                let (p, _, map) = s
                    .nodes
                    .as_ref()
                    .ok_or_else(|| self.c.err(at, "$Elements before $Nodes"))?;
                let mut a = Assembler::new(p.len(), self.c.budget);
                let tags = read_elements(self, map, &mut a)?;
                s.elements = Some((a, tags));
                self.expect_end("$EndElements")?;
            }
            b"$NodeData" | b"$ElementData" => self.view(s, at, t)?,
            _ if t.starts_with(b"$") && !t.starts_with(b"$End") => {
                self.skip_section(at, t, &mut s.skipped)?
            }
            _ => {
                return Err(self.c.err(
                    at,
                    format!("expected a section such as $Nodes, found '{}'", shown(t)),
                ));
            }
        }
        if let Some(k) = MESH_SECTIONS.iter().find(|k| **k == t) {
            s.spans.insert(k, (at, self.c.pos));
        }
        Ok(())
    }

    /// A `$NodeData` or `$ElementData` block (`t`, at `at`) into its arrays.
    fn view(&mut self, s: &mut Sections<'a>, at: usize, t: &[u8]) -> Result<(), LoadError> {
        let cells = t == b"$ElementData";
        let (section, item) = if cells {
            ("$ElementData", "element")
        } else {
            ("$NodeData", "node")
        };
        if cells
            && s.element_map.is_none()
            && let Some((_, tags)) = &s.elements
        {
            s.element_map = Some(tag_map(self, tags, "element")?);
        }
        let map = if cells {
            s.element_map.as_ref()
        } else {
            s.nodes.as_ref().map(|n| &n.2)
        };
        let map = map.ok_or_else(|| {
            let before = if cells { "$Elements" } else { "$Nodes" };
            self.c.err(at, format!("{section} before {before}"))
        })?;
        let arrays = if cells {
            &mut s.cell_arrays
        } else {
            &mut s.arrays
        };
        read_view(self, &View { map, section, item }, arrays)?;
        s.first_view_cells.get_or_insert(cells);
        self.expect_end(&format!("$End{}", &section[1..]))
    }

    /// A repeat at `at` of mesh section `t`, whose first copy spans `first`: skipped when
    /// identical, an error naming both places otherwise.
    fn repeat(
        &mut self,
        at: usize,
        t: &[u8],
        (start, end): (usize, usize),
    ) -> Result<(), LoadError> {
        let data = self.c.data;
        let (old, new) = (&data[start..end], &data[at..]);
        let same = old.iter().zip(new).take_while(|(a, b)| a == b).count();
        if same == old.len() {
            self.c.pos = at + old.len();
            return Ok(());
        }
        let place = |o: usize| {
            if self.c.by_byte {
                format!("byte {o}")
            } else {
                format!("line {}", self.c.line_of(o))
            }
        };
        Err(self.c.err(
            at + same,
            format!(
                "{} at {} differs here from the one at {}; tetvr reads a repeated mesh block \
                 (as Gmsh writes before an appended view) only when it is identical",
                shown(t),
                place(at),
                place(start)
            ),
        ))
    }

    /// Skips section `t` up to its `$End` line; element-node data are named in `skipped` by
    /// their first string tag.
    fn skip_section(
        &mut self,
        at: usize,
        t: &[u8],
        skipped: &mut Vec<String>,
    ) -> Result<(), LoadError> {
        let section = &t[1..];
        if section == b"ElementNodeData" {
            let save = self.c.pos;
            if self.c.parse::<usize>("").is_ok_and(|n| n > 0) {
                self.c.skip_ws();
                let s = self.c.rest_of_line().trim_ascii();
                skipped.push(String::from_utf8_lossy(s).trim_matches('"').to_owned());
            }
            self.c.pos = save;
        }
        let mut needle = b"$End".to_vec();
        needle.extend_from_slice(section);
        let rest = &self.c.data[self.c.pos..];
        let i = rest
            .windows(needle.len())
            .position(|w| w == needle.as_slice())
            .ok_or_else(|| {
                self.c.err(
                    at,
                    format!("section {} has no {}", shown(t), shown(&needle)),
                )
            })?;
        self.c.pos += i + needle.len();
        Ok(())
    }

    /// A 4.x `$Nodes` or `$Elements` header: the numbers of blocks and of `items` ("node" or
    /// "element"), and 4.1's tag range (read and dropped).
    fn block_counts(&mut self, items: &str, section: &str) -> Result<(usize, usize), LoadError> {
        let wide = self.version == Version::V41;
        if self.binary.is_some() {
            self.c.finish_line(); // binary data starts on the line after the keyword
        }
        let b = self.count(wide, &format!("the number of {items} blocks"), section)?;
        let n = self.count(wide, &format!("the number of {items}s"), section)?;
        if self.version == Version::V41 {
            self.int(wide, &format!("the minimum {items} tag"), section)?;
            self.int(wide, &format!("the maximum {items} tag"), section)?;
        }
        Ok((b, n))
    }
}

fn read_nodes(r: &mut Reader) -> Result<(Vec<DVec3>, Vec<u64>, NodeMap), LoadError> {
    let (blocks, total) = match r.version {
        // 2.2 binary files still give the count as text.
        Version::V2 => (1, r.c.count("the number of nodes")?),
        Version::V40 | Version::V41 => r.block_counts("node", "$Nodes")?,
    };
    if r.binary.is_some() && r.version == Version::V2 {
        r.c.finish_line();
    }
    // Each node takes at least 4 bytes in any encoding: cap the reservation by the file size.
    let cap = total.min(r.c.remaining() / 4);
    r.c.budget.charge_items(cap, size_of::<DVec3>() + 8, || {
        format!("the positions and tags of {cap} nodes")
    })?;
    let mut positions = Vec::with_capacity(cap);
    let mut tags: Vec<u64> = Vec::with_capacity(cap);
    for _ in 0..blocks {
        let at = r.c.pos;
        let (n, extra) = match r.version {
            Version::V2 => (total, 0),
            Version::V40 | Version::V41 => node_block_header(r)?,
        };
        if n > total - tags.len() {
            return Err(r.c.err(
                at,
                format!("node block of {n} nodes exceeds the node count {total}"),
            ));
        }
        node_block(r, n, extra, &mut tags, &mut positions)?;
    }
    if tags.len() != total {
        return Err(r.c.err(
            r.c.pos,
            format!(
                "the node blocks hold {} nodes, the header says {total}",
                tags.len()
            ),
        ));
    }
    let map = tag_map(r, &tags, "node")?;
    Ok((positions, tags, map))
}

/// A 4.x node block's header: its number of nodes, and how many parametric coordinates
/// follow each node's x, y, z.
fn node_block_header(r: &mut Reader) -> Result<(usize, usize), LoadError> {
    let wide = r.version == Version::V41;
    let (dim, param) = if r.version == Version::V41 {
        let dim = r.int(false, "the entity dimension", "$Nodes")?;
        r.int(false, "the entity tag", "$Nodes")?;
        (dim, r.int(false, "the parametric flag", "$Nodes")?)
    } else {
        r.int(false, "the entity tag", "$Nodes")?;
        let dim = r.int(false, "the entity dimension", "$Nodes")?;
        (dim, r.int(false, "the parametric flag", "$Nodes")?)
    };
    let n = r.count(wide, "the number of nodes in the block", "$Nodes")?;
    let extra = if param != 0 {
        dim.clamp(0, 3) as usize
    } else {
        0
    };
    Ok((n, extra))
}

/// A block's `n` nodes: 4.1 lists the tags, then the coordinates; earlier versions give
/// each node's tag and coordinates together.
fn node_block(
    r: &mut Reader,
    n: usize,
    extra: usize,
    tags: &mut Vec<u64>,
    positions: &mut Vec<DVec3>,
) -> Result<(), LoadError> {
    if r.version == Version::V41 {
        let first = tags.len();
        for _ in 0..n {
            let t = r.count(true, "a node tag", "$Nodes")?;
            tags.push(t as u64);
        }
        for i in 0..n {
            let p = r.coords(extra, first + i)?;
            positions.push(p);
        }
    } else {
        for _ in 0..n {
            let t = r.count(false, "a node tag", "$Nodes")? as u64;
            let p = r.coords(extra, tags.len())?;
            tags.push(t);
            positions.push(p);
        }
    }
    Ok(())
}

/// Node or element (`item`) tags to indices: a table where the tags are dense enough, a hash
/// map otherwise. A tag given twice is an error.
fn tag_map(r: &Reader, tags: &[u64], item: &str) -> Result<NodeMap, LoadError> {
    let max = tags.iter().copied().max().unwrap_or(0);
    let dup = |t: u64| r.c.err(r.c.pos, format!("{item} tag {t} is defined twice"));
    r.c.budget.charge_items(tags.len(), 16, || {
        format!("the index of {} {item} tags", tags.len())
    })?;
    if max <= 2 * tags.len() as u64 + 1024 {
        let mut v = vec![u32::MAX; max as usize + 1];
        for (i, &t) in tags.iter().enumerate() {
            if v[t as usize] != u32::MAX {
                return Err(dup(t));
            }
            v[t as usize] = i as u32;
        }
        Ok(NodeMap::Dense(v))
    } else {
        let mut m = HashMap::with_capacity(tags.len());
        for (i, &t) in tags.iter().enumerate() {
            if m.insert(t, i as u32).is_some() {
                return Err(dup(t));
            }
        }
        Ok(NodeMap::Sparse(m))
    }
}

/// The `$Elements` section into `asm`; returns the element tags in file order.
fn read_elements(
    r: &mut Reader,
    map: &NodeMap,
    asm: &mut Assembler,
) -> Result<Vec<u64>, LoadError> {
    let (blocks, total) = match r.version {
        Version::V2 => (usize::MAX, r.c.count("the number of elements")?),
        Version::V40 | Version::V41 => r.block_counts("element", "$Elements")?,
    };
    if r.binary.is_some() && r.version == Version::V2 {
        r.c.finish_line();
    }
    // Each element takes at least 4 bytes in any encoding: cap the reservation by the file.
    let cap = total.min(r.c.remaining() / 4);
    r.c.budget
        .charge_items(cap, 8, || format!("the tags of {cap} elements"))?;
    let mut tags: Vec<u64> = Vec::with_capacity(cap);
    let mut index = 0usize;
    let mut nodes: Vec<u64> = Vec::with_capacity(125);
    let mut block = 0;
    while block < blocks && !(r.version == Version::V2 && index == total) {
        block += 1;
        let at = r.c.pos;
        let (ty, n, ntags) = element_block_header(r)?;
        if n > total - index {
            return Err(r.c.err(
                at,
                format!("element block of {n} elements exceeds the element count {total}"),
            ));
        }
        for _ in 0..n {
            tags.push(element(r, map, asm, (index, ty, ntags), &mut nodes)?);
            index += 1;
        }
    }
    if index != total {
        return Err(r.c.err(
            r.c.pos,
            format!("the element blocks hold {index} elements, the header says {total}"),
        ));
    }
    Ok(tags)
}

/// Per block: element type, count, and (2.2) number of tags; 2.2 ASCII has one element per
/// "block" with its type on its own line.
fn element_block_header(r: &mut Reader) -> Result<(i64, usize, usize), LoadError> {
    Ok(match (r.version, r.binary) {
        (Version::V2, None) => (0, 1, 0),
        (Version::V2, Some(_)) => {
            let ty = r.i32("$Elements")?;
            let n = r.count(false, "the number of elements in the block", "$Elements")?;
            let nt = r.count(false, "the number of tags", "$Elements")?;
            (ty, n, nt)
        }
        (Version::V41, _) => {
            r.int(false, "the entity dimension", "$Elements")?;
            r.int(false, "the entity tag", "$Elements")?;
            let ty = r.int(false, "the element type", "$Elements")?;
            (
                ty,
                r.count(true, "the number of elements in the block", "$Elements")?,
                0,
            )
        }
        (Version::V40, _) => {
            r.int(false, "the entity tag", "$Elements")?;
            r.int(false, "the entity dimension", "$Elements")?;
            let ty = r.int(false, "the element type", "$Elements")?;
            (
                ty,
                r.count(false, "the number of elements in the block", "$Elements")?,
                0,
            )
        }
    })
}

/// One element, the `index`th of the file, of the block's type `ty` with `ntags` tags (2.2
/// ASCII gives both per element): a 3D one goes to `asm`, a lower one is counted; returns its
/// tag. `nodes` is scratch space.
fn element(
    r: &mut Reader,
    map: &NodeMap,
    asm: &mut Assembler,
    (index, ty, ntags): (usize, i64, usize),
    nodes: &mut Vec<u64>,
) -> Result<u64, LoadError> {
    let wide = r.version == Version::V41;
    let tag = r.count(wide, "an element tag", "$Elements")? as u64;
    let (ty, ntags) = if r.version == Version::V2 && r.binary.is_none() {
        let ty = r.int(false, "the element type", "$Elements")?;
        (ty, r.count(false, "the number of tags", "$Elements")?)
    } else {
        (ty, ntags)
    };
    for _ in 0..ntags {
        r.int(false, "an element tag", "$Elements")?;
    }
    let loc = Location::Element { index, tag };
    let Some((nn, dim)) = element_info(ty) else {
        return Err(LoadError::unsupported(
            r.c.name,
            loc,
            format!("unknown element type {ty}"),
        ));
    };
    nodes.clear();
    for _ in 0..nn {
        let t = r.count(wide, "a node tag", "$Elements")? as u64;
        nodes.push(t);
    }
    if dim < 3 {
        asm.skip()?;
        return Ok(tag);
    }
    let Some(kind) = solid_kind(ty) else {
        return Err(LoadError::unsupported(
            r.c.name,
            loc,
            format!(
                "element type {ty} (a {nn}-node 3D element) is not supported; tetvr reads \
                 tets (4, 11), hexahedra (5), prisms (6) and pyramids (7)"
            ),
        ));
    };
    let mut ids = [0i64; 10];
    for (k, &t) in nodes.iter().enumerate() {
        ids[k] = map.get(t).ok_or_else(|| {
            LoadError::malformed(r.c.name, loc.clone(), format!("node {t} is not defined"))
        })? as i64;
    }
    asm.cell(kind, &ids[..nn], |m| {
        LoadError::malformed(r.c.name, loc.clone(), m)
    })?;
    Ok(tag)
}

impl ViewArrays {
    /// The index of array `name` with `nc` components, a new one if the name is new; `None`
    /// if an array of that name has another number of components.
    fn slot(&mut self, name: &str, nc: usize) -> Option<usize> {
        match self.slots.get(name) {
            Some(&i) if self.list[i].nc == nc => Some(i),
            Some(_) => None,
            None => {
                self.slots.insert(name.to_owned(), self.list.len());
                self.list.push(ViewArray {
                    name: name.to_owned(),
                    nc,
                    nodes: Vec::new(),
                    values: Vec::new(),
                });
                Some(self.list.len() - 1)
            }
        }
    }
}

/// What a view block is read into: the node or element tag map, and words for messages.
struct View<'m> {
    map: &'m NodeMap,
    /// `$NodeData` or `$ElementData`.
    section: &'static str,
    /// "node" or "element".
    item: &'static str,
}

impl View<'_> {
    /// "a node tag" or "an element tag".
    fn tag_word(&self) -> &'static str {
        if self.item == "node" {
            "a node tag"
        } else {
            "an element tag"
        }
    }
}

/// A `$NodeData` or `$ElementData` block's values into `arrays` (by the view's name).
fn read_view(r: &mut Reader, v: &View, arrays: &mut ViewArrays) -> Result<(), LoadError> {
    let (map, section, item) = (v.map, v.section, v.item);
    let at = r.c.pos;
    let (aname, nc, n) = view_header(r, at, v)?;
    let shown_n = shown_name(&aname);
    if r.binary.is_some() {
        r.c.finish_line();
    }
    // An entry takes a 4-byte tag and nc 8-byte values in binary, and at least two bytes per
    // number in text: check the count against the file before reserving for it.
    let entry = if r.binary.is_some() {
        4 + 8 * nc
    } else {
        2 * (1 + nc)
    };
    if n > r.c.remaining() / entry {
        return Err(r.c.err(
            at,
            format!(
                "{section} '{shown_n}' announces {n} {item}s, more than the {} bytes left can hold",
                r.c.remaining()
            ),
        ));
    }
    let slot = arrays.slot(&aname, nc).ok_or_else(|| {
        r.c.err(
            at,
            format!("{section} '{shown_n}' changes its number of components"),
        )
    })?;
    r.c.budget.charge_items(n, 4 + 8 * nc, || {
        format!("{section} '{shown_n}' ({n} {item}s)")
    })?;
    let a = &mut arrays.list[slot];
    a.nodes.reserve(n);
    a.values.reserve(n * nc);
    for _ in 0..n {
        let tat = r.c.pos;
        let tag = r.count(false, v.tag_word(), section)? as u64;
        let i = map.get(tag).ok_or_else(|| {
            r.c.err(
                tat,
                format!("{section} '{shown_n}': {item} {tag} is not defined"),
            )
        })?;
        let describe = |_: usize, x: f64| {
            format!("{section} '{shown_n}' has the non-finite value {x} at {item} {tag}")
        };
        let v =
            r.c.values(nc, Scalar::F64, r.binary, section, Some(&describe))?;
        a.nodes.push(i);
        a.values.extend_from_slice(&v);
    }
    Ok(())
}

/// A view block's tags, the block starting at `at`: the array's name (the first string tag),
/// its number of components (1 to 9) and of nodes or elements (integer tags 2 and 3).
fn view_header(r: &mut Reader, at: usize, v: &View) -> Result<(String, usize, usize), LoadError> {
    let (section, item) = (v.section, v.item);
    let nstr = r.c.count("the number of string tags")?;
    let mut aname = None;
    for _ in 0..nstr {
        if r.c.at_end() {
            return Err(r.c.err(
                r.c.pos,
                format!("file ends inside the {section} string tags"),
            ));
        }
        let s = r.c.rest_of_line().trim_ascii();
        aname.get_or_insert_with(|| String::from_utf8_lossy(s).trim_matches('"').to_owned());
    }
    let aname = aname.unwrap_or_else(|| section[1..].to_owned());
    let shown_n = shown_name(&aname);
    let nreal = r.c.count("the number of real tags")?;
    for _ in 0..nreal {
        r.c.parse::<f64>("a real tag")?;
    }
    let nint = r.c.count("the number of integer tags")?;
    let mut ints = Vec::new();
    for _ in 0..nint {
        ints.push(r.c.parse::<i64>("an integer tag")?);
    }
    let (Some(&nc), Some(&n)) = (ints.get(1), ints.get(2)) else {
        return Err(r.c.err(
            at,
            format!(
                "{section} '{shown_n}' lacks the component and {item} counts (integer tags 2 and 3)"
            ),
        ));
    };
    let nc = usize::try_from(nc)
        .ok()
        .filter(|&k| (1..=9).contains(&k))
        .ok_or_else(|| {
            r.c.err(
                at,
                format!("{section} '{shown_n}' has {nc} components (expected 1 to 9)"),
            )
        })?;
    let n = usize::try_from(n).map_err(|_| {
        r.c.err(
            at,
            format!("{section} '{shown_n}' has a negative {item} count"),
        )
    })?;
    Ok((aname, nc, n))
}
