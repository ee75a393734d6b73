"""Webots' ``Supervisor``: a Robot with scene-tree access and simulation control (docs/reference/webots-on-ode.md §6).

``worldSave`` writes the current scene tree as a ``.wbt`` (PROTO instances are written expanded, as base nodes;
floats in their shortest exact form). ``worldLoad``/``worldReload`` end this world as Webots does: every
controller gets -1 from ``step``; the runner then loads the requested world (``worldReload``: the current file,
as saved on disk) and runs it, with fresh controllers, for what is left of the run's duration.

Headless answers where Webots needs its GUI: nothing is ever selected (``getSelected`` is None); labels, images,
movies and HTML5 animations have no 3D view to come from (``setLabel`` is accepted and draws nothing;
``exportImage``, ``movieStartRecording`` and ``animationStartRecording`` print an error and write nothing,
``movieFailed()`` is then True); no virtual-reality headset is ever in use.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from dualtwin.webots.api_args import as_float, as_int, as_text, warn
from dualtwin.webots.robot import Robot, link_of
from dualtwin.webots.runtime import SIMULATION_MODE_FAST, SIMULATION_MODE_PAUSE, SIMULATION_MODE_REAL_TIME
from dualtwin.webots.scene_api import Node, descendants, find_def, world_as_saved
from dualtwin.webots.writer import write_world

__all__ = ["Supervisor"]


class Supervisor(Robot):
    """Webots ``Supervisor`` (a Robot whose node has ``supervisor TRUE``)."""

    SIMULATION_MODE_PAUSE = SIMULATION_MODE_PAUSE
    SIMULATION_MODE_REAL_TIME = SIMULATION_MODE_REAL_TIME
    SIMULATION_MODE_FAST = SIMULATION_MODE_FAST

    # -- simulation control

    def simulationGetMode(self) -> int:
        """The mode at the last ``step`` (Webots caches it there)."""
        return int(link_of(self).mode)

    def simulationSetMode(self, mode: Any) -> None:
        """Headless, REAL_TIME and FAST both run as fast as possible; PAUSE ends a run nobody can resume."""
        value = as_int(mode, "Supervisor.simulationSetMode")
        if value not in (SIMULATION_MODE_PAUSE, SIMULATION_MODE_REAL_TIME, SIMULATION_MODE_FAST):
            warn(f"Supervisor.simulationSetMode(): unknown mode {value}; ignored")
            return
        link_of(self)._runtime.mode = value

    @property
    def simulation_mode(self) -> int:
        return self.simulationGetMode()

    @simulation_mode.setter
    def simulation_mode(self, mode: Any) -> None:
        self.simulationSetMode(mode)

    def simulationReset(self) -> None:
        """Restore the load state at the next ``step`` (controllers keep running)."""
        link = link_of(self)
        link._runtime.request_reset(link.client)

    def simulationResetPhysics(self) -> None:
        link_of(self)._sim.reset_physics()

    def simulationQuit(self, status: Any) -> None:
        code = as_int(status, "Supervisor.simulationQuit")
        runtime = link_of(self)._runtime
        runtime.exit_status = code
        # Webots terminates every controller at once (webots-devices.md §11.4: step returns -1 on quit): those
        # waiting in their step are answered -1 now, not once this supervisor happens to step again or end
        runtime.finish()

    # -- worlds

    def worldSave(self, filename: str | None = None) -> int:
        """Write the current scene tree to ``filename`` (None: over the current world); 1 on success, else 0.
        Solids are written where the physics has them now and PROTO instances as PROTO nodes, as Webots does."""
        sim = link_of(self)._sim
        target = Path(sim.world.path if filename is None else str(filename))
        if target.suffix != ".wbt":
            warn(f"Supervisor.worldSave(): {target} is not a .wbt file")
            return 0
        try:
            target.write_text(write_world(world_as_saved(sim), protos=True), encoding="utf-8")
        except OSError as exc:
            warn(f"Supervisor.worldSave(): cannot write {target}: {exc.strerror or exc}")
            return 0
        return 1

    def worldLoad(self, filename: str) -> None:
        """End this world and have the runner load ``filename`` (every controller then gets -1 from ``step``)."""
        target = Path(str(filename))
        if not target.is_file():
            warn(f"Supervisor.worldLoad(): {target} does not exist")
            return
        self.__request(target)

    def worldReload(self) -> None:
        """End this world and have the runner load the current world file again (unsaved edits are lost)."""
        self.__request(Path(link_of(self)._sim.world.path))

    def __request(self, world: Path) -> None:
        link = link_of(self)
        # read by the runner (runner.WORLD_REQUEST) once every controller has ended
        link._sim.extensions["world_request"] = (world.resolve(), link._runtime.clock)
        link._runtime.finish()  # every controller's step says -1 now, as on quit (webots-devices.md §11.4)

    # -- scene tree

    def getRoot(self) -> Node:
        return link_of(self).root()

    def getSelf(self) -> Node:
        link = link_of(self)
        return Node(link, link._rec.node)

    def getFromDef(self, d: str) -> Node | None:
        """Node by DEF name; ``"A.B"`` scopes B inside A; PROTO internals are not searched."""
        link = link_of(self)
        scope = list(link._sim.world.nodes)
        found = None
        for part in as_text(d, "Supervisor.getFromDef").split("."):
            found = None
            for top in scope:
                found = find_def(top, part)
                if found is not None:
                    break
            if found is None:
                return None
            scope = descendants(found)
        return Node(link, found) if found is not None else None

    def getFromId(self, id: Any) -> Node | None:  # noqa: A002 - Webots' parameter name
        """The node with this unique id (see :meth:`Node.getId`), or None."""
        return link_of(self).getFromId(id)

    def getFromDevice(self, tag: Any) -> Node | None:
        """The node of the device with this tag (``device._tag``)."""
        link = link_of(self)
        binding = link._binding_for(as_int(tag, "Supervisor.getFromDevice"))
        record = binding.record if binding is not None else None
        # a Propeller's motor is recorded on its Propeller (its ``motor`` node): Webots answers the motor's node
        node = getattr(record, "node", None) or getattr(record, "motor", None)
        return Node(link, node) if node is not None else None

    def getSelected(self) -> Node | None:
        """Nothing can be selected without Webots' scene tree view."""
        return None

    def setLabel(self, id: Any, label: str, x: Any, y: Any, size: Any, color: Any, transparency: Any = 0,  # noqa: A002
                 font: str = "Arial") -> None:
        """Labels are drawn on the 3D view; headless there is none, so the label is checked and not drawn."""
        as_int(id, "Supervisor.setLabel")
        as_text(label, "Supervisor.setLabel")
        as_text(font, "Supervisor.setLabel")
        for value in (x, y, size, transparency):
            as_float(value, "Supervisor.setLabel")
        as_int(color, "Supervisor.setLabel")

    # -- images, movies, animations, VR (need Webots' 3D view)

    def exportImage(self, filename: str, quality: Any) -> None:
        as_int(quality, "Supervisor.exportImage")
        warn(f"Supervisor.exportImage(): no 3D view headless; {filename} was not written")

    def movieStartRecording(self, filename: str, width: Any, height: Any, codec: Any, quality: Any,
                            acceleration: Any, caption: Any) -> None:
        warn(f"Supervisor.movieStartRecording(): no 3D view headless; {filename} will not be recorded")
        link_of(self).movie_failed = True

    def movieStopRecording(self) -> None:
        pass

    def movieIsReady(self) -> bool:
        return True

    def movieFailed(self) -> bool:
        return bool(getattr(link_of(self), "movie_failed", False))

    def animationStartRecording(self, filename: str) -> int:
        warn(f"Supervisor.animationStartRecording(): no 3D view headless; {filename} will not be recorded")
        return 0

    def animationStopRecording(self) -> int:
        return 0

    def virtualRealityHeadsetIsUsed(self) -> bool:
        return False

    def virtualRealityHeadsetGetPosition(self) -> list[float]:
        return [math.nan] * 3

    def virtualRealityHeadsetGetOrientation(self) -> list[float]:
        return [math.nan] * 9
