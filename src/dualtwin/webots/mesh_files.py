"""The triangles of a Webots ``Mesh`` node's file: STL, Wavefront OBJ and COLLADA, as Webots reads them.

Webots (R2023b) loads a ``Mesh`` url through Assimp and merges every mesh of the file into one triangle set:
it walks the file's node tree, applies each node's accumulated transform to its meshes' vertices, and keeps a
mesh only if the node's ``name`` field is empty or equals the mesh's name, and ``materialIndex`` is -1 or
equals the mesh's material index. Polygons are triangulated. ``ccw FALSE`` reverses the winding. The result is
used as ODE's triangle mesh in a ``boundingObject`` (``dCreateTriMesh``, mass by ``dMassSetTrimesh``) and as
the drawn shape elsewhere.

What we read, format by format (a file is data from a world we did not write: sizes are capped, and a file
that cannot be read gives one :class:`MeshFileError` line, never a traceback):

- **STL**, binary or ASCII (an ASCII file starts with ``solid`` and has ``facet`` lines): its triangles; the
  ASCII ``solid`` name is the mesh's name; material index 0.
- **OBJ**: ``v`` and ``f`` lines (``v/vt/vn`` forms, negative indices counting back from the last vertex,
  polygons cut into triangles that cover them, concave ones too); a face's names are its current ``o`` object
  and ``g`` group names, its material index is the order in which its ``usemtl`` name was first used (our
  reading of Assimp's numbering; the ``.mtl`` file is not read). Faces before any ``usemtl`` have index 0
  and shift the others by one, as Assimp's default material does.
- **COLLADA** (``.dae``, through pycollada): every geometry instanced in the file's scene, with its node
  transforms, scaled by the asset's ``unit meter``; a mesh's name is its geometry's ``name`` or ``id``, its
  material index the position of its material in ``library_materials``. The ``up_axis`` is not applied:
  coordinates are taken as written (Webots' worlds are Z-up, the usual up axis of the files robots use).

Where a ``Mesh`` url points (:func:`locate_mesh`), as Webots resolves it, with one restriction of ours: a world
is data, so its urls are confined.

- ``http(s)://`` and ``webots://`` urls (and relative urls inside a remote PROTO, joined to its url) are read
  from ``$WEBOTS_HOME`` for ``webots://`` when it holds the file, else from the PROTO cache, downloaded into it
  like a PROTO unless downloads are off (``dualtwin webots fetch`` fills the cache beforehand);
- a relative url is joined to the folder of the file that wrote the node (the world, or a local PROTO file);
  the result must lie inside that file's project, the folder above the file's own folder (the folder holding
  ``worlds/`` and ``protos/``); an absolute local path or one that leaves the project is refused.
"""

from __future__ import annotations

import functools
import os
import re
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.webots.nodes import Node
from dualtwin.webots.polygons import triangulate_polygon
from dualtwin.webots.proto_cache import (
    FetchError,
    ProtoCache,
    default_cache_root,
    is_remote,
    remote_url,
    webots_assets_dir,
)

__all__ = ["EXTENSIONS", "MAX_FILE_BYTES", "MAX_TRIANGLES", "MeshFileError", "TriangleMesh", "locate_mesh",
           "read_mesh", "read_mesh_node", "url_extension"]

#: The extensions read here (lower case); Webots' other Assimp formats are refused with a clear line.
EXTENSIONS = (".stl", ".obj", ".dae")
#: A mesh file larger than this is refused: larger than any robot part's mesh, small enough to parse in seconds.
MAX_FILE_BYTES = 64 * 1024 * 1024
#: Triangles kept from one file at most (Webots warns above 100,000 vertices per mesh; this is a hard cap).
MAX_TRIANGLES = 2_000_000


class MeshFileError(DualtwinError):
    """A mesh file that cannot be read (missing, too large, malformed, or of an unsupported format)."""


@dataclass(frozen=True)
class TriangleMesh:
    """Triangles in the Mesh node's frame (metres): ``vertices`` (n, 3) float64, ``triangles`` (m, 3) int32."""

    vertices: np.ndarray
    triangles: np.ndarray

    def __post_init__(self) -> None:
        self.vertices.setflags(write=False)
        self.triangles.setflags(write=False)


@dataclass
class _Part:
    """One mesh of a file before selection: its triangles, names and material index."""

    vertices: np.ndarray
    triangles: np.ndarray
    names: tuple[str, ...]
    material: int


