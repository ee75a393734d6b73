"""Webots devices whose output only exists in Webots' GUI: ``Speaker`` (sound) and ``Skin`` (a mesh deformed by
bones), headless (the ``Pen`` is in :mod:`.pen`).

What they answer without a GUI, as Webots does without sound or rendering: a Speaker plays nothing (no sound is
ever playing, nothing is spoken; the text-to-speech engine is ``'pico'`` with language ``'en-US'``, the only engine
Webots has on Linux); a Skin has no skeleton loaded (0 bones).
Webots' ``Speaker.setLanguage`` calls the C function that sets the engine (a bug in its wrapper); ours sets the
language, as Webots documents.
"""

from __future__ import annotations

import math
from typing import Any

from dualtwin.webots.api_args import as_float, as_int, as_text, warn
from dualtwin.webots.device_base import Device

__all__ = ["Skin", "Speaker"]

_ENGINES = ("pico",)
_LANGUAGES = ("en-US", "en-UK", "de-DE", "es-ES", "fr-FR", "it-IT")


class Speaker(Device):
    """Webots ``Speaker``: headless, no sound is ever played or spoken."""

    def __init__(self, name: Any) -> None:
        super().__init__(name)
        if self._owner is self:  # (another handle on the speaker shares its engine and language)
            self._engine = "pico"
            self._language = "en-US"

    @staticmethod
    def playSound(left: Speaker, right: Speaker, sound: str, volume: Any, pitch: Any, balance: Any,
                  loop: Any) -> None:
        """Nothing is played headless (the sound file is not even opened)."""
        as_text(sound, "Speaker.playSound")
        for value in (volume, pitch, balance):
            as_float(value, "Speaker.playSound")

    def stop(self, sound: str | None = None) -> None:
        pass

    def isSoundPlaying(self, sound: str) -> bool:
        return False

    def speak(self, text: str, volume: Any) -> None:
        as_text(text, "Speaker.speak")
        as_float(volume, "Speaker.speak")

    def isSpeaking(self) -> bool:
        return False

    def setEngine(self, engine: str) -> bool:
        if as_text(engine, "Speaker.setEngine") not in _ENGINES:
            warn(f"Speaker.setEngine(): unknown engine {engine!r} (available: {', '.join(_ENGINES)})")
            return False
        self._engine = engine
        return True

    def setLanguage(self, language: str) -> bool:
        if as_text(language, "Speaker.setLanguage") not in _LANGUAGES:
            warn(f"Speaker.setLanguage(): unsupported language {language!r}")
            return False
        self._language = language
        return True

    def getEngine(self) -> str:
        return self._engine

    def getLanguage(self) -> str:
        return self._language


class Skin(Device):
    """Webots ``Skin``: its skeleton comes from a mesh file Webots loads for rendering; headless there is none."""

    def __init__(self, name: Any) -> None:
        super().__init__(name)

    def getBoneCount(self) -> int:
        return 0

    def getBoneName(self, index: Any) -> str:
        self._no_bone("getBoneName", index)
        return ""

    def getBoneOrientation(self, index: Any, absolute: Any) -> list[float]:
        self._no_bone("getBoneOrientation", index)
        return [math.nan] * 4

    def getBonePosition(self, index: Any, absolute: Any) -> list[float]:
        self._no_bone("getBonePosition", index)
        return [math.nan] * 3

    def setBoneOrientation(self, index: Any, orientation: Any, absolute: Any) -> None:
        self._no_bone("setBoneOrientation", index)

    def setBonePosition(self, index: Any, position: Any, absolute: Any) -> None:
        self._no_bone("setBonePosition", index)

    def _no_bone(self, method: str, index: Any) -> None:
        warn(f"Skin.{method}(): index {as_int(index, 'Skin.' + method)} out of range (no skeleton headless)")

    bone_count = property(lambda self: self.getBoneCount())
