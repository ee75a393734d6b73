"""PROTO resolution: where the file of a PROTO ``Name`` is found, and parsing it once per world.

Resolution order for a PROTO ``Name`` (declared by ``EXTERNPROTO "url"`` in the file using it):

1. a relative (or absolute / ``file://``) url, resolved against the declaring file;
2. ``Name.proto`` in the world's ``protos/`` folder and in ``../protos`` (Webots project layout);
3. ``Name.proto`` in the user folders: ``proto_paths`` then ``$DUALTWIN_PROTO_PATH`` (os.pathsep list),
   searched recursively;
4. with ``$WEBOTS_HOME`` set: ``webots://projects/...`` and
   ``https://raw.githubusercontent.com/cyberbotics/webots/<version>/projects/...`` urls map to
   ``$WEBOTS_HOME/projects/...``;
5. a remote url (``http(s)``, ``webots://`` at the R2023b tag, or relative inside a remote PROTO) already
   fetched: our verified cache, a mirror folder, Webots' own asset cache (:mod:`.proto_cache`);
6. our stand-ins (:mod:`dualtwin.webots.standins`) for Floor, RectangleArena, TexturedBackground and
   TexturedBackgroundLight;
7. a remote url downloaded into the cache, as Webots downloads it on load (unless offline);
8. a PROTO still missing is skipped with a warning when it is known to be visual only (appearances,
   backgrounds); anything else raises :class:`ProtoNotFoundError`.

Stand-ins rank below a fetched file (``dualtwin webots fetch`` makes the real one win) but above the
network, so a world whose only remote PROTOs have stand-ins loads without a connection attempt.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dualtwin.errors import DualtwinError
from dualtwin.webots.nodes import SourceLocation
from dualtwin.webots.parser import ParsedProto, decode_source, parse_proto
from dualtwin.webots.proto_cache import CacheCorruptError, FetchError, ProtoCache, remote_url
from dualtwin.webots.standins import STANDIN_PREFIX, STANDIN_PROTOS

__all__ = ["FoundProto", "ProtoError", "ProtoNotFoundError", "ProtoResolver"]

_RAW_GITHUB = re.compile(r"https?://raw\.githubusercontent\.com/cyberbotics/webots/[^/]+/(.+)")


class ProtoError(DualtwinError):
    """A PROTO could not be expanded (template failure, recursion, unsupported Lua template...)."""


class ProtoNotFoundError(ProtoError):
    """A PROTO used by a world or PROTO file was found nowhere on the search path."""


@dataclass(frozen=True)
class FoundProto:
    """A PROTO located by :meth:`ProtoResolver.find`."""

    path: str  # file path, or STANDIN_PREFIX + name for a stand-in
    text: str | None = None  # stand-in text


class ProtoResolver:
    """Finds and caches PROTO files for one world.

    Args:
        world_path: the world file; its ``protos/`` and ``../protos`` folders are searched first.
        proto_paths: user folders, searched (recursively) after the project folders.
        use_env: also read ``DUALTWIN_PROTO_PATH``, ``WEBOTS_HOME`` and the PROTO cache settings.
        cache: where remote urls are looked up and downloaded; default: the user's cache configured by the
            environment (:class:`~dualtwin.webots.proto_cache.ProtoCache`), none without ``use_env``.
    """

    def __init__(
        self,
        world_path: Path | None,
        proto_paths: Sequence[str | os.PathLike[str]] = (),
        *,
        use_env: bool = True,
        cache: ProtoCache | None = None,
    ) -> None:
        self.use_env = use_env
        self._cache = cache
        self.project_dirs: list[Path] = []
        if world_path is not None:
            wdir = world_path.parent
            self.project_dirs = [wdir / "protos", wdir.parent / "protos"]
        self.user_dirs = [Path(p) for p in proto_paths]
        env_paths = os.environ.get("DUALTWIN_PROTO_PATH", "") if use_env else ""
        self.user_dirs += [Path(p) for p in env_paths.split(os.pathsep) if p]
        home = os.environ.get("WEBOTS_HOME", "") if use_env else ""
        self.webots_home = Path(home) if home else None
        self._index: dict[Path, dict[str, Path]] = {}
        self._parsed: dict[str, ParsedProto] = {}

    def _dir_index(self, directory: Path) -> dict[str, Path]:
        if directory not in self._index:
            index: dict[str, Path] = {}
            if directory.is_dir():
                for root, dirs, files in os.walk(directory):
                    dirs.sort()
                    for name in sorted(files):
                        if name.endswith(".proto"):
                            index.setdefault(name[:-6], Path(root) / name)
            self._index[directory] = index
        return self._index[directory]

    def webots_path(self, url: str) -> Path | None:
        """Map a ``webots://`` or raw.githubusercontent Webots url into ``$WEBOTS_HOME``."""
        if self.webots_home is None:
            return None
        rel: str | None = None
        if url.startswith("webots://"):
            rel = url[len("webots://") :]
        else:
            m = _RAW_GITHUB.match(url)
            if m:
                rel = m.group(1)
        if rel is None or ".." in Path(rel).parts:
            return None
        return self.webots_home / rel

    @property
    def cache(self) -> ProtoCache | None:
        """The PROTO cache, created from the environment on first use (``None`` without ``use_env``)."""
        if self._cache is None and self.use_env:
            self._cache = ProtoCache()
        return self._cache

    def find(
        self, name: str, url: str | None, declaring_dir: Path | None, declaring_url: str | None = None
    ) -> tuple[FoundProto | None, list[str]]:
        """Locate ``name``; returns the hit (or None) and the list of places tried.

        ``declaring_url`` is the url of the remote PROTO holding the declaration (relative urls join it).

        Raises:
            CacheCorruptError: a cached copy no longer matches the hash recorded at its fetch.
        """
        tried: list[str] = []
        remote = remote_url(url, declaring_url) if url is not None else None
        is_local = url is not None and remote is None and ("://" not in url or url.startswith("file://"))
        if url is not None and is_local:
            local = Path(url[len("file://") :] if url.startswith("file://") else url)
            if not local.is_absolute() and declaring_dir is not None:
                local = declaring_dir / local
            if not local.name.endswith(".proto"):
                # a world is data: a declaration of /etc/passwd read that file (and quoted its first line in the
                # parse error); Webots' PROTOs are .proto files, whatever folder they are in
                tried.append(f"{local} (not a .proto file: not read)")
            else:
                tried.append(str(local))
                if local.is_file():
                    return FoundProto(str(local)), tried
        elif url is None and declaring_dir is not None and declaring_url is None:
            local = declaring_dir / f"{name}.proto"
            tried.append(str(local))
            if local.is_file():
                return FoundProto(str(local)), tried
        for directory in [*self.project_dirs, *self.user_dirs]:
            tried.append(f"{directory}/**/{name}.proto")
            hit = self._dir_index(directory).get(name)
            if hit is not None:
                return FoundProto(str(hit)), tried
        if url is not None:
            mapped = self.webots_path(url)
            if mapped is not None:
                tried.append(str(mapped))
                if mapped.is_file():
                    return FoundProto(str(mapped)), tried
            elif self.webots_home is None and (url.startswith("webots://") or _RAW_GITHUB.match(url)):
                tried.append("$WEBOTS_HOME (not set)")
        cache = self.cache if remote is not None else None
        if remote is not None and cache is not None:
            hit = cache.cached(remote)
            tried.append(f"{remote} in {cache.describe()}")
            if hit is not None:
                return FoundProto(remote, cache.read_text(remote)), tried
        if name in STANDIN_PROTOS:
            return FoundProto(STANDIN_PREFIX + name + ".proto", STANDIN_PROTOS[name]), tried
        if remote is not None and cache is not None:
            try:
                cache.get(remote)
            except CacheCorruptError:
                raise
            except FetchError as exc:
                tried.append(str(exc))
            else:
                return FoundProto(remote, cache.read_text(remote)), tried
        elif remote is not None:
            tried.append(f"{remote} (no PROTO cache: remote urls are not fetched)")
        return None, tried

    def load(self, found: FoundProto, location: SourceLocation) -> ParsedProto:
        """Parse (once) the PROTO file found by :meth:`find`."""
        if found.path not in self._parsed:
            if found.text is not None:
                text = found.text
            else:
                try:
                    data = Path(found.path).read_bytes()
                except OSError as exc:
                    raise ProtoError(f"{location}: cannot read PROTO file {found.path}: {exc}") from None
                text = decode_source(data, found.path)
            self._parsed[found.path] = parse_proto(text, found.path)
        return self._parsed[found.path]
