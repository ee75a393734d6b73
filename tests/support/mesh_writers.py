"""Mesh files written by tests: closed boxes as binary STL, Wavefront OBJ and COLLADA, wound outwards."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

Vec = tuple[float, float, float]

# the 12 outward triangles of a box whose corner k is (bit 2, bit 1, bit 0) of k along (x, y, z)
BOX_FACES = ((0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3))


def box_corners(lo: Sequence[float], hi: Sequence[float]) -> list[Vec]:
    return [(hi[0] if k & 4 else lo[0], hi[1] if k & 2 else lo[1], hi[2] if k & 1 else lo[2]) for k in range(8)]


def box_triangles(lo: Sequence[float], hi: Sequence[float]) -> list[tuple[Vec, Vec, Vec]]:
    c = box_corners(lo, hi)
    return [(c[a], c[b], c[d]) for a, b, d in BOX_FACES]


def binary_stl(path: Path, triangles: Sequence[Sequence[Sequence[float]]]) -> Path:
    with path.open("wb") as out:
        out.write(b"\0" * 80 + struct.pack("<I", len(triangles)))
        for tri in triangles:
            out.write(struct.pack("<3f", 0, 0, 0))
            for vertex in tri:
                out.write(struct.pack("<3f", *vertex))
            out.write(b"\0\0")
    return path


def ascii_stl(triangles: Sequence[Sequence[Sequence[float]]], name: str = "part") -> str:
    facets = "".join("facet normal 0 0 0\nouter loop\n" + "".join(f"vertex {x!r} {y!r} {z!r}\n" for x, y, z in tri)
                     + "endloop\nendfacet\n" for tri in triangles)
    return f"solid {name}\n{facets}endsolid {name}\n"


def box_obj(boxes: Sequence[tuple[str, Sequence[float], Sequence[float]]]) -> str:
    """An OBJ with one object (``o name``) per ``(name, lo, hi)`` box, each face a quad (two triangles)."""
    lines, base = [], 0
    quads = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))
    for name, lo, hi in boxes:
        lines.append(f"o {name}")
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in box_corners(lo, hi)]
        lines += ["f " + " ".join(str(base + i + 1) for i in quad) for quad in quads]
        base += 8
    return "\n".join(lines) + "\n"


def box_collada(lo: Sequence[float], hi: Sequence[float], *, meter: float, translate: Sequence[float]) -> str:
    """A COLLADA file with one box (coordinates in the file's unit, ``meter`` metres each) in a node moved by
    ``translate`` (file units)."""
    corners = " ".join(f"{v!r}" for c in box_corners(lo, hi) for v in c)
    index = " ".join(str(i) for face in BOX_FACES for i in face)
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="unit" meter="{meter!r}"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="box-mesh" name="box">
      <mesh>
        <source id="p"><float_array id="pa" count="24">{corners}</float_array>
          <technique_common><accessor source="#pa" count="8" stride="3">
            <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
          </accessor></technique_common></source>
        <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
        <triangles count="12"><input semantic="VERTEX" source="#v" offset="0"/><p>{index}</p></triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="Scene">
      <node id="moved" name="moved"><translate>{" ".join(f"{v!r}" for v in translate)}</translate>
        <instance_geometry url="#box-mesh"/></node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
"""
