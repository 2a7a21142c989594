#!/usr/bin/env python3
"""Writes the Gmsh fixtures of tests/io.rs with the `gmsh` Python package (pip install gmsh),
as Gmsh itself writes them: a mesh saved, then post-processing views appended to the same file
with gmsh.view.write(..., append=True), which repeats the mesh blocks ($MeshFormat, $Entities,
$Nodes, $Elements) before each view's data.

Usage: python3 scripts/gmsh_fixtures.py [OUTDIR]   (default tests/corpus/valid)

Files (a unit cube of a few dozen tets, with its boundary triangles):
  views22.msh, views41.msh  MSH 2.2 and 4.1: views 'temperature' (node scalar x + 2y + 3z),
                            'displacement' (node vector (x, y, z) / 10) and 'pressure' (element
                            scalar: the tet's tag), in that order.
  cellfirst41.msh           MSH 4.1 whose first view is the element view 'pressure'.
  views22b.msh, views41b.msh  views22.msh and views41.msh in binary.
"""
import sys

import gmsh

OUT = sys.argv[1] if len(sys.argv) > 1 else "tests/corpus/valid"


def mesh():
    gmsh.model.add("cube")
    gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", 2.0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0)
    gmsh.model.mesh.generate(3)


def node_view(name, f, components):
    tags, coords, _ = gmsh.model.mesh.getNodes()
    data = [f(coords[3 * i : 3 * i + 3]) for i in range(len(tags))]
    v = gmsh.view.add(name)
    gmsh.view.addModelData(v, 0, "cube", "NodeData", tags, data, numComponents=components)
    return v


def element_view(name):
    types, tags, _ = gmsh.model.mesh.getElements(3)
    tets = [int(t) for t in tags[list(types).index(4)]]
    v = gmsh.view.add(name)
    gmsh.view.addModelData(v, 0, "cube", "ElementData", tets, [[float(t)] for t in tets])
    return v


def write(path, version, views, binary=0):
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", binary)
    gmsh.option.setNumber("PostProcessing.Binary", binary)
    gmsh.write(path)
    for v in views:
        gmsh.view.write(v, path, append=True)


def main():
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    mesh()
    t = node_view("temperature", lambda p: [p[0] + 2 * p[1] + 3 * p[2]], 1)
    d = node_view("displacement", lambda p: [p[0] / 10, p[1] / 10, p[2] / 10], 3)
    p = element_view("pressure")
    # Views are saved in the version set for meshes (PostProcessing.SaveMesh keeps the mesh).
    write(f"{OUT}/views22.msh", 2.2, [t, d, p])
    write(f"{OUT}/views41.msh", 4.1, [t, d, p])
    write(f"{OUT}/cellfirst41.msh", 4.1, [p, t])
    write(f"{OUT}/views22b.msh", 2.2, [t, d, p], binary=1)
    write(f"{OUT}/views41b.msh", 4.1, [t, d, p], binary=1)
    gmsh.finalize()


if __name__ == "__main__":
    main()