def locate_mesh(node: Node, cache: ProtoCache | None = None) -> Path:
    """The local file of a ``Mesh`` node's first url (see the module's text for the rules).

    ``cache``: where remote urls are looked up (default: the user's PROTO cache, made on first need).

    Raises:
        MeshFileError: no url, a url outside the project, or a remote file that cannot be had.
    """
    where = _where(node)
    url = _first_url(node)
    if not url:
        raise MeshFileError(f"{where}: {node.type_name} has no url")
    origin = node.location.file.removesuffix("[generated]") if node.location is not None else ""
    try:
        remote = remote_url(url, origin if is_remote(origin) else None)
    except FetchError as exc:
        raise MeshFileError(f"{where}: {exc}") from None
    if remote is not None:
        home = os.environ.get("WEBOTS_HOME", "")
        if url.startswith("webots://") and home:
            rel = Path(url[len("webots://"):].lstrip("/"))
            if ".." not in rel.parts and (Path(home) / rel).is_file():
                return Path(home) / rel
        try:
            return (cache if cache is not None else _default_cache()).get(remote, asset=True)
        except FetchError as exc:
            raise MeshFileError(f"{where}: mesh {url!r}: {exc}") from None
    local = Path(url[len("file://"):] if url.startswith("file://") else url)
    if local.is_absolute() or not origin or origin.startswith("<"):
        raise MeshFileError(f"{where}: mesh url {url!r} is not read: only urls relative to the world or PROTO "
                            "file (inside its project folder) and remote urls are")
    folder = Path(origin).resolve().parent
    project = folder.parent
    path = (folder / local).resolve()
    if not path.is_relative_to(project):
        raise MeshFileError(f"{where}: mesh url {url!r} leads outside the project folder {project}; not read")
    return path


def _default_cache() -> ProtoCache:
    """The user's PROTO cache as the environment names it now (its folder, mirror and offline switch): one
    :class:`ProtoCache` per such setting, so a process whose environment changes reads the cache it names."""
    env = os.environ
    return _cache_for(str(default_cache_root()), str(webots_assets_dir()), env.get("DUALTWIN_PROTO_MIRROR", ""),
                      env.get("DUALTWIN_PROTO_OFFLINE", ""))


@functools.lru_cache(maxsize=8)
def _cache_for(root: str, assets: str, mirror: str, offline: str) -> ProtoCache:
    del assets, mirror, offline  # the key: ProtoCache reads them from the environment
    return ProtoCache(Path(root))


def read_mesh_node(node: Node, cache: ProtoCache | None = None) -> TriangleMesh:
    """The triangles of a ``Mesh`` node: its file located by :func:`locate_mesh`, read by :func:`read_mesh` with
    the node's ``name``, ``materialIndex`` and ``ccw``. A ``CadShape`` (no ``name`` or ``materialIndex``
    field) gets every mesh of its file.

    Raises:
        MeshFileError: as both functions (the message names the node's place in its file).
    """
    path = locate_mesh(node, cache)
    try:
        return read_mesh(path, str(node.fields.get("name", "") or ""), int(node.fields.get("materialIndex", -1)),
                         bool(node.fields.get("ccw", True)), extension=url_extension(node))
    except MeshFileError as exc:
        raise MeshFileError(f"{_where(node)}: {exc}") from None


def url_extension(node: Node) -> str:
    """The file extension (lower case, with its dot) of a Mesh's or CadShape's first url, which names its format:
    a remote file sits in the PROTO cache under a name without one."""
    url = _first_url(node)
    return Path(url.split("?", 1)[0].split("#", 1)[0]).suffix.lower() if url else ""


def _first_url(node: Node) -> str:
    """The first non-empty entry of the node's ``url`` field, the one Webots reads ("" without one)."""
    return next((str(u) for u in (node.fields.get("url") or []) if str(u)), "")


def _where(node: Node) -> str:
    return str(node.location) if node.location is not None else node.type_name


def read_mesh(path: str | os.PathLike[str], name: str = "", material_index: int = -1, ccw: bool = True, *,
              extension: str | None = None) -> TriangleMesh:
    """The triangles Webots makes of the mesh file ``path`` for a ``Mesh`` node's ``name``, ``materialIndex``
    and ``ccw`` fields. Read once per file version (size and modification time) and selection. ``extension``
    names the format when the path's own does not (a cached download: :func:`url_extension`).

    Raises:
        MeshFileError: unreadable, too large, malformed, unsupported format, or nothing selected.
    """
    file = Path(path)
    try:
        stat = file.stat()
    except OSError as exc:
        raise MeshFileError(f"{file}: cannot read the mesh file ({exc.strerror or exc})") from None
    ext = (extension if extension is not None else file.suffix).lower()
    return _read_cached(str(file), ext, stat.st_size, stat.st_mtime_ns, name, int(material_index), bool(ccw))


