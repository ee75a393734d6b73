"""A rotating Lidar: its head turns and its range image is filled column by column as the head sweeps it.

webots-devices.md §3.2: "Rotating: ``rotatingHead`` turned by −2π·f·dt per step about its z-axis, sampling period
forced to basicTimeStep, image filled column-wise"; §3.1: a rotating lidar's image spans 2π (the load-time layer
check uses 2π for its field of view).

Sweep
    The head's sweep ``s`` counts the turns it made since the load (or the last ``simulationReset``, which puts
    the head back: §11.3 "Lidar head reset"). At every basic step while the lidar is enabled it grows by
    ``f·dt`` (f the lidar's frequency in Hz, dt the basic step in s): the head points at azimuth ``−2π·s`` in the
    lidar's frame, clockwise seen from +z. A disabled lidar's head stands still (the reference is silent; our
    reading, UNVERIFIED: Webots turns the head in the per-step work that fills the image, done for an enabled
    lidar only), and so does the head of a robot whose controller was restarted, until the new controller
    enables the lidar: a restarted controller finds its devices disabled (``RobotLink._release``).

Image
    ``horizontalResolution`` (W) columns per layer over the whole turn, in the lidar's frame (the image does not
    turn with the head): column ``j`` looks at ``θ_j = π − (j+½)·2π/W``, the fixed lidar's ``fov/2 − (j+½)·fov/W``
    with fov = 2π (``getFov()`` returns 2π, the ``fieldOfView`` field is not used, and the projection is
    cylindrical: no flat image plane spans a turn), so column 0 looks just left of straight behind and the
    columns go clockwise, in the order the head sweeps them. The head, starting along +x, reaches column j when its sweep crosses
    ``c_j = ((j+½)/W − ½) mod 1`` turns (plus whole turns). At each basic step the columns whose ``c_j`` the sweep
    crossed during that step are cast, from the poses after that step's physics (as every ray sensor is sampled),
    and stamped with that time for the point cloud; the other columns keep their last values, 0.0 (and time 0)
    before their first sweep as the fixed lidar's image before its first sample (§3.2). A step that sweeps a full
    turn or more casts every column once. A crossing within 1e-9 turn of the step's end counts as reached.

Sampling period
    "Forced to basicTimeStep": the lidar is sampled at every basic step whatever ``enable(p)`` asked, and
    ``getSamplingPeriod()`` still returns p (the controller library echoes the requested period, §0.2; the forcing
    is on the simulator's side).

Frequency
    Starts at ``defaultFrequency``; ``setFrequency`` outside [minFrequency, maxFrequency] is an error that changes
    nothing (§3.3). Where the reference is silent: bounds that are not ``0 < min <= max < inf`` become 1 and 25 Hz,
    and a default outside them is clamped into them, with a warning (:func:`frequencies`).

Head Solid
    The ``rotatingHead`` Solid (if any) is built as a Solid below the lidar (cameras draw it, rays see it, a
    supervisor reads its fields). After each basic step's physics its rotation becomes its load rotation turned
    by ``−2π·s`` about its own z axis (its ``rotation`` field is written, its subtree moves with it); nothing
    else about it changes (a supervisor's edit of its rotation lasts until the next turn). A head with a body of its own (a Physics node) is not turned (one warning):
    turning a body inside the step would move it against ODE's state.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dualtwin.webots import _math3 as m3
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import DeviceRec, Simulation, SolidRec

__all__ = ["HeadDriver", "LidarHead", "RotatingHeads", "RotatingScan", "frequencies", "heads_of", "swept_columns"]

#: a column whose crossing is this close (in turns) to the end of a step is cast at that step
SWEEP_TOLERANCE = 1e-9


class HeadDriver(Protocol):
    """The enabled Lidar device that turns a head (the head needs its frequency and whether it is enabled)."""

    def getFrequency(self) -> float: ...  # noqa: N802 - Webots' method name

    def getSamplingPeriod(self) -> int: ...  # noqa: N802 - Webots' method name


@dataclass
class LidarHead:
    """A rotating lidar's head: how far it turned and the Solid that shows it (see the module docstring)."""

    solid: SolidRec | None
    load_rotation: m3.Mat3
    swept: float = 0.0  # turns since the load or the last reset (less the whole turns both sweeps made)
    cast: float = 0.0  # the sweep when the lidar's columns were last cast
    driver: HeadDriver | None = None  # the enabled lidar device turning it


def frequencies(fields: dict[str, object], warn: Callable[[str], None]) -> tuple[float, float, float]:
    """``(minFrequency, maxFrequency, defaultFrequency)`` of a Lidar's fields. Out of order or not positive and
    finite, the bounds take Webots' defaults 1 and 25 Hz, and a default frequency outside them is clamped into
    them, with a warning (the reference is silent on these checks: an infinite frequency would turn the head
    by an infinite angle, which ODE cannot take)."""
    fmin, fmax = (float(fields.get(name, default)) for name, default in  # type: ignore[arg-type]
                  (("minFrequency", 1.0), ("maxFrequency", 25.0)))
    if not 0.0 < fmin <= fmax < math.inf:
        warn(f"Lidar: minFrequency {fmin:g} and maxFrequency {fmax:g} are not 0 < min <= max; using 1 and 25")
        fmin, fmax = 1.0, 25.0
    f = float(fields.get("defaultFrequency", 10.0))  # type: ignore[arg-type]
    if not fmin <= f <= fmax:
        clamped = fmin if not f > fmin else fmax
        warn(f"Lidar: defaultFrequency {f:g} is outside [{fmin:g}, {fmax:g}]; using {clamped:g}")
        f = clamped
    return fmin, fmax, f


