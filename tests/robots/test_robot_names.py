"""How ``--robot`` words are read: a bare word is always a bundled robot, a path always a file (as for
``--scenarios``; docs/concepts/bindings.md, "Naming a robot")."""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import BUNDLED, resolve_robot


def test_a_bare_word_is_a_bundled_robot_even_beside_a_file_of_that_name(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cartpole").write_text((BUNDLED / "arm" / "binding.yaml").read_text(encoding="utf-8"))
    assert resolve_robot("cartpole").spec.name == "cartpole"


def test_a_bare_word_that_names_no_bundled_robot_is_refused_even_when_a_file_has_that_name(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    binding = (BUNDLED / "cartpole" / "binding.yaml").read_text(encoding="utf-8")
    (tmp_path / "mybot").write_text(binding.replace("model: cartpole.", f"model: {BUNDLED}/cartpole/cartpole."))
    with pytest.raises(DualtwinError, match=r"unknown robot 'mybot': not a bundled robot \(.*cartpole.*\); "
                                            r"to use a binding file of that name, write \./mybot"):
        resolve_robot("mybot")
    assert resolve_robot("./mybot").spec.name == "cartpole"  # the path means the file


def test_a_path_or_a_file_name_with_a_suffix_is_a_binding_file(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(DualtwinError, match=r"unknown robot 'bot\.yaml': .* and not a binding file"):
        resolve_robot("bot.yaml")
    assert resolve_robot(str(BUNDLED / "arm" / "binding.yaml")).spec.name == "arm"
