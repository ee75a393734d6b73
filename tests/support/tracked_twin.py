"""The MuJoCo twin under another registry name, each instance recorded with whether it was closed: a test can see
that whoever built a twin through the public registry (:data:`dualtwin.twins.TWINS`) also closed it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from dualtwin.robots.binding import RobotBinding
from dualtwin.twins import TWINS
from dualtwin.twins.mujoco import MuJoCoTwin

NAME = "tracked-mujoco"
ENTRY = "tests.support.tracked_twin:from_binding"


class TrackedTwin(MuJoCoTwin):
    """A MuJoCo twin that remembers being closed."""

    closed = False

    def close(self) -> None:
        self.closed = True
        super().close()


#: Every twin the factory built while registered, oldest first.
BUILT: list[TrackedTwin] = []


def from_binding(robot: RobotBinding, control_period: float) -> TrackedTwin:
    """The registry's factory: MuJoCo's own (twins.mujoco.from_binding), recording the twin."""
    section = robot.spec.twins.get("mujoco")
    twin = TrackedTwin(robot.model_path("mujoco"), control_period, dict(section.aliases) if section else None)
    BUILT.append(twin)
    return twin


@contextmanager
def tracked() -> Iterator[list[TrackedTwin]]:
    """Register the tracked twin for the duration; yields the list of twins built meanwhile."""
    BUILT.clear()
    TWINS[NAME] = ENTRY
    try:
        yield BUILT
    finally:
        TWINS.pop(NAME, None)
