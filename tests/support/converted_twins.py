"""Both twins of one world: the world written to a folder, converted, its binding written, and the Webots twin
(our ODE runtime) and the MuJoCo twin (the converted model) built from that binding, closed after the block.
Used by the converter's fidelity tests (initial velocities, coupled motors, sensor resolution)."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from pathlib import Path

from dualtwin.convert import Conversion, convert_world
from dualtwin.robots.binding import load_binding
from dualtwin.twins import Twin, make_twin

__all__ = ["converted_twins", "world_text"]


def world_text(scene: str, info: str = "") -> str:
    """A R2023b world: ``WorldInfo { info }`` then ``scene``."""
    return f"#VRML_SIM R2023b utf8\nWorldInfo {{ {info} }}\n{scene}\n"


@contextlib.contextmanager
def converted_twins(text: str, folder: Path, period: float,
                    robot: str | None = None) -> Iterator[tuple[Conversion, Twin, Twin]]:
    """(conversion, Webots twin, MuJoCo twin) of the world ``text`` (its robot ``robot``: DEF or name, may be left out
    when it has one), stepped every ``period`` seconds."""
    world = folder / "world.wbt"
    world.write_text(text, encoding="utf-8")
    conv = convert_world(world, robot)
    conv.write(folder / "model.xml", folder / "binding.yaml")
    binding = load_binding(folder / "binding.yaml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the world's build warnings (coupled limits, no DEF...) are not tested here
        webots = make_twin("webots", binding, period)
    mujoco_twin = make_twin("mujoco", binding, period)
    try:
        yield conv, webots, mujoco_twin
    finally:
        webots.close()
        mujoco_twin.close()
