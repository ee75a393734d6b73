"""Text parameters of the controller API refuse anything but a ``str`` with a ``TypeError``, as Webots' wrapper does.

webots-python-api.md lists these parameters as text (Robot ``wwiSendText(text)``, ``getDevice(name)``,
``setCustomData(data)``; Supervisor ``setLabel(id, label, ..., font='Arial')``, ``getFromDef(d)``; Node
``getField(name)``; Display ``drawText(text, x, y)``, ``setFont(font, ...)``; Speaker ``speak(text, volume)``,
``playSound(..., sound, ...)``, ``setEngine(engine)``, ``setLanguage(language)``). Webots' Python wrapper encodes each
before the C call (``str.encode(text)``), which raises ``TypeError`` for anything that is not a ``str``: a number,
``None`` or ``bytes``. Where the text has no use headless (a label, a robot-window message), it was accepted
silently, so a script that fails in Webots passed here. ``Node.setVisibility(fromNode, visible)`` takes a Node.
``Emitter.send`` (bytes, str or a list: webots-devices.md §5.3) and ``Field.setSFString`` (an error line,
webots-python-api.md "Shared semantics") were already as Webots and are not changed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF BOSS Robot {
  name "boss"
  supervisor TRUE
  children [ Display { name "display" } Speaker { name "speaker" } ]
}
"""


def _display(sup: Supervisor) -> Any:
    return sup.getDevice("display")


def _speaker(sup: Supervisor) -> Any:
    return sup.getDevice("speaker")


CALLS: dict[str, Callable[[Supervisor, Any], object]] = {
    "Robot.wwiSendText": lambda sup, text: sup.wwiSendText(text),
    "Robot.getDevice": lambda sup, text: sup.getDevice(text),
    "Robot.setCustomData": lambda sup, text: sup.setCustomData(text),
    "Supervisor.setLabel": lambda sup, text: sup.setLabel(0, text, 0.1, 0.1, 0.1, 0xFF0000),
    "Supervisor.setLabel font": lambda sup, text: sup.setLabel(0, "label", 0.1, 0.1, 0.1, 0xFF0000, 0, text),
    "Supervisor.getFromDef": lambda sup, text: sup.getFromDef(text),
    "Node.getField": lambda sup, text: sup.getSelf().getField(text),
    "Node.getProtoField": lambda sup, text: sup.getSelf().getProtoField(text),
    "Node.getFromProtoDef": lambda sup, text: sup.getSelf().getFromProtoDef(text),
    "Display.drawText": lambda sup, text: _display(sup).drawText(text, 0, 0),
    "Display.setFont": lambda sup, text: _display(sup).setFont(text, 8, True),
    "Speaker.speak": lambda sup, text: _speaker(sup).speak(text, 1.0),
    "Speaker.playSound": lambda sup, text: _speaker(sup).playSound(_speaker(sup), _speaker(sup), text, 1.0, 1.0,
                                                                   0.0, False),
    "Speaker.setEngine": lambda sup, text: _speaker(sup).setEngine(text),
    "Speaker.setLanguage": lambda sup, text: _speaker(sup).setLanguage(text),
}


@pytest.mark.parametrize("value", [5, None, b"bytes"], ids=["int", "None", "bytes"])
@pytest.mark.parametrize("method", list(CALLS))
def test_a_text_parameter_refuses_what_is_not_a_str(method: str, value: object,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    sup = quiet_supervisor(WORLD)
    with pytest.raises(TypeError, match=rf"^{method.split()[0]}\(\) expects a str, got "):
        CALLS[method](sup, value)
    assert capsys.readouterr().err == ""  # the exception says it all: no error line as well


@pytest.mark.parametrize("method", list(CALLS))
def test_a_str_subclass_is_text(method: str) -> None:
    # str.encode takes a str subclass: a NumPy string (a name read from an array) passes
    sup = quiet_supervisor(WORLD)
    CALLS[method](sup, np.str_("display"))


def test_set_visibility_takes_a_node() -> None:
    sup = quiet_supervisor(WORLD)
    me = sup.getSelf()
    me.setVisibility(me, False)
    with pytest.raises(TypeError, match=r"^Node\.setVisibility\(\) expects a Node, got str"):
        me.setVisibility("BOSS", False)
