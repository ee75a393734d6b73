"""The documentation site: the CLI reference is generated from the typer app and current, the site builds
with ``mkdocs build --strict`` (broken links and unlisted pages fail), and the README stays a short entry point
(at most 10 KB, links that resolve, commands that exist)."""

from __future__ import annotations

import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.names import dotted_names, resolves

ROOT = Path(__file__).resolve().parents[1]


def _generator():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("gen_cli_docs", ROOT / "scripts" / "gen_cli_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cli_reference_is_generated_from_the_current_app() -> None:
    generator = _generator()
    assert generator.TARGET.read_text(encoding="utf-8") == generator.render(), (
        "docs/reference/cli.md is stale: run python scripts/gen_cli_docs.py")


def test_site_builds_strictly(tmp_path: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "-d", str(tmp_path)],
                            cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "reference" / "cli" / "index.html").is_file()


README = ROOT / "README.md"
MAX_README_BYTES = 10 * 1024


def test_readme_is_at_most_10_kb() -> None:
    size = README.stat().st_size
    assert size <= MAX_README_BYTES, f"README.md is {size} bytes; move detail into docs/ (limit {MAX_README_BYTES})"


def test_every_relative_link_in_the_readme_exists() -> None:
    """Links must work on the forge too, so they are relative paths to files that exist (anchors aside)."""
    text = README.read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    relative = [t for t in targets if not re.match(r"[a-z][a-z0-9+.-]*:", t) and not t.startswith("#")]
    assert relative, "the README links to no docs page"
    missing = [t for t in relative if not (ROOT / t.split("#", 1)[0]).exists()]
    assert not missing, f"README.md links to missing files: {missing}"
    # Every page of the site is reachable from the README or from a page it links to (docs/index.md).
    assert "docs/index.md" in relative and "docs/results.md" in relative


def _readme_command_lines() -> list[str]:
    """The ``dualtwin ...`` lines of the README's shell blocks, continuation lines joined, comments dropped."""
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), re.DOTALL):
        for line in re.sub(r"\\\n\s*", " ", block).splitlines():
            line = re.split(r"\s#\s", line, maxsplit=1)[0].strip()
            if line.startswith("dualtwin "):
                lines.append(line)
    return lines


def test_readme_commands_and_options_exist() -> None:
    """The README's pipeline names real commands and options, so a CLI change that breaks it fails here."""
    import typer.main

    from dualtwin.cli import app

    root = typer.main.get_command(app)
    lines = _readme_command_lines()
    assert len(lines) >= 8, lines
    for line in lines:
        words = shlex.split(line)[1:]
        command = root  # typer may bundle its own click, so groups are recognised by their 'commands'
        while hasattr(command, "commands") and words and words[0] in command.commands:
            command = command.commands[words.pop(0)]
        assert not hasattr(command, "commands"), f"README: {line!r} names no command"
        options = {o for p in command.params for o in [*p.opts, *p.secondary_opts]}
        unknown = [w for w in words if w.startswith("-") and w.split("=", 1)[0] not in options]
        assert not unknown, f"README: {line!r}: unknown options {unknown}"


LAYOUT = ROOT / "docs" / "concepts" / "layout.md"


def _layout_tree() -> list[str]:
    """The package names of the layout page's tree, top to bottom (``cli/`` -> ``cli``, ``errors.py`` -> ``errors``)."""
    block = re.search(r"```\nsrc/dualtwin/\n(.*?)```", LAYOUT.read_text(encoding="utf-8"), re.DOTALL)
    assert block, "docs/concepts/layout.md has no src/dualtwin/ tree"
    return [m.group(1) for m in re.finditer(r"[├└]── (\w+)(?:/|\.py)", block.group(1))]


def _packages() -> set[str]:
    src = ROOT / "src" / "dualtwin"
    dirs = {p.parent.name for p in src.glob("*/__init__.py")}
    modules = {p.stem for p in src.glob("*.py") if p.stem not in ("__init__", "__main__")}
    return dirs | modules


def test_the_layout_page_lists_every_package_once() -> None:
    tree = _layout_tree()
    assert len(tree) == len(set(tree)), f"listed twice: {sorted({n for n in tree if tree.count(n) > 1})}"
    missing, gone = sorted(_packages() - set(tree)), sorted(set(tree) - _packages())
    assert not missing, f"docs/concepts/layout.md does not list: {missing}"
    assert not gone, f"docs/concepts/layout.md lists packages that no longer exist: {gone}"


def test_the_layout_page_follows_the_declared_layer_order() -> None:
    """The tree runs from the lowest layer up, as .importlinter declares it (top line = highest layer)."""
    text = (ROOT / ".importlinter").read_text(encoding="utf-8")
    layers = re.search(r"^layers =\n((?:[ \t]+\S.*\n)+)", text, re.MULTILINE)
    assert layers, ".importlinter declares no layers"
    rank = {}
    for i, line in enumerate(reversed(layers.group(1).strip().splitlines())):
        for name in line.split("|"):
            rank[name.strip().removeprefix("dualtwin.")] = i
    unlayered = sorted(_packages() - set(rank))
    assert not unlayered, f".importlinter puts these packages in no layer, so nothing checks their imports: {unlayered}"
    order = [(rank[n], n) for n in _layout_tree()]
    out_of_order = [f"{b} (layer {rb}) after {a} (layer {ra})"
                    for (ra, a), (rb, b) in zip(order, order[1:], strict=False) if rb < ra]
    assert not out_of_order, "docs/concepts/layout.md is out of the .importlinter order: " + "; ".join(out_of_order)


