"""Worlds and PROTOs that are well-formed but hostile. Their size, once USE, IS and PROTOs are expanded, is bounded
(``MAX_NODES``), so loading one is a one-line error instead of minutes of copying and gigabytes of memory; long
strings, comments and lines cost memory and time linear in their length."""

from __future__ import annotations

import math
import signal
import tracemalloc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dualtwin.cli import main
from dualtwin.webots import WebotsSyntaxError, load_world, load_world_text
from dualtwin.webots.lexer import tokenize
from dualtwin.webots.parser import MAX_NODES, parse_world
from dualtwin.webots.proto_resolver import ProtoError
from dualtwin.webots.protos import expand_world

HEADER = "#VRML_SIM R2023b utf8\n"
FAN_OUT = 12
# Levels of FAN_OUT-fold copies whose expansion just passes MAX_NODES: small enough that the code without the
# bound finishes (so this test fails there instead of hanging), one level more than the bound allows.
LEVELS = math.ceil(math.log(MAX_NODES, FAN_OUT))


@pytest.fixture(autouse=True)
def _clean_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DUALTWIN_PROTO_PATH", raising=False)
    monkeypatch.delenv("WEBOTS_HOME", raising=False)


def nested_uses(levels: int = LEVELS) -> str:
    """The 'billion laughs' of VRML: each DEF holds FAN_OUT USEs of the previous one."""
    lines = [HEADER.rstrip(), "WorldInfo { basicTimeStep 8 }", "DEF L0 Group { }"]
    for i in range(1, levels + 1):
        lines.append(f"DEF L{i} Group {{ children [ " + f"USE L{i - 1} " * FAN_OUT + "] }")
    return "\n".join(lines) + "\n"


def test_nested_use_copies_are_bounded(tmp_path: Path) -> None:
    world = tmp_path / "laughs.wbt"
    world.write_text(nested_uses())
    with pytest.raises(WebotsSyntaxError, match=rf"laughs\.wbt:{LEVELS + 3}:\d+: expected a world of at most {MAX_NODES} nodes"):
        load_world(world)


def test_nested_is_copies_are_bounded(tmp_path: Path) -> None:
    # A PROTO pasting its MFNode field FAN_OUT times, nested in its own field: each level multiplies.
    body = " ".join(["Group { children IS kids }"] * FAN_OUT)
    (tmp_path / "Fan.proto").write_text(f"{HEADER}PROTO Fan [ field MFNode kids [ ] ]\n{{\n  Group {{ children [ {body} ] }}\n}}\n")
    nested = "Group { }"
    for _ in range(LEVELS):
        nested = f"Fan {{ kids [ {nested} ] }}"
    with pytest.raises(WebotsSyntaxError, match=rf"expected a world of at most {MAX_NODES} nodes"):
        load_world_text(f'{HEADER}EXTERNPROTO "Fan.proto"\n{nested}\n', tmp_path / "w.wbt")


def test_a_file_of_too_many_nodes_is_refused(tmp_path: Path) -> None:
    with pytest.raises(WebotsSyntaxError, match=rf"w\.wbt:2:\d+: expected at most {MAX_NODES} nodes in a file"):
        load_world_text(HEADER + "Group { } " * (MAX_NODES + 1), tmp_path / "w.wbt")


def test_cli_refuses_nested_uses_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = tmp_path / "laughs.wbt"
    world.write_text(nested_uses())
    out = tmp_path / "laughs.xml"
    assert main(["convert", str(world), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "laughs.wbt" in err[0] and f"at most {MAX_NODES} nodes" in err[0], err
    assert not out.exists()


def test_long_strings_and_comments_tokenize_in_linear_memory() -> None:
    # The tokenizer's regexes once kept a backtracking entry per character of a string or comment line: a 4 MB
    # string took ~600 MB to tokenize. Measured with tracemalloc (allocations, not time): a few copies of the input.
    text = '#VRML_SIM R2023b utf8\nSolid { name "' + "x" * 4_000_000 + '" }\n' + "#\n" * 1_000_000
    tracemalloc.start()
    try:
        tokens = tokenize(text, "w.wbt")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert [t.kind for t in tokens] == ["ident", "{", "ident", "string", "}", "eof"]
    assert peak < 10 * len(text), f"{peak / 1e6:.0f} MB to tokenize {len(text) / 1e6:.0f} MB"


@pytest.fixture
def hang_guard() -> Iterator[None]:
    """Turns a hang into a failure: each load below takes milliseconds, it took hours before the fix."""

    def fire(signum: int, frame: Any) -> None:
        raise TimeoutError("still loading after 60 s: a regex is quadratic in the input again")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.alarm(60)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize(
    "proto",
    [
        # a long PROTO header comment line (the '# tags: ...' metadata regex)
        "#VRML_SIM R2023b utf8\n# a" + " " * 1_000_000 + "b\nPROTO Long [ ]\n{\n  Group { }\n}\n",
        # a template with many blank lines (the regex that binds 'import' lines)
        "#VRML_SIM R2023b utf8\nPROTO Long [ ]\n{\n%< " + "\n" * 1_000_000 + " >%\n  Group { }\n}\n",
    ],
    ids=["header-comment", "template-blank-lines"],
)
def test_long_proto_lines_load_in_linear_time(tmp_path: Path, proto: str, hang_guard: None) -> None:
    (tmp_path / "Long.proto").write_text(proto)
    world = load_world_text(f'{HEADER}EXTERNPROTO "Long.proto"\nLong {{ }}\n', tmp_path / "w.wbt")
    assert [n.type_name for n in world.nodes] == ["Group"]


def test_templates_of_one_world_share_one_time_budget(tmp_path: Path) -> None:
    # Each template stays under its own limit (1 s of a 10 s one); together they pass the world's budget. Before,
    # only the per-template limit existed, so N instances of a 9 s template ran for N * 9 s.
    (tmp_path / "Slow.proto").write_text(
        f"{HEADER}PROTO Slow [ ]\n{{\n%< const t0 = Date.now(); while (Date.now() - t0 < 1000) {{}} >%\n  Group {{ }}\n}}\n"
    )
    world = tmp_path / "w.wbt"
    world.write_text(f'{HEADER}EXTERNPROTO "Slow.proto"\n' + "Slow { }\n" * 3)
    with pytest.raises(ProtoError, match=r"w\.wbt:\d+:1: template of PROTO Slow .* ran longer than 2 s in total$"):
        expand_world(parse_world(world.read_text(), str(world)), world, template_seconds=2)


@pytest.mark.parametrize("url", ["../../../../../../../../etc/passwd", "file:///etc/hostname"])
def test_an_externproto_that_is_not_a_proto_file_is_not_read(tmp_path: Path, url: str) -> None:
    """Before, the file was read as a PROTO, and its first line quoted in the parse error (root:x:0:0:...)."""
    from dualtwin.errors import DualtwinError

    name = url.rsplit("/", 1)[-1]
    world = tmp_path / "w.wbt"
    world.write_text(f'#VRML_SIM R2023b utf8\nEXTERNPROTO "{url}"\nWorldInfo {{ }}\n{name} {{ }}\n')
    with pytest.raises(DualtwinError) as info:
        load_world(world)
    message = str(info.value)
    assert f"PROTO '{name}'" in message and "(not a .proto file: not read)" in message, message
    assert "root:" not in message and "found '" not in message
