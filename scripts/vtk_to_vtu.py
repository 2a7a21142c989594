#!/usr/bin/env python3
"""Converts a legacy VTK BINARY tet mesh (as in ../shared/data) to a zlib-compressed .vtu.

Usage: scripts/vtk_to_vtu.py IN.vtk OUT.vtu [--box X0 Y0 Z0 X1 Y1 Z1]

The data are copied bit for bit: float32 points and point arrays stay Float32, connectivity
becomes Int32, and the point and cell order is kept, so the mesh tetvr loads from OUT is the
one it loads from IN. With --box, only the cells whose points all lie in the box are kept, and
the points they use (in their order in IN). Only what the shared data sets hold is understood: POINTS float, CELLS,
CELL_TYPES, and POINT_DATA with one SCALARS float array and FIELD arrays of float. Each array is
one zlib block (level 9) in raw appended data. Standard library only.
"""

import sys
import zlib
from array import array


class Reader:
    """Big-endian legacy VTK: header lines, then binary runs addressed by counts."""

    def __init__(self, data):
        self.data, self.pos = data, 0

    def line(self):
        end = self.data.index(b"\n", self.pos)
        text = self.data[self.pos:end].decode("ascii").strip()
        self.pos = end + 1
        return text if text else self.line()

    def values(self, code, n):
        a = array(code)
        a.frombytes(self.data[self.pos:self.pos + n * a.itemsize])
        if len(a) != n:
            sys.exit(f"truncated at byte {self.pos}")
        a.byteswap()
        self.pos += n * a.itemsize
        return a


def read_vtk(path):
    r = Reader(open(path, "rb").read())
    while not r.line().startswith("DATASET"):
        pass
    words = r.line().split()
    assert words[0] == "POINTS" and words[2] == "float", words
    points = r.values("f", 3 * int(words[1]))
    words = r.line().split()
    assert words[0] == "CELLS", words
    cells = r.values("i", int(words[2]))
    words = r.line().split()
    assert words[0] == "CELL_TYPES", words
    types = r.values("i", int(words[1]))
    cells = split_cells(cells, len(types))
    words = r.line().split()
    assert words[0] == "POINT_DATA", words
    n = int(words[1])
    arrays = []
    while r.data[r.pos:].strip():
        words = r.line().split()
        if words[0] == "SCALARS":
            assert words[2] == "float", words
            assert r.line() == "LOOKUP_TABLE default"
            arrays.append((words[1], r.values("f", n)))
        elif words[0] == "FIELD":
            for _ in range(int(words[2])):
                name, comps, tuples, kind = r.line().split()
                assert (comps, tuples, kind) == ("1", str(n), "float"), words
                arrays.append((name, r.values("f", n)))
        else:
            sys.exit(f"unexpected section {words[0]}")
    return points, cells, types, arrays


def split_cells(cells, count):
    """Each cell's point list from VTK's `n i0 .. in-1` cell list."""
    out, i = [], 0
    for _ in range(count):
        k = cells[i]
        out.append(cells[i + 1:i + 1 + k])
        i += 1 + k
    return out


def crop(points, cells, types, arrays, lo, hi):
    """The cells with every point in the box [lo, hi], and the points they use, renumbered in
    their order in the input."""
    inside = [all(lo[j] <= points[3 * i + j] <= hi[j] for j in range(3))
              for i in range(len(points) // 3)]
    kept = [c for c, cell in enumerate(cells) if all(inside[v] for v in cell)]
    used = sorted({v for c in kept for v in cells[c]})
    new = {v: i for i, v in enumerate(used)}
    points = array("f", [points[3 * v + j] for v in used for j in range(3)])
    cells = [array("i", [new[v] for v in cells[c]]) for c in kept]
    types = array("i", [types[c] for c in kept])
    arrays = [(name, array("f", [values[v] for v in used])) for name, values in arrays]
    return points, cells, types, arrays


def block(a):
    """VTK's compressed block, UInt32 header: 1 block, its size, last size, compressed size."""
    raw = a.tobytes()
    packed = zlib.compress(raw, 9)
    return array("I", [1, len(raw), len(raw), len(packed)]).tobytes() + packed


def write_vtu(path, points, cells, types, arrays):
    assert sys.byteorder == "little"
    conn, offsets = array("i"), array("i")
    for cell in cells:
        conn.extend(cell)
        offsets.append(len(conn))
    np, nc = len(points) // 3, len(types)
    blobs, xml = [], []

    def entry(a, attrs):
        offset = sum(len(b) for b in blobs)
        blobs.append(block(a))
        xml.append(f'        <DataArray {attrs} format="appended" offset="{offset}"/>')

    xml.append(f'      <PointData Scalars="{arrays[0][0]}">')
    for name, values in arrays:
        entry(values, f'type="Float32" Name="{name}"')
    xml.append("      </PointData>\n      <Points>")
    entry(points, 'type="Float32" NumberOfComponents="3"')
    xml.append("      </Points>\n      <Cells>")
    entry(conn, 'type="Int32" Name="connectivity"')
    entry(offsets, 'type="Int32" Name="offsets"')
    entry(array("B", types), 'type="UInt8" Name="types"')
    xml.append("      </Cells>")
    head = (
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">\n'
        f'  <UnstructuredGrid>\n    <Piece NumberOfPoints="{np}" NumberOfCells="{nc}">\n'
        + "\n".join(xml)
        + '\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding="raw">\n   _'
    )
    with open(path, "wb") as f:
        f.write(head.encode("ascii"))
        for b in blobs:
            f.write(b)
        f.write(b"\n  </AppendedData>\n</VTKFile>\n")


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) not in (2, 9) or (len(args) == 9 and args[2] != "--box"):
        sys.exit(__doc__)
    mesh = read_vtk(args[0])
    if len(args) == 9:
        box = [float(x) for x in args[3:]]
        mesh = crop(*mesh, box[:3], box[3:])
    write_vtu(args[1], *mesh)