RESULTS = ROOT / "docs" / "results.md"
HASH = re.compile(r"`([0-9a-f]{7,40})`")
BENCH = re.compile(r"\b(bench_\w+)\.py")


def _git(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=60)


def _scripts(text: str) -> set[str]:
    return set(BENCH.findall(text))


def result_problems(text: str) -> list[str]:
    """What a results page lacks: per section with a table, a bench command and a commit that changed it."""
    sections = re.split(r"^(?=#{2,3} )", text, flags=re.MULTILINE)[1:]
    problems = []
    for section in sections:
        title = section.splitlines()[0]
        if not any(line.startswith("|") for line in section.splitlines()):
            continue
        scripts, hashes = _scripts(section), set(HASH.findall(section))
        if not scripts or not hashes:
            problems.append(f"{title}: names no bench command or no commit")
        for digest in sorted(hashes):
            changed = _git("show", "--name-only", "--format=", digest)
            if changed.returncode != 0:
                problems.append(f"{title}: commit {digest} does not exist")
            elif not {Path(f).stem for f in changed.stdout.split()} & scripts:
                problems.append(f"{title}: commit {digest} changed none of {sorted(scripts)}")
        if title.startswith("## Summary"):
            for row in [line for line in section.splitlines() if line.startswith("|")][2:]:
                if not (_scripts(row) and HASH.search(row)):
                    problems.append(f"Summary row without command or commit: {row[:80]}")
    return problems


@pytest.fixture
def git_checkout() -> None:
    if not (ROOT / ".git").exists() or _git("rev-parse", "HEAD").returncode != 0:
        pytest.skip("not a git checkout")


def test_every_result_names_its_command_and_commit(git_checkout: None) -> None:
    """Each results section with numbers names the bench command and the commit of the script that printed them;
    each Summary row names both; each cited commit exists and changed one of the bench scripts it is cited for."""
    text = RESULTS.read_text(encoding="utf-8")
    assert len(re.findall(r"^#{2,3} ", text, re.MULTILINE)) >= 10
    problems = result_problems(text)
    assert not problems, "docs/results.md:\n" + "\n".join(problems)


def test_the_results_check_catches_each_gap(git_checkout: None) -> None:
    """The control: a section without a command, a commit that never touched the script, one that does not exist."""
    good = "## A\n\n`python bench/bench_convert.py` (bench commit `ca859c1`)\n\n| x |\n|---|\n| 1 |\n"
    assert result_problems(good) == []
    assert "names no bench command" in result_problems("## A\n\n| x |\n|---|\n| 1 |\n")[0]
    assert "changed none of" in result_problems(good.replace("ca859c1", "f1c94e4"))[0]
    assert "does not exist" in result_problems(good.replace("ca859c1", "0000000"))[0]


DOCS = ROOT / "docs"
#: Paths the docs use as examples of a user's files, not files of this repository.
ILLUSTRATIVE_PATHS = {"project/controllers/inverted_pendulum/inverted_pendulum.py"}


def _doc_pages() -> list[Path]:
    return [p for p in sorted(DOCS.rglob("*.md")) if p != DOCS / "reference" / "cli.md"]  # cli.md is generated


def test_every_module_and_source_file_the_docs_name_exists() -> None:
    """A module moved or a function renamed must not leave a docs page naming the old one."""
    missing = []
    for page in _doc_pages():
        text = page.read_text(encoding="utf-8")
        where = page.relative_to(ROOT)
        for dotted in sorted(dotted_names(text)):
            if not resolves(dotted):
                missing.append(f"{where}: {dotted}")
        for path in sorted(set(re.findall(r"(?<![\w./-])((?:[\w-]+/)*\w+\.py)\b", text)) - ILLUSTRATIVE_PATHS):
            candidates = [ROOT / path, ROOT / "src" / path, ROOT / "src" / "dualtwin" / path, ROOT / "bench" / path]
            if not any(c.is_file() for c in candidates):
                missing.append(f"{where}: {path}")
    assert not missing, "docs name modules or files that do not exist:\n" + "\n".join(missing)


def test_the_name_check_resolves_modules_and_attributes() -> None:
    assert resolves("dualtwin.twins.base.Twin") and resolves("dualtwin.suite.runner")
    assert not resolves("dualtwin.twins.base.NoSuchName") and not resolves("dualtwin.no_such_package")
    assert dotted_names("see dualtwin.knobs/1, \"dualtwin.x\" and `dualtwin.twins.make_twin`; "
                        "from dualtwin.twins import Twin, TWINS as T") \
        == {"dualtwin.twins", "dualtwin.twins.make_twin", "dualtwin.twins.Twin", "dualtwin.twins.TWINS"}
