//! TetGen `.node`/`.ele` writer for the fuzz model: 0- or 1-based, with point attributes (the
//! arrays), boundary markers, element attributes and comments.

use arbitrary::Arbitrary;

use crate::Mesh;

#[derive(Arbitrary, Clone, Copy, Debug)]
pub struct Style {
    pub one_based: bool,
    pub markers: bool,
    /// Attributes per element (0 to 3).
    pub element_attributes: u8,
    /// Nodes per tet in the `.ele` header (4 or, with `true`, 10).
    pub quadratic: bool,
    pub comments: bool,
}

/// The mesh as a `(node, ele)` pair.
pub fn write(mesh: &Mesh, style: Style) -> (Vec<u8>, Vec<u8>) {
    let base = style.one_based as i64;
    let coords = mesh.coords();
    let attrs: Vec<Vec<f64>> = mesh
        .arrays
        .iter()
        .map(|a| mesh.array_values(a, coords.len(), 1))
        .collect();
    let np = mesh.lies().points.map_or(coords.len(), |n| n as usize);
    let mut node = format!("{np} 3 {} {}\n", attrs.len(), style.markers as u8);
    if style.comments {
        node.push_str(&format!("# {}\n", mesh.title.text().replace('\n', " ")));
    }
    for (i, p) in coords.iter().enumerate() {
        node.push_str(&format!(
            "{} {:e} {:e} {:e}",
            i as i64 + base,
            p[0],
            p[1],
            p[2]
        ));
        for a in &attrs {
            node.push_str(&a.get(i).map_or(String::new(), |v| format!(" {v:e}")));
        }
        node.push_str(if style.markers { " 1\n" } else { "\n" });
    }
    let nattr = style.element_attributes % 4;
    let per = if style.quadratic { 10 } else { 4 };
    let nc = mesh.lies().cells.map_or(mesh.cells.len(), |n| n as usize);
    let mut ele = format!("{nc} {per} {nattr}\n");
    for (i, cell) in mesh.cells.iter().enumerate() {
        ele.push_str(&format!("{}", i as i64 + base));
        for v in mesh.cell_verts(cell) {
            ele.push_str(&format!(" {}", v + base));
        }
        (0..nattr).for_each(|k| ele.push_str(&format!(" {k}")));
        ele.push('\n');
    }
    let mut ele = ele.into_bytes();
    ele.extend_from_slice(&mesh.tail);
    (node.into_bytes(), ele)
}

/// The raw target's input split into `.node` and `.ele` at the first line `#ele`.
pub fn split_pair(data: &[u8]) -> (&[u8], &[u8]) {
    const MARK: &[u8] = b"\n#ele\n";
    match data.windows(MARK.len()).position(|w| w == MARK) {
        Some(at) => (&data[..at + 1], &data[at + MARK.len()..]),
        None => (data, data),
    }
}
