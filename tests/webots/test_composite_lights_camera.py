"""Composite: a Camera's image of a white box lit by the world's lights.

The twin's camera drew its PointLights as MuJoCo "point" lights, which MuJoCo's renderer draws as nothing.

Expected values are relative: every image is compared with a control world drawn by the same renderer, the
same light at top level at the world place worked out by hand (the same pixel), or no light (MuJoCo's headlight
alone, the darker pixel).
"""

from __future__ import annotations

import warnings

import numpy as np

from dualtwin.webots.camera import Camera
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.protos import load_world_text

# The robot at (0.5, 0, 0) turned a quarter turn about z: its x axis (the camera's view) is the world's +y, its y
# axis the world's -x. The white box's near face is at y = 1.9, straight ahead of the camera.
ROBOT_AT = "0.5 0 0"
# Dim lamps (attenuation 1/d²) so that the box stays below white: a brighter pixel means more light.
DIM = "attenuation 0 0 1 intensity 0.01"  # 0.01/0.4² = 0.0625 on the face 0.4 m away


def _world(top: str, carried: str, robot_at: str = ROBOT_AT) -> str:
    return f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 }}
{top}
Solid {{ translation 0.5 2 0 children [ Shape {{ geometry Box {{ size 1 0.2 1 }} }} ] }}
DEF ROBOT Robot {{
  translation {robot_at} rotation 0 0 1 1.5707963267948966
  children [ Camera {{ name "cam" width 16 height 16 }} {carried} ]
  controller "<extern>"
  supervisor TRUE
}}
"""


def _open(text: str) -> tuple[Supervisor, Camera]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    cam = sup.getDevice("cam")
    assert isinstance(cam, Camera)
    cam.enable(16)
    return sup, cam


def _box_bgr(sup: Supervisor, cam: Camera) -> np.ndarray:
    """The mean B, G, R bytes of the image's centre (on the box's near face) after one more step."""
    sup.step(16)
    image = np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(16, 16, 4)
    return np.asarray(image[6:10, 6:10, :3], dtype=float).mean(axis=(0, 1))


def _pixel(text: str) -> np.ndarray:
    return _box_bgr(*_open(text))


def test_a_point_light_lights_the_box() -> None:
    # at top level, 0.4 m in front of the face's centre: the pixel brighter than by MuJoCo's headlight alone
    dark = _pixel(_world("", ""))
    lit = _pixel(_world(f"PointLight {{ location 0.5 1.5 0 {DIM} }}", ""))
    assert (lit > dark + 5).all(), (lit, dark)
