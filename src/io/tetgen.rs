//! TetGen `.node` + `.ele`: `#` comments, 0- or 1-based numbering (taken from the first point's
//! index; points must be numbered consecutively from there), 4- or 10-node tets. Point
//! attributes become arrays `attribute0`, `attribute1`, ...; tet attributes (TetGen's region
//! attributes) become one cell array `tetrahedron attributes` of as many components (select one
//! with `tetrahedron attributes:0`).

use super::text::Cursor;
use super::{Assembler, Budget, Fields, Format, LoadError, Loaded, Location, Scalar};
use crate::mesh::split::CellKind;
use crate::mesh::{DataArray, ScalarArray};
use glam::DVec3;

pub(super) fn read(
    node: &[u8],
    node_name: &str,
    ele: &[u8],
    ele_name: &str,
    budget: &Budget,
) -> Result<Loaded, LoadError> {
    let mut c = Cursor::new(node, node_name, Some(b'#'), budget);
    let header = node_header(&mut c)?;
    let points = read_points(&mut c, header)?;
    let mut e = Cursor::new(ele, ele_name, Some(b'#'), budget);
    let mut asm = Assembler::new(points.positions.len(), budget);
    let tet_attrs = read_tets(&mut e, points.base, &mut asm)?;
    let mut fields = Fields {
        scalars: split_rows(&points.attrs, header.attributes)
            .enumerate()
            .map(|(k, v)| ScalarArray::new(format!("attribute{k}"), v))
            .collect(),
        ..Fields::default()
    };
    if tet_attrs.count > 0 {
        let a = DataArray::new("tetrahedron attributes", tet_attrs.count, tet_attrs.values);
        fields.cells.push(a);
    }
    asm.finish(ele_name, Format::TetGen, points.positions, fields)
}

/// Columns of a row-by-row table of `columns` values per row.
fn split_rows(rows: &[f64], columns: usize) -> impl Iterator<Item = Vec<f64>> + '_ {
    (0..columns).map(move |k| rows.iter().skip(k).step_by(columns).copied().collect())
}

/// The `.ele` file's tet attributes: `count` per tet, row by row.
struct TetAttributes {
    count: usize,
    values: Vec<f64>,
}

/// The `.node` file's first line.
#[derive(Clone, Copy)]
struct NodeHeader {
    points: usize,
    attributes: usize,
    boundary_markers: usize,
}

/// The `.node` header line: point count, dimension 3, attributes and boundary markers, each
/// checked against the file's size before anything is reserved.
fn node_header(c: &mut Cursor) -> Result<NodeHeader, LoadError> {
    let n = c.count("the number of points")?;
    let (dat, dim) = c.expect("the dimension")?;
    if dim != b"3" {
        return Err(c.err(dat, "the dimension must be 3 (tetvr reads 3D meshes)"));
    }
    let nattr = c.count("the number of point attributes")?;
    // Each attribute takes at least two bytes per point.
    if nattr > c.remaining() / 2 {
        return Err(c.err(
            dat,
            format!("{nattr} point attributes cannot fit in the file"),
        ));
    }
    let nbm = c.count("the number of boundary markers (0 or 1)")?;
    if nbm > 1 {
        return Err(c.err(
            dat,
            format!("expected 0 or 1 boundary markers, found {nbm}"),
        ));
    }
    if n == 0 {
        return Err(c.err(0, "the .node file lists no points"));
    }
    // A point line has at least 4 + nattr tokens of 2 bytes: check the count by the file size.
    if n > c.remaining() / (8 + 2 * nattr) {
        return Err(c.err(
            dat,
            format!("{n} points of {nattr} attributes cannot fit in the file"),
        ));
    }
    Ok(NodeHeader {
        points: n,
        attributes: nattr,
        boundary_markers: nbm,
    })
}

/// The `.node` file's points.
struct Points {
    positions: Vec<DVec3>,
    /// Point attributes row by row (point after point), split into arrays at the end.
    attrs: Vec<f64>,
    /// The first point's index, 0 or 1: the file's numbering.
    base: usize,
}

