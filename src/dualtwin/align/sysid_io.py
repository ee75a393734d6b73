"""`mujoco.sysid` parameter files as knob definitions, and fitted knobs written back in that format.

A ``mujoco.sysid`` user describes what to identify as a ``ParameterDict``, saved by
``ParameterDict.save_to_disk`` as YAML: one entry per parameter with ``name``, ``nominal``, ``min_value``,
``max_value``, ``value`` and ``frozen`` (arrays as lists). Alignment reads such a file (``sysid_params``):
every scalar, unfrozen parameter whose name is a knob of the target twin (or a glob of knobs) is fitted, within
the file's bounds. The twin's nominal value stays the knob's nominal (the file's ``nominal`` is the sysid
user's start, and the twin's model is what alignment starts from). Frozen parameters are skipped; a
multi-dimensional parameter or a name that matches no knob is refused with the reason.

After the fit, ``sysid_params.yaml`` holds the fitted physics knobs in the same format (``value`` the fitted
value), readable by ``ParameterDict.load_from_disk``. The file is written without importing ``mujoco.sysid``
(its optional dependencies need not be installed), with the field order ``save_to_disk`` uses.

In Python the same two directions work on objects: :func:`sysid_knobs` reads a ``ParameterDict`` (names and
bounds for ``AlignConfig(knobs=..., bounds=...)``), and :func:`to_parameter_dict` turns fitted knobs
(``AlignResult.knobs``) into a ``ParameterDict`` (this one needs ``mujoco.sysid`` and its optional
dependencies: the ``sysid`` extra).
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from dualtwin.align.writers import KnobFit
from dualtwin.artifacts import read_yaml, write_text
from dualtwin.errors import DualtwinError

SYSID_FILE = "sysid_params.yaml"


def _scalar(value: Any, where: str) -> float:
    items = value if isinstance(value, list) else [value]
    if len(items) != 1 or isinstance(items[0], list):
        raise DualtwinError(f"{where}: a {len(items)}-element parameter; alignment knobs are scalars (split it "
                            "into one parameter per knob)")
    try:
        number = float(items[0])
    except (TypeError, ValueError):
        raise DualtwinError(f"{where}: {items[0]!r} is not a number") from None
    if not math.isfinite(number):
        raise DualtwinError(f"{where}: {number} is not finite")
    return number


def read_sysid_params(path: Path) -> tuple[list[str], dict[str, tuple[float, float]]]:
    """The knob names (or globs) and bounds of a ``mujoco.sysid`` parameter file (frozen ones skipped).

    Raises:
        DualtwinError: Unreadable or malformed file, a non-scalar parameter, or bounds not below one another.
    """
    # The shared careful reader: binary data, a directory, duplicate keys (of which YAML would keep the last
    # silently) or deep nesting is one line naming the file, line and column.
    return _knobs_of(read_yaml(Path(path), "mujoco.sysid parameter file"), str(path))


def sysid_knobs(params: Any) -> tuple[list[str], dict[str, tuple[float, float]]]:
    """The knob names (or globs) and bounds of a ``mujoco.sysid.ParameterDict`` (frozen ones skipped), for
    ``AlignConfig(knobs=names, bounds=bounds)``; the same rules as a saved file (:func:`read_sysid_params`).

    Raises:
        DualtwinError: Not a ParameterDict, a non-scalar parameter, or bounds not below one another.
    """
    try:
        doc = {key: {"name": p.name, "min_value": _as_list(p.min_value), "max_value": _as_list(p.max_value),
                     "frozen": bool(p.frozen)} for key, p in params.items()}
    except (AttributeError, TypeError):
        raise DualtwinError(f"expected a mujoco.sysid ParameterDict, got {type(params).__name__}") from None
    return _knobs_of(doc, "ParameterDict")


def _as_list(value: Any) -> Any:
    return value.tolist() if hasattr(value, "tolist") else value


def _knobs_of(doc: Any, source: str) -> tuple[list[str], dict[str, tuple[float, float]]]:
    if not isinstance(doc, dict) or not doc:
        raise DualtwinError(f"{source}: expected a mujoco.sysid parameter file (a mapping of parameter names to "
                            "name/nominal/min_value/max_value/frozen), got something else")
    names: list[str] = []
    bounds: dict[str, tuple[float, float]] = {}
    for key, entry in doc.items():
        where = f"{source}: parameter {key!r}"
        if not isinstance(entry, dict) or not {"min_value", "max_value"} <= set(entry):
            raise DualtwinError(f"{where}: needs min_value and max_value")
        if entry.get("frozen", False):
            continue
        name = entry.get("name", key)
        if not isinstance(name, str) or not name.strip():
            raise DualtwinError(f"{where}: name must be a knob name or glob, got {name!r}")
        lower, upper = _scalar(entry["min_value"], where + " min_value"), _scalar(entry["max_value"], where + " max_value")
        if not lower < upper:
            raise DualtwinError(f"{where}: min_value {lower:g} is not below max_value {upper:g}")
        names.append(name)
        bounds[name] = (lower, upper)
    if not names:
        raise DualtwinError(f"{source}: every parameter is frozen; nothing to fit")
    return names, bounds


def sysid_document(knobs: Mapping[str, KnobFit]) -> dict[str, dict[str, Any]]:
    """Fitted knobs as a ``ParameterDict.save_to_disk`` document."""
    return {name: {"name": name, "nominal": [k.nominal], "min_value": [k.lower], "max_value": [k.upper],
                   "value": [k.fitted], "frozen": False} for name, k in knobs.items()}


def write_sysid_params(out_dir: Path, files: dict[str, str], knobs: Mapping[str, KnobFit]) -> None:
    """``sysid_params.yaml``: the fitted physics knobs in ``mujoco.sysid``'s parameter format."""
    write_text(out_dir / SYSID_FILE, yaml.safe_dump(sysid_document(knobs), default_flow_style=False, sort_keys=True))
    files["sysid_params"] = SYSID_FILE


def to_parameter_dict(knobs: Mapping[str, KnobFit]) -> Any:
    """Fitted knobs (``AlignResult.knobs``) as a ``mujoco.sysid.ParameterDict``: ``value`` the fitted value,
    ``nominal`` the twin's, the fit's bounds. No modifiers: the names are dualtwin knobs, which only the twin
    knows how to apply.

    Raises:
        DualtwinError: ``mujoco.sysid`` or its optional dependencies are not installed.
    """
    try:  # imported by name: a static import makes mypy analyse the untyped mujoco package
        sysid = importlib.import_module("mujoco.sysid")
    except ImportError:
        sysid = None
    if sysid is None or not hasattr(sysid, "ParameterDict"):
        raise DualtwinError("mujoco.sysid is not usable here: install the sysid extra (pip install 'dualtwin[sysid]')")
    params = sysid.ParameterDict()
    for name, k in knobs.items():
        parameter = sysid.Parameter(name, nominal=k.nominal, min_value=k.lower, max_value=k.upper)
        parameter.update_from_vector([k.fitted])
        params.add(parameter)
    return params