@functools.lru_cache(maxsize=64)
def _read_cached(path: str, ext: str, size: int, mtime_ns: int, name: str, material_index: int,
                 ccw: bool) -> TriangleMesh:
    del mtime_ns  # part of the cache key only: an edited file is read again
    file = Path(path)
    if ext not in EXTENSIONS:
        raise MeshFileError(f"{file}: mesh format {ext or '(no extension)'!r} is not read here "
                            f"(supported: {', '.join(EXTENSIONS)})")
    if size > MAX_FILE_BYTES:
        raise MeshFileError(f"{file}: mesh file of {size} bytes is larger than the {MAX_FILE_BYTES}-byte limit")
    try:
        data = file.read_bytes()
    except OSError as exc:
        raise MeshFileError(f"{file}: cannot read the mesh file ({exc.strerror or exc})") from None
    try:
        parts = {".stl": _stl, ".obj": _obj, ".dae": _collada}[ext](data)
    except MeshFileError as exc:
        raise MeshFileError(f"{file}: {exc}") from None
    except (ValueError, IndexError, KeyError, TypeError, struct.error, UnicodeDecodeError, AttributeError) as exc:
        raise MeshFileError(f"{file}: malformed {ext[1:].upper()} file ({type(exc).__name__}: {exc})") from None
    kept = [p for p in parts if (not name or name in p.names) and (material_index < 0 or p.material == material_index)]
    if not kept:
        what = []
        if name:
            what.append(f"name {name!r}")
        if material_index >= 0:
            what.append(f"materialIndex {material_index}")
        raise MeshFileError(f"{file}: no triangles" + (f" for {' and '.join(what)}" if what else ""))
    vertices, triangles, offset = [], [], 0
    for part in kept:
        vertices.append(part.vertices)
        triangles.append(part.triangles + offset)
        offset += len(part.vertices)
    v = np.ascontiguousarray(np.concatenate(vertices), dtype=np.float64)
    t = np.ascontiguousarray(np.concatenate(triangles), dtype=np.int32)
    if len(t) > MAX_TRIANGLES:
        raise MeshFileError(f"{file}: {len(t)} triangles, more than the {MAX_TRIANGLES} read at most")
    if not np.all(np.isfinite(v)):
        raise MeshFileError(f"{file}: a vertex is not a finite number")
    if not ccw:
        t = np.ascontiguousarray(t[:, ::-1])
    return TriangleMesh(v, t)


def _stl(data: bytes) -> list[_Part]:
    head = data[:512].lstrip().lower()
    if head.startswith(b"solid") and b"facet" in data[:4096].lower():
        return _stl_ascii(data.decode("ascii", errors="replace"))
    if len(data) < 84:
        raise MeshFileError("STL file shorter than its 84-byte header")
    (count,) = struct.unpack_from("<I", data, 80)
    if len(data) < 84 + 50 * count:
        raise MeshFileError(f"binary STL announces {count} triangles but holds {(len(data) - 84) // 50}")
    if count > MAX_TRIANGLES:
        raise MeshFileError(f"{count} triangles, more than the {MAX_TRIANGLES} read at most")
    records = np.frombuffer(data, dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]),
                            count=count, offset=84)
    vertices = records["v"].reshape(-1, 3).astype(np.float64)
    return [_Part(vertices, np.arange(len(vertices), dtype=np.int64).reshape(-1, 3), ("",), 0)]


_FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_VERTEX = re.compile(rf"^\s*vertex\s+({_FLOAT})\s+({_FLOAT})\s+({_FLOAT})\s*$", re.MULTILINE | re.IGNORECASE)


def _stl_ascii(text: str) -> list[_Part]:
    first = text.lstrip().splitlines()[0] if text.strip() else ""
    solid = first.split(None, 1)[1].strip() if len(first.split(None, 1)) > 1 else ""
    coords = np.array(_VERTEX.findall(text), dtype=np.float64).reshape(-1, 3)
    if len(coords) == 0 or len(coords) % 3:
        raise MeshFileError(f"ASCII STL with {len(coords)} vertex lines (not a whole number of triangles)")
    return [_Part(coords, np.arange(len(coords), dtype=np.int64).reshape(-1, 3), (solid,), 0)]