def swept_columns(width: int, start: float, end: float) -> np.ndarray:
    """The columns (of ``width``) whose direction the head crossed while its sweep went from ``start`` to ``end``
    turns (``start`` excluded, ``end`` included)."""
    if end - start >= 1.0:
        return np.arange(width)
    offsets = ((np.arange(width) + 0.5) / width - 0.5) % 1.0
    last = offsets + np.floor(end - offsets + SWEEP_TOLERANCE)  # the last crossing of each column up to ``end``
    return np.flatnonzero(last > start + SWEEP_TOLERANCE)


class RotatingHeads:
    """The simulation's rotating lidar heads: turned after each step's physics, put back by a reset."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.heads: dict[int, LidarHead] = {}
        sim.step_hooks.append(self.turn)
        sim.reset_hooks.append(self.reset)

    def head(self, record: DeviceRec) -> LidarHead:
        head = self.heads.get(id(record))
        if head is None:
            node = record.node.fields.get("rotatingHead")
            solid = self.sim.solid_for(node) if isinstance(node, Node) else None
            if solid is not None and solid.body is not None:
                self.sim.warn_once(f"Lidar '{record.name}': its rotatingHead has a Physics node; it is not turned")
                solid = None
            # its rotation field's value at load (a supervisor may have edited the field since)
            loaded = (solid.pre.inverse() * solid.load_rel).R if solid is not None else None
            head = LidarHead(solid, loaded or m3.rot_axis_angle((0.0, 0.0, 1.0, 0.0)))
            self.heads[id(record)] = head
        return head

    def turn(self) -> None:
        dt = self.sim.dt
        for head in self.heads.values():
            driver = head.driver
            if driver is None or driver.getSamplingPeriod() <= 0:
                continue
            turns = driver.getFrequency() * dt
            # a step of a turn or more casts every column: its whole turns matter no more than one, and both
            # sweeps lose their common whole turns, so that a huge maxFrequency never makes them overflow
            head.swept += turns % 1.0 + (1.0 if turns >= 1.0 else 0.0)
            whole = math.floor(min(head.swept, head.cast))
            head.swept, head.cast = head.swept - whole, head.cast - whole
            self._place(head)

    def reset(self) -> None:
        # the head Solid's fields and pose are restored by the simulation's reset (it is a Solid of the scene)
        for head in self.heads.values():
            head.swept = head.cast = 0.0

    def _place(self, head: LidarHead) -> None:
        if head.solid is None:
            return
        angle = -2.0 * math.pi * (head.swept % 1.0)
        turned = m3.mat_mul(head.load_rotation, m3.rot_axis_angle((0.0, 0.0, 1.0, angle)))
        self.sim.turn_solid(head.solid, m3.axis_angle_from_mat(turned))


def heads_of(sim: Simulation) -> RotatingHeads:
    heads = sim.extensions.get("lidar_heads")
    if heads is None:
        heads = sim.extensions["lidar_heads"] = RotatingHeads(sim)
    return heads


class RotatingScan:
    """A rotating lidar's column-by-column image (see the module docstring), one per lidar device."""

    def __init__(self, sim: Simulation, record: DeviceRec, width: int, layers: int) -> None:
        self.head = heads_of(sim).head(record)
        self.width, self.layers = width, layers
        self.times = np.zeros(width)  # when each column was last cast (s)
        self.columns = np.empty(0, dtype=int)  # the columns of the rays being cast
        self.rays = np.empty(0, dtype=int)  # their indices in the layer-major image

    def start(self, driver: HeadDriver) -> None:
        """The lidar was enabled: its head turns from where it stands, the next cast starts there."""
        self.head.driver = driver
        self.head.cast = self.head.swept

    def stop(self) -> None:
        self.head.driver = None

    def spec(self, directions: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The rays of the columns swept since the last cast (None when the head crossed none)."""
        head = self.head
        self.columns = swept_columns(self.width, head.cast, head.swept)
        head.cast = head.swept
        if not len(self.columns):
            return None
        self.rays = (np.arange(self.layers)[:, None] * self.width + self.columns[None, :]).ravel()
        return directions[self.rays], lengths[self.rays]

    def resize(self, width: int, layers: int) -> None:
        """A supervisor's edit gave the image another size (:mod:`.image_edits`): every column is cast anew."""
        self.width, self.layers = width, layers
        self.times = np.zeros(width)
        self.columns = self.rays = np.empty(0, dtype=int)

    def clear(self) -> None:
        """The image was cleared (simulationReset, a first enable): every column was cast at time 0."""
        self.times[:] = 0.0

    def fill(self, image: np.ndarray | None, ranges: np.ndarray, now: float) -> np.ndarray:
        """The image with the cast columns' ``ranges`` (in the order of :meth:`spec`'s rays) written at ``now``."""
        if image is None:  # nothing sampled yet, or the image was cleared (simulationReset): zeros and time 0
            image = np.zeros(self.width * self.layers)
            self.clear()
        out = image
        out[self.rays] = ranges
        self.times[self.columns] = now
        return out

    def __repr__(self) -> str:
        return f"RotatingScan(width={self.width}, layers={self.layers}, swept={self.head.swept!r})"
