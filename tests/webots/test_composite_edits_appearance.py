"""A supervisor's edit of a Shape's colour meeting the devices that see colours, and DEF/USE: an infra-red
DistanceSensor weighs the red of what its ray hits at each sample (D §1: "red from material ... at the hit point"), and
a Camera draws the Shape in its colour, so both follow an edit of a PBRAppearance's baseColor from the next sample or
image; a DEF'd appearance is one node with its USEs (the twin's DEF/USE rule, docs/webots-coverage.md Solid row), so
the Shapes that USE it change too. ``simulationReset`` restores the colour (S §6: all fields).

D = shared/reference/webots-devices.md, S = webots-on-ode.md. Expected values are hand computations from D §1; each
test has its control (the same run without the edit)."""

from __future__ import annotations

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

STEP = 8

# two white boxes 0.2 m wide, 1 m ahead of two infra-red sensors (axis +x); the second box's Shape USEs the first's
# appearance. A Camera looks along +x at the first box.
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {STEP} gravity 0 }}
Solid {{ translation 1 0 0 children [ Shape {{
  appearance DEF PAINT PBRAppearance {{ baseColor 1 1 1 roughness 1 metalness 0 }} geometry Box {{ size 0.2 0.2 0.2 }} }} ] }}
Solid {{ translation 1 2 0 name "second" children [ Shape {{
  appearance USE PAINT geometry Box {{ size 0.2 0.2 0.2 }} }} ] }}
Robot {{ supervisor TRUE children [
  DistanceSensor {{ name "ir0" type "infra-red" lookupTable [ 0 0 0, 2 2 0 ] }}
  DistanceSensor {{ name "ir1" translation 0 2 0 type "infra-red" lookupTable [ 0 0 0, 2 2 0 ] }}
  Camera {{ name "camera" width 8 height 8 }}
] }}
"""


def _open() -> Supervisor:
    sup = quiet_supervisor(WORLD)
    for name in ("ir0", "ir1", "camera"):
        sup.getDevice(name).enable(STEP)
    return sup


def _reflection(red: float, roughness: float = 1.0) -> float:
    return 0.2 + 0.8 * red * (1.0 - 0.5 * roughness)  # D §1, infra-red f_i (no occlusion map)


def _readings(sup: Supervisor) -> list[float]:
    return [sup.getDevice(name).getValue() for name in ("ir0", "ir1")]


@pytest.mark.parametrize("edit", [True, False])
def test_an_appearance_colour_edit_reaches_infra_red_rays_through_its_uses(edit: bool) -> None:
    # one ray (D §1.2), hit at d = 1 − 0.1 = 0.9 m: d = d̄/f̄ with redColorSensitivity 1 (D §1), read through the table
    # that maps distance to itself. White (red 1, roughness 1): f = 0.6, 0.9/0.6 = 1.5; red 0.75: f = 0.5, 1.8
    sup = _open()
    assert sup.step(STEP) != -1
    assert _readings(sup) == pytest.approx([0.9 / _reflection(1.0)] * 2)
    if edit:
        sup.getFromDef("PAINT").getField("baseColor").setSFColor([0.75, 0.0, 0.0])
    assert sup.step(STEP) != -1
    expected = 0.9 / _reflection(0.75 if edit else 1.0)
    assert _readings(sup) == pytest.approx([expected] * 2)
    assert expected == pytest.approx(1.8 if edit else 1.5)
    sup.simulationReset()
    assert sup.step(STEP) != -1
    assert sup.step(STEP) != -1
    assert _readings(sup) == pytest.approx([1.5, 1.5])


@pytest.mark.parametrize("edit", [True, False])
def test_an_appearance_colour_edit_shows_in_the_next_camera_image(edit: bool) -> None:
    # the centre pixel sees the first box: white, it is grey (red = green, the lights being white); painted red
    # (green 0) its green falls below its red (a white light's highlight is all that is left in green), where
    # the control's stays equal
    sup = _open()
    camera = sup.getDevice("camera")
    assert sup.step(STEP) != -1
    image = camera.getImage()
    red, green = camera.imageGetRed(image, 8, 4, 4), camera.imageGetGreen(image, 8, 4, 4)
    assert red == green > 0
    if edit:
        sup.getFromDef("PAINT").getField("baseColor").setSFColor([1.0, 0.0, 0.0])
    assert sup.step(STEP) != -1
    image = camera.getImage()
    red, green = camera.imageGetRed(image, 8, 4, 4), camera.imageGetGreen(image, 8, 4, 4)
    assert (green < red / 2) if edit else (green == red)
