"""One robot's Camera sees another robot's LED light (LED reference page: the lights among an LED's children are
off while the LED is off, its state at start, and on in its colour otherwise), each robot with its own controller.

The LED's value reaches the world with its controller's next step request and acts on the step it makes
(webots-on-ode.md §6: "commands issued before call k act on the physics of call k"), so the
image of the step before, read by the other robot after the request was sent, still shows the light off: Webots
draws a camera image during its step, not when the controller reads it. The twin draws an image when it is read:
the value showed as soon as the LED's controller had sent its request, so the image depended on which controller
ran first.

The watcher waits a real time before it reads its first image, long enough for the switcher to have sent its
request (no timing is asserted: the wait only orders the calls; had the switcher not sent it yet, the light
would be off all the same).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

# The watcher's camera at (0.5, 0, 0) looks along the world's +y (its x axis, a quarter turn about z) at the near
# face of a white box (y = 1.9). The switcher, at (0.5, 1.5, 0) turned the same way and with nothing to draw,
# carries an LED whose dim spot points along its x axis, the world's +y, at the face's centre.
WORLD = """
WorldInfo { basicTimeStep 16 }
Solid { translation 0.5 2 0 children [ Shape { geometry Box { size 1 0.2 1 } } ] }
DEF A Robot {
  translation 0.5 0 0 rotation 0 0 1 1.5707963267948966
  children [ Camera { name "cam" width 16 height 16 } ]
  name "a" controller "watcher"
}
DEF B Robot {
  translation 0.5 1.5 0 rotation 0 0 1 1.5707963267948966
  children [ LED { name "led" color [ 1 1 1 ]
    children [ SpotLight { direction 1 0 0 attenuation 0 0 1 intensity 0.01 } ] } ]
  name "b" controller "switcher"
}
"""

WATCHER = """
import time
from controller import Robot
robot = Robot()
camera = robot.getDevice("cam")
camera.enable(16)

def centre():
    image = camera.getImage()
    at = 4 * (8 * 16 + 8)
    return " ".join(str(v) for v in image[at:at + 3])

robot.step(16)
time.sleep(0.5)  # b has set its LED and sent its step request meanwhile
print("a step 1:", centre())
robot.step(16)
print("a step 2:", centre())
"""

SWITCHER = """
from controller import Robot
robot = Robot()
led = robot.getDevice("led")
robot.step(16)
led.set(1)
robot.step(16)
robot.step(16)
"""


@pytest.mark.parametrize("isolation", ["threads", "process"])
def test_an_led_light_shows_in_another_robots_image_from_the_step_that_executes_it(tmp_path: Path,
                                                                                    isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"watcher": WATCHER, "switcher": SWITCHER}, isolation, duration_s=0.048)
    step1, step2 = ([int(v) for v in line.split(":")[1].split()] for line in lines_of(lines, "a "))
    # step 1's image: the LED off (b's set went with its step-2 request); step 2's: lit by the white spot, every
    # channel brighter (the box stays below white: test_composite_lights_camera's dim spot)
    assert all(lit > dark + 5 for dark, lit in zip(step1, step2, strict=True)), (step1, step2)
