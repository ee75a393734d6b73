"""Reading an MJCF file into a model: parse, check the sizes it asks for, compile; each failure one line.

A model may come from someone else (a downloaded robot, a generated one), so it is data: MuJoCo allocates what
its ``<size>``, height fields and textures ask for when it compiles, and ``nuser_body="1000000000"`` or a
100 000 × 100 000 height field made the process hang allocating gigabytes (or, under a memory limit, end in
"Caught an unknown exception!", a traceback). The limits below are far above what a robot model uses (the
bundled ones ask for none of these) and far below what would exhaust a machine.
"""

from __future__ import annotations

import re
from pathlib import Path

import mujoco

from dualtwin.errors import DualtwinError

__all__ = ["MAX_HFIELD_SAMPLES", "MAX_TEXTURE_PIXELS", "MAX_USER_NUMBERS", "check_sizes", "compile_spec",
           "load_spec"]

#: Most user numbers per element (``nuser_body``, ``nuser_jnt``...) and in ``nuserdata``.
MAX_USER_NUMBERS = 100_000
#: Most samples of one height field (``nrow`` × ``ncol``): 400 MB of floats.
MAX_HFIELD_SAMPLES = 100_000_000
#: Most pixels of one texture MuJoCo builds itself (``width`` × ``height``, × 6 for a cube or skybox): 256 MB
#: of RGBA.
MAX_TEXTURE_PIXELS = 64_000_000
#: Most bytes of the arena a model may reserve (``<size memory="..."/>``).
MAX_ARENA_BYTES = 16e9


def check_sizes(spec: mujoco.MjSpec, origin: str) -> None:
    """Refuse a model whose sizes exceed the limits above, naming the element and the size."""
    asks: list[tuple[str, float, float]] = [
        (f"size {name}", getattr(spec, name), MAX_USER_NUMBERS)
        for name in ("nuser_body", "nuser_jnt", "nuser_geom", "nuser_site", "nuser_cam", "nuser_tendon",
                     "nuser_actuator", "nuser_sensor", "nuserdata")
    ]
    asks.append(("size memory", spec.memory, MAX_ARENA_BYTES))
    for hfield in spec.hfields:
        asks.append((f"hfield {hfield.name!r} nrow x ncol", float(hfield.nrow) * float(hfield.ncol), MAX_HFIELD_SAMPLES))
    for texture in spec.textures:
        faces = 1 if texture.type == mujoco.mjtTexture.mjTEXTURE_2D else 6
        asks.append((f"texture {texture.name!r} width x height", float(texture.width) * float(texture.height) * faces,
                     MAX_TEXTURE_PIXELS))
    for what, value, limit in asks:
        if value > limit:
            raise DualtwinError(f"{origin}: the model asks for {what} = {value:g}, more than the {limit:g} dualtwin "
                                "compiles (MuJoCo would allocate it all)")


def compile_spec(spec: mujoco.MjSpec, origin: str) -> mujoco.MjModel:
    check_sizes(spec, origin)
    try:
        return spec.compile()
    except (ValueError, RuntimeError) as exc:  # (RuntimeError: MuJoCo's "Caught an unknown exception!")
        message = " ".join(str(exc).split())
        raise DualtwinError(f"{origin}: MJCF does not compile: {message}") from None


_HFIELD = re.compile(r"<hfield\b[^>]*>")
_ATTRIBUTE = re.compile(r"""\b(nrow|ncol)\s*=\s*["']\s*([^"']*)["']""")
_INCLUDE = re.compile(r"""<include\b[^>]*?\bfile\s*=\s*["']([^"']*)["']""")
#: Most files one model may include (directly or through included files) that the height-field check reads.
MAX_INCLUDED_FILES = 1000


def _check_hfields(path: Path, folder: Path | None = None, seen: set[Path] | None = None) -> None:
    # MuJoCo's parser itself allocates a height field's samples (11 GB for 100 000 x 100 000, before any compile),
    # so the <hfield> elements are read from the text first: the model file's own and those of the files it
    # <include>s, at any depth (MuJoCo finds an included file beside the file that includes it or in the main
    # model's folder: both are read)
    folder = path.parent if folder is None else folder
    seen = {path.resolve()} if seen is None else seen
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return  # MuJoCo's parser reports it
    for tag in _HFIELD.findall(text):
        sizes = dict(_ATTRIBUTE.findall(tag))
        try:
            samples = float(sizes.get("nrow", 0)) * float(sizes.get("ncol", 0))
        except ValueError:
            continue  # MuJoCo's parser reports it
        if samples > MAX_HFIELD_SAMPLES:
            raise DualtwinError(f"{path}: the model asks for {tag[:80]} = {samples:g} samples, more than the "
                                f"{MAX_HFIELD_SAMPLES:g} dualtwin compiles (MuJoCo would allocate it all)")
    for name in _INCLUDE.findall(text):
        for base in (path.parent, folder):
            try:
                included = (base / name).resolve()
            except (OSError, ValueError, RuntimeError):  # Python 3.11 raises RuntimeError for a loop of links
                continue  # (a NUL, a loop of links) MuJoCo's parser reports it
            if included in seen or len(seen) >= MAX_INCLUDED_FILES:
                continue  # (an include cycle is MuJoCo's error to report)
            seen.add(included)
            _check_hfields(included, folder, seen)


def load_spec(path: Path) -> mujoco.MjSpec:
    if not Path(path).is_file():
        raise DualtwinError(f"{path}: model file not found")
    if not Path(path).suffix:
        # MuJoCo picks its decoder by the extension: without one it prints two warnings of its own on stderr
        # before its error, where the command line promises one line
        raise DualtwinError(f"{path}: a model file needs its extension (.xml): MuJoCo chooses its parser by it")
    _check_hfields(Path(path))
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        message = " ".join(str(exc).split())
        raise DualtwinError(f"{path}: MJCF does not parse: {message}") from None