/// The point lines after the header, numbered consecutively from 0 or 1, and nothing after.
fn read_points(c: &mut Cursor, h: NodeHeader) -> Result<Points, LoadError> {
    let (n, nattr) = (h.points, h.attributes);
    c.budget
        .charge_items(n, size_of::<DVec3>() + 8 * nattr, || {
            format!("{n} points with {nattr} attributes")
        })?;
    let mut p = Points {
        positions: Vec::with_capacity(n),
        attrs: Vec::with_capacity(n * nattr),
        base: 0,
    };
    for i in 0..n {
        let idx = point_index(c, i, &mut p.base)?;
        let describe = |_: usize, x: f64| format!("point {idx} has the non-finite coordinate {x}");
        let xyz = c.values(
            3,
            Scalar::F64,
            None,
            "the point coordinates",
            Some(&describe),
        )?;
        p.positions.push(DVec3::new(xyz[0], xyz[1], xyz[2]));
        let section = (nattr, "the point attributes");
        read_attributes(c, section, ("point", idx as u64), &mut p.attrs)?;
        for _ in 0..h.boundary_markers {
            c.parse::<i64>("a boundary marker")?;
        }
    }
    if !c.at_end() {
        return Err(c.err(c.pos, format!("unexpected data after the {n} points")));
    }
    Ok(p)
}

/// The `count` attributes of point or tetrahedron (`kind`) `index` of the file, each a finite
/// number, appended to `out`. `section` names them in a parse error: a literal, as this runs
/// once per line of the file and a message is only formatted on an error.
fn read_attributes(
    c: &mut Cursor,
    (count, section): (usize, &str),
    (kind, index): (&str, u64),
    out: &mut Vec<f64>,
) -> Result<(), LoadError> {
    let describe =
        |k: usize, x: f64| format!("attribute {k} of {kind} {index} is not finite ({x})");
    out.extend(c.values(count, Scalar::F64, None, section, Some(&describe))?);
    Ok(())
}

/// The index of the `i`th point line: the first sets the numbering `base` (0 or 1), the
/// others must follow in sequence.
fn point_index(c: &mut Cursor, i: usize, base: &mut usize) -> Result<usize, LoadError> {
    let (iat, _) = c.expect("a point index")?;
    c.pos = iat;
    let idx: usize = c.count("a point index")?;
    if i == 0 {
        if idx > 1 {
            return Err(c.err(
                iat,
                format!("the first point has index {idx}; TetGen numbering starts at 0 or 1"),
            ));
        }
        *base = idx;
    } else if idx != *base + i {
        return Err(c.err(
            iat,
            format!("point index {idx} out of sequence (expected {})", *base + i),
        ));
    }
    Ok(idx)
}

/// The `.ele` file: its header, then each tet (its point indices numbered from `base`) into
/// `asm`, and nothing after; returns the tet attributes.
fn read_tets(e: &mut Cursor, base: usize, asm: &mut Assembler) -> Result<TetAttributes, LoadError> {
    let m = e.count("the number of tetrahedra")?;
    let (kat, k) = e.expect("the number of nodes per tetrahedron")?;
    let kind = match k {
        b"4" => CellKind::Tetra,
        b"10" => CellKind::QuadraticTetra,
        _ => return Err(e.err(kat, "nodes per tetrahedron must be 4 or 10")),
    };
    let eattr = e.count("the number of tetrahedron attributes")?;
    // Each attribute takes at least two bytes per tet: reserve no more than the file holds.
    let cap = m.saturating_mul(eattr).min(e.remaining() / 2);
    e.budget
        .charge_items(cap, 8, || format!("{m} tetrahedra with {eattr} attributes"))?;
    let mut attrs = TetAttributes {
        count: eattr,
        values: Vec::with_capacity(cap),
    };
    let name = e.name;
    let mut ids = [0i64; 10];
    for i in 0..m {
        let (tat, _) = e.expect("a tetrahedron index")?;
        e.pos = tat;
        let tag: u64 = e.parse("a tetrahedron index")?;
        for id in ids.iter_mut().take(kind.vertex_count()) {
            *id = e.parse::<i64>("a point index")?.saturating_sub(base as i64);
        }
        let section = (eattr, "the tetrahedron attributes");
        read_attributes(e, section, ("tetrahedron", tag), &mut attrs.values)?;
        asm.cell(kind, &ids[..kind.vertex_count()], |msg| {
            LoadError::malformed(
                name,
                Location::Element { index: i, tag },
                format!("{msg} (0-based; the file numbers from {base})"),
            )
        })?;
    }
    if !e.at_end() {
        return Err(e.err(e.pos, format!("unexpected data after the {m} tetrahedra")));
    }
    Ok(attrs)
}