def _obj(data: bytes) -> list[_Part]:
    positions: list[tuple[float, float, float]] = []
    # faces grouped by (object, group, material index), in first-seen order
    groups: dict[tuple[str, str, int], list[list[int]]] = {}
    materials: dict[str, int] = {}
    obj_name = group_name = ""
    material = 0
    untextured_first = False  # faces before any usemtl take index 0 (Assimp's default material)
    for raw in data.decode("utf-8", errors="replace").splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        key, _, rest = line.partition(" ")
        if key == "v":
            xyz = rest.split()
            positions.append((float(xyz[0]), float(xyz[1]), float(xyz[2])))
        elif key == "f":
            polygon = []
            for item in rest.split():
                index = int(item.split("/", 1)[0])
                # 1-based, or negative (relative to the last vertex); checked here because an index too large
                # for int64 (a hostile file) made the triangle array raise OverflowError, a traceback
                if index == 0 or abs(index) > MAX_FILE_BYTES:
                    raise MeshFileError(f"OBJ face refers to vertex {index}, which cannot exist: {raw.strip()[:80]!r}")
                polygon.append(index - 1 if index > 0 else len(positions) + index)
            if len(polygon) < 3:
                raise MeshFileError(f"OBJ face with {len(polygon)} vertices: {raw.strip()!r}")
            if not materials:
                untextured_first = True
            groups.setdefault((obj_name, group_name, material), []).append(polygon)
        elif key == "o":
            obj_name = rest.strip()
        elif key == "g":
            group_name = rest.strip()
        elif key == "usemtl":
            label = rest.strip()
            if label not in materials:
                materials[label] = len(materials) + (1 if untextured_first else 0)
            material = materials[label]
    if not positions:
        raise MeshFileError("OBJ file without vertices")
    vertices = np.array(positions, dtype=np.float64)
    parts = []
    for (obj, group, mat), polygons in groups.items():
        if any(min(p) < 0 or max(p) >= len(positions) for p in polygons):
            raise MeshFileError("OBJ face refers to a vertex that does not exist")
        # each face cut into triangles that cover it, a concave one too (as an IndexedFaceSet's faces)
        triangles = [t for p in polygons for t in triangulate_polygon(positions, p)]
        tri = np.array(triangles, dtype=np.int64)
        used, local = np.unique(tri, return_inverse=True)
        parts.append(_Part(vertices[used], local.reshape(-1, 3), (obj, group), mat))
    if not parts:
        raise MeshFileError("OBJ file without faces")
    return parts


def _collada(data: bytes) -> list[_Part]:
    import io

    import collada  # pycollada, only for .dae files

    ignore = [collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PendingDeprecationWarning)  # pycollada's use of numpy.matrix
            document = collada.Collada(io.BytesIO(data), ignore=ignore)
    except collada.common.DaeError as exc:
        raise MeshFileError(f"malformed COLLADA file ({exc})") from None
    except Exception as exc:  # noqa: BLE001 - the XML parser's own errors (expat, lxml) vary by backend
        raise MeshFileError(f"malformed COLLADA file ({type(exc).__name__}: {exc})") from None
    unit = float(document.assetInfo.unitmeter or 1.0) if document.assetInfo is not None else 1.0
    material_order = {m.id: i for i, m in enumerate(document.materials)}
    scene = document.scene
    if scene is None:
        raise MeshFileError("COLLADA file without a scene")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PendingDeprecationWarning)  # pycollada's use of numpy.matrix
        return _collada_parts(collada, scene, unit, material_order)


def _collada_parts(collada: Any, scene: Any, unit: float, material_order: dict[str, int]) -> list[_Part]:
    parts = []
    for bound in scene.objects("geometry"):
        names = tuple(n for n in (bound.original.name, bound.original.id) if n)
        for primitive in bound.primitives():
            if isinstance(primitive, (collada.polylist.BoundPolylist, collada.polygons.BoundPolygons)):
                primitive = primitive.triangleset()
            if not isinstance(primitive, collada.triangleset.BoundTriangleSet) or primitive.vertex is None:
                continue  # lines and points have no triangles
            index = np.asarray(primitive.vertex_index, dtype=np.int64).reshape(-1, 3)
            if len(index) == 0:
                continue
            material = primitive.material
            mat_id = str(getattr(material, "id", ""))
            parts.append(_Part(np.asarray(primitive.vertex, dtype=np.float64) * unit, index, names,
                               material_order.get(mat_id, 0)))
    return parts
