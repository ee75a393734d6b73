"""A world of three robots and two supervisors whose controllers, in the same steps, write fields that another
robot's devices or getters depend on and read them, printing what they see with ``getTime()`` (the determinism
harness: tests/webots/test_composite_multi_determinism.py, and scripts/stress_determinism.py run by hand with many
runs under load).

webots-on-ode.md §6: a controller sees the world through its steps; a supervisor's write is executed at the
beginning of the next step, the writes of one step in the supervisors' scene-tree order. So what every controller
prints is the same whichever controller's request reaches the simulation first in real time. Each controller
waits a random real time (``jitter_s``, drawn from the operating system, not from a seed) before some of its calls,
only to vary that order from run to run: no output may depend on it."""

from __future__ import annotations

from pathlib import Path

from tests.support.multi_worlds import run_multi

STEPS = 12

WORLD = """
WorldInfo { basicTimeStep 8 }
DEF BOX Solid { translation 0 0 1 }
DEF R1 Robot {
  name "r1" controller "reader"
  children [
    DEF DS DistanceSensor { name "ds" lookupTable [ 0 0 0, 0.1 1000 0 ] }
    HingeJoint {
      device [ DEF M RotationalMotor { name "m" maxVelocity 10 } PositionSensor { name "ps" } ]
      endPoint Solid { physics Physics { density -1 mass 1 } boundingObject Sphere { radius 0.05 } }
    }
    DEF EM Emitter { name "em" channel 1 }
  ]
}
DEF R2 Robot { name "r2" controller "reader" customData "a" children [ DEF EM2 Emitter { name "em" channel 2 } ] }
DEF R3 Robot { name "r3" controller "reader" children [ Receiver { name "rx" channel 13 } ] }
DEF S1 Robot { name "s1" controller "writer" supervisor TRUE }
DEF S2 Robot { name "s2" controller "writer" supervisor TRUE }
"""

#: each robot reads what the supervisors write of its own devices and customData; r1's Emitter sends its step
#: number on the channel s2 writes (10 + i), r3's Receiver hears channel 13 only (the supervisors read the box);
#: r1 commands its motor in the steps where s1 writes its maxVelocity and s2 its multiplier, and prints its angle
READER = """
import os, random, time
from controller import Robot
rng = random.Random(os.urandom(8))
def jitter():
    time.sleep(rng.random() * JITTER)
robot = Robot()
name = robot.getName()
ds, m, em, rx = (robot.getDevice(n) if n in DEVICES[name].split() else None for n in ("ds", "m", "em", "rx"))
if rx:
    rx.enable(8)
if ds:
    ds.enable(8)
if m:
    ps = robot.getDevice("ps")
    ps.enable(8)
    m.setPosition(float("inf"))
for i in range(STEPS):
    robot.step(8)
    jitter()
    seen = [f"t={robot.getTime():.3f}", f"custom={robot.getCustomData()!r}"]
    if ds:
        seen += [f"table={ds.getLookupTable()}", f"max={ds.getMaxValue()}", f"value={ds.getValue():.6g}"]
    if m:
        seen.append(f"maxVelocity={m.getMaxVelocity()}")
    if em:
        seen.append(f"channel={em.getChannel()}")
    jitter()
    if ds:  # read again after a wait: a write may have come meanwhile
        seen += [f"table={ds.getLookupTable()}", f"maxVelocity={m.getMaxVelocity()}"]
    if em:
        seen.append(f"channel={em.getChannel()}")
    if em and name == "r1":
        em.send(f"{i}".encode())
    while rx and rx.getQueueLength():
        seen.append(f"heard={rx.getBytes().decode()}")
        rx.nextPacket()
    seen.append(f"custom={robot.getCustomData()!r}")
    print(name, *seen)
    if m:
        m.setVelocity(30.0 if i % 2 else 3.0)
        print(f"{name}m t={robot.getTime():.3f} angle={ps.getValue():.9f} velocity={m.getVelocity()}")
"""

WRITER = """
import os, random, time
from controller import Supervisor
rng = random.Random(os.urandom(8))
def jitter():
    time.sleep(rng.random() * JITTER)
sup = Supervisor()
name = sup.getName()
node = sup.getFromDef
for i in range(STEPS):
    sup.step(8)
    jitter()
    if name == "s1":
        table = node("DS").getField("lookupTable")
        table.setMFVec3f(1, [0.1 + i, 1000.0 * (i + 1), 0.0])
        node("M").getField("maxVelocity").setSFFloat(10.0 + i)
        node("R2").getField("customData").setSFString(f"s1-{i}")
        node("BOX").getField("translation").setSFVec3f([0.0, 0.0, 1.0 + i])
    else:
        node("EM").getField("channel").setSFInt32(10 + i)
        node("EM2").getField("channel").setSFInt32(20 + i)
        node("R2").getField("customData").setSFString(f"s2-{i}")
        node("M").getField("multiplier").setSFFloat(1.0 + i % 3)
        if i % 2:
            node("BOX").getField("translation").setSFVec3f([0.5, 0.0, 2.0 + i])
    jitter()
    box = node("BOX").getField("translation").getSFVec3f()
    seen = [f"t={sup.getTime():.3f}", f"box={box}", f"custom2={node('R2').getField('customData').getSFString()!r}",
            f"maxVelocity={node('M').getField('maxVelocity').getSFFloat()}",
            f"channel={node('EM').getField('channel').getSFInt32()}"]
    print(name, *seen)
"""


def controllers(jitter_s: float) -> dict[str, str]:
    head = f"STEPS = {STEPS}\nJITTER = {jitter_s!r}\nDEVICES = {{'r1': 'ds m em', 'r2': 'em', 'r3': 'rx'}}\n"
    return {"reader": head + READER, "writer": head + WRITER}


def run_stress(folder: Path, isolation: str, jitter_s: float = 0.002) -> list[str]:
    """One run of the world in ``isolation`` mode; the lines the controllers printed, each controller's in order,
    the controllers in the robots' order (r1, r2, r3, s1, s2), so that runs compare whatever the real-time order of
    their output."""
    lines = run_multi(folder, WORLD, controllers(jitter_s), isolation)
    return sorted(lines, key=lambda line: line.split(" ", 1)[0])
