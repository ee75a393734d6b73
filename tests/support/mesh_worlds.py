"""Mesh files written by tests (binary STL, OBJ) and the Webots project folder a world reading them lives in."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np

# The six faces of a box as outward, counter-clockwise quads of the corners (x, y, z each -1 or +1, x slowest).
_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))


def box_mesh(size: Sequence[float], centre: Sequence[float] = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """The 8 corners and 12 outward-wound triangles of an axis-aligned box of ``size`` centred at ``centre``."""
    corners = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    vertices = corners * np.asarray(size, dtype=float) / 2 + np.asarray(centre, dtype=float)
    triangles = [(q[0], q[1], q[2]) for q in _QUADS] + [(q[0], q[2], q[3]) for q in _QUADS]
    return vertices, np.array(triangles, dtype=np.int64)


def write_stl(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> Path:
    """A binary STL file of the triangles (float32 coordinates, zero normals as many exporters write)."""
    out = bytearray(80) + struct.pack("<I", len(triangles))
    for tri in triangles:
        out += struct.pack("<3f", 0.0, 0.0, 0.0)
        for i in tri:
            out += struct.pack("<3f", *(float(v) for v in vertices[i]))
        out += b"\0\0"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(bytes(out))
    return path


def write_obj(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> Path:
    """A Wavefront OBJ file of the triangles (one object, no material)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles.tolist()]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path


def write_world(project: Path, text: str, name: str = "mesh.wbt") -> Path:
    """The world file ``project/worlds/<name>``: its relative mesh urls (``../meshes/...``) resolve in
    ``project``, as in a Webots project folder."""
    path = project / "worlds" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path
