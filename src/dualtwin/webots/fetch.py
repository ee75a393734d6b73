"""Pre-fetch everything a world needs from the network: ``dualtwin webots fetch WORLD... [--out FOLDER]``.

What is fetched, following what Webots downloads when it loads a world:

- every ``EXTERNPROTO`` and ``IMPORTABLE EXTERNPROTO`` the world declares with a remote url (``http(s)``, or
  ``webots://`` at the R2023b tag), and, transitively, every remote PROTO those files declare (relative urls
  join the declaring file's url). Local PROTO files are read for their own declarations but not copied;
- the mesh files the twin reads: the remote ``url`` of every ``Mesh`` (bounding objects for collisions and
  mass, Shapes for cameras, lidars and range finders) and every ``CadShape`` of the expanded world. Textures
  and sounds are never fetched (nothing here draws a texture or plays a sound).

The world is then expanded from the fetched files (offline) to prove it loads; its warnings are returned.
Errors stop the command at the first url that cannot be fetched, naming it and the declaration.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dualtwin.artifacts import check_input_file, check_output_dir, write_json
from dualtwin.errors import DualtwinError
from dualtwin.webots.nodes import Node
from dualtwin.webots.parser import ExternProto, decode_source, parse_proto, parse_world
from dualtwin.webots.proto_cache import (
    LAYOUT,
    WEBOTS_VERSION,
    FetchError,
    ProtoCache,
    default_cache_root,
    is_remote,
    remote_url,
    shown_url,
)

__all__ = ["MESH_NODES", "PROTO_FOLDER_KIND", "FetchReport", "fetch_command", "fetch_worlds"]

PROTO_FOLDER_KIND = "proto-cache"

#: More distinct files than any real world declares: stops a hostile PROTO chain that never ends.
MAX_FILES = 5000


@dataclass
class FetchReport:
    """What ``fetch_worlds`` made available."""

    protos: list[str] = field(default_factory=list)  # remote PROTO urls, in discovery order
    assets: list[str] = field(default_factory=list)  # remote mesh urls of the Mesh and CadShape nodes
    warnings: list[str] = field(default_factory=list)  # warnings of loading each world afterwards


def _declarations(
    externs: Sequence[ExternProto], parent_url: str | None, local_dir: Path | None, where: str
) -> list[tuple[ExternProto, str | None, Path | None, str]]:
    return [(e, parent_url, local_dir, where) for e in externs]


def fetch_worlds(
    worlds: Sequence[str | os.PathLike[str]],
    cache: ProtoCache,
    proto_paths: Sequence[str | os.PathLike[str]] = (),
) -> FetchReport:
    """Fetch every remote file the worlds need into ``cache`` (see the module docstring).

    Raises:
        DualtwinError: a world or local PROTO cannot be read or parsed.
        FetchError: a url could not be fetched (the message names it and where it is declared).
    """
    from dualtwin.webots.proto_resolver import ProtoResolver
    from dualtwin.webots.protos import expand_world

    report = FetchReport()
    seen: set[str] = set()
    for world in worlds:
        path = Path(world)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise DualtwinError(f"{path}: cannot read world: {exc.strerror or exc}") from None
        parsed = parse_world(data, str(path))
        queue = _declarations(parsed.externprotos, None, path.parent, str(path))
        while queue:
            ext, parent_url, local_dir, where = queue.pop(0)
            try:
                url = remote_url(ext.url, parent_url)
            except FetchError as exc:
                raise FetchError(f"{ext.location}: EXTERNPROTO {shown_url(ext.url)}: {exc}") from None
            if url is None:  # a local file: follow its declarations, nothing to fetch
                local = Path(ext.url[len("file://") :] if ext.url.startswith("file://") else ext.url)
                if not local.is_absolute() and local_dir is not None:
                    local = local_dir / local
                key = str(local.resolve())
                if key in seen or not local.is_file() or not local.name.endswith(".proto"):
                    continue  # a missing (or not a .proto) local file is reported when the world loads
                seen.add(key)
                try:
                    source = local.read_bytes()
                except OSError as exc:  # (a special file: /proc/self/mem said only "Input/output error")
                    raise DualtwinError(f"{ext.location}: EXTERNPROTO {local}: cannot read it: "
                                        f"{exc.strerror or exc}") from None
                proto = parse_proto(decode_source(source, str(local)), str(local))
                queue += _declarations(proto.externprotos, None, local.parent, str(local))
                continue
            if url in seen:
                continue
            seen.add(url)
            if len(seen) > MAX_FILES:
                raise FetchError(f"{ext.location}: more than {MAX_FILES} PROTO files declared; stopped")
            try:
                text = cache.read_text(url)
            except FetchError as exc:
                raise FetchError(f"{ext.location}: EXTERNPROTO {shown_url(ext.url)}: {exc}") from None
            report.protos.append(url)
            proto = parse_proto(text, url)
            queue += _declarations(proto.externprotos, url, None, url)
        resolver = ProtoResolver(path, proto_paths, cache=cache)
        loaded = expand_world(parsed, path, proto_paths, resolver=resolver)
        report.warnings += loaded.warnings
        for url, location, kind in _mesh_urls(loaded.nodes):
            if url in seen:
                continue
            seen.add(url)
            try:
                cache.get(url, asset=True)
            except FetchError as exc:
                raise FetchError(f"{location}: {kind} url: {exc}") from None
            report.assets.append(url)
    return report


#: The nodes whose ``url`` is a mesh file the twin reads.
MESH_NODES = ("Mesh", "CadShape")


def _mesh_urls(nodes: Sequence[Node]) -> list[tuple[str, str, str]]:
    """Remote urls of every Mesh and CadShape (in bounding objects, Shapes and children alike), with where each
    is written and its node type, in scene order."""
    out: list[tuple[str, str, str]] = []
    for top in nodes:
        for node in top.walk():
            if node.type_name not in MESH_NODES:
                continue
            origin = node.location.file if node.location is not None else ""
            origin = origin.removesuffix("[generated]")
            for entry in node.fields.get("url", []) or []:
                try:
                    url = remote_url(str(entry), origin if is_remote(origin) else None)
                except FetchError as exc:
                    raise FetchError(f"{node.location}: {node.type_name} url: {exc}") from None
                if url is not None:
                    out.append((url, str(node.location), node.type_name))
    return out


def fetch_command(
    worlds: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str] | None = None,
    say: Callable[[str], None] | None = None,
) -> tuple[FetchReport, Path]:
    """``dualtwin webots fetch``: fill the user's cache, or the folder ``out`` for an offline machine.

    ``out`` becomes a cache root of its own with a ``manifest.json`` (kind ``proto-cache``) listing every
    file with its SHA-256; it is filled from the user's cache and mirror where possible, then the network.
    Running the command again on the same folder adds to it. Returns the report and the root written.

    Raises:
        DualtwinError: bad ``out`` folder, unreadable world, or a url that cannot be fetched.
    """
    for world in worlds:
        check_input_file(Path(world), "world")
    fresh = existed = False
    if out is None:
        cache = ProtoCache(copy_sources=True, progress=say)
    else:
        root = Path(out)
        existed = root.exists()
        fresh = not check_output_dir(root, PROTO_FOLDER_KIND, resume=True, resumable=True)  # absent or empty
        _refuse_links(root)
        # a folder for an offline machine must hold every file, wherever it was found here
        cache = ProtoCache(root, sources=[default_cache_root()], copy_sources=True, progress=say)
        # first, so an interrupted fetch leaves a folder the next one continues; "complete" says it is not done
        _write_manifest(cache, complete=False)
    try:
        report = fetch_worlds(worlds, cache)
    except BaseException as exc:
        cache.close()
        if out is not None:
            if fresh and not cache.entries():
                # nothing was fetched: a refusal leaves the folder as it found it (absent, or empty)
                _remove_empty_fetch(cache.root, keep_root=existed)
            else:
                _write_manifest(cache, complete=False, error=str(exc) or type(exc).__name__)
        raise
    cache.close()
    if out is not None:
        _write_manifest(cache, complete=True)
    return report, cache.root


def _refuse_links(root: Path) -> None:
    """Refuse a fetch folder in which the cache folder (``v1``), the manifest or a cached file is a symbolic link.

    A folder from an earlier fetch is continued, so what it holds is followed: files were written through a
    ``v1`` link into wherever it pointed, a linked cached file was read as a fetched copy, and a linked manifest
    decided what kind of folder this is. The folder is refused before anything is written (a link is the user's
    to remove; nothing here deletes it)."""
    folder = root / LAYOUT
    links = [path for path in (folder, root / "manifest.json") if path.is_symlink()]
    if not links and folder.is_dir():
        links = sorted(path for path in folder.iterdir() if path.is_symlink())
    if links:
        raise DualtwinError(f"--out {root}: {links[0]} is a symbolic link; a fetch folder holds only the files "
                            "fetch wrote there (a link would be written through or read as a fetched copy)")


def _write_manifest(cache: ProtoCache, *, complete: bool, error: str | None = None) -> None:
    record: dict[str, Any] = {
        "kind": PROTO_FOLDER_KIND,
        "layout": LAYOUT,
        "webots_version": WEBOTS_VERSION,
        "usage": "export DUALTWIN_PROTO_MIRROR=<this folder>",
        # false until every url of every world was fetched: a folder whose fetch failed or was interrupted is
        # not a complete mirror (run the same command again to finish it)
        "complete": complete,
        "files": cache.entries(),
    }
    if error is not None:
        record["error"] = error
    write_json(cache.root / "manifest.json", record)


def _remove_empty_fetch(root: Path, *, keep_root: bool) -> None:
    """Delete what a fetch that fetched nothing wrote: its manifest and empty folders (``root`` too, unless it
    was there before)."""
    (root / "manifest.json").unlink(missing_ok=True)
    for folder in sorted((p for p in root.rglob("*") if p.is_dir()), key=lambda p: len(p.parts), reverse=True):
        if not any(folder.iterdir()):
            folder.rmdir()
    if not keep_root and root.is_dir() and not any(root.iterdir()):
        root.rmdir()
