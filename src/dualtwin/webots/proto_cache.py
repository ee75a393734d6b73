"""Remote PROTO files (and the assets bounding objects need) in a verified cache, as Webots keeps them.

Decisions, and why:

- **Keys.** A cached file is named by the SHA-1 hex of its exact url, the way Webots names the files of its
  own asset cache. The url carries the Webots version tag (``.../cyberbotics/webots/R2023b/...``), so files of
  two releases never mix; the ``v1`` folder under the cache root versions our layout itself.
- **Where.** ``$DUALTWIN_PROTO_CACHE``, else ``$XDG_CACHE_HOME/dualtwin/protos``, else
  ``~/.cache/dualtwin/protos``. A file ``<key>`` is written atomically, then ``<key>.json`` records its url,
  size and SHA-256 at the first fetch.
- **Verified on every read.** A released url is immutable, so a cached file whose hash differs from the one
  recorded at its first fetch is corrupt or was changed: that is an error naming the url and the file, never
  a silent re-download.
- **Webots' own cache is read too.** Webots keeps downloads flat in ``<cache>/Cyberbotics/Webots/assets/
  <sha1(url)>`` (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux). A file found there is copied into our cache on
  first use, which records its hash from then on.
- **Offline clusters.** ``dualtwin webots fetch --out FOLDER`` writes a folder in our layout.
  ``DUALTWIN_PROTO_MIRROR`` set to such a folder makes the runtime read it (verified, not copied); set to an
  ``http(s)`` base url, it stands for ``https://raw.githubusercontent.com/cyberbotics/webots/`` (so the mirror
  serves ``<base>/R2023b/projects/...``) and official urls are downloaded from it, still cached under their
  official url. ``DUALTWIN_PROTO_OFFLINE=1`` forbids the network altogether.
- **Downloads** go through httpx with connect/read timeouts, a deadline on each whole download (300 s),
  ``http``/``https`` only, at most 5 redirects and a size limit (16 MiB for a PROTO, 128 MiB for a mesh). Failed
  downloads store nothing.
- **Nothing fetched is executed.** A PROTO is parsed as data; only its own JavaScript template runs, in QuickJS
  with time and memory limits and no module loading (:mod:`dualtwin.webots.protos`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import urljoin, urlsplit

from dualtwin.artifacts import atomic_open, sha256_file, write_json
from dualtwin.errors import DualtwinError
from dualtwin.webots.parser import decode_source

__all__ = [
    "LAYOUT",
    "OFFICIAL_PREFIX",
    "WEBOTS_VERSION",
    "CacheCorruptError",
    "FetchError",
    "ProtoCache",
    "cache_key",
    "default_cache_root",
    "is_remote",
    "remote_url",
    "shown_url",
    "webots_assets_dir",
]

#: The Webots release this runtime follows; ``webots://`` urls in worlds resolve to its tag.
WEBOTS_VERSION = "R2023b"
OFFICIAL_PREFIX = "https://raw.githubusercontent.com/cyberbotics/webots/"
#: Layout version of our cache folder.
LAYOUT = "v1"
PROTO_MAX_BYTES = 16 * 1024 * 1024
ASSET_MAX_BYTES = 128 * 1024 * 1024
#: Seconds one download may take in all: a 128 MiB mesh at under 0.5 MiB/s. httpx's timeouts are per read, so a
#: server sending one byte every few seconds kept ``webots fetch`` waiting forever (found by fuzzing with a hostile
#: loopback server).
DOWNLOAD_DEADLINE_S = 300.0
#: Longer urls are refused where they are declared (httpx's own limit is 65536; no real url comes near this).
MAX_URL_LENGTH = 4096
_OFFICIAL = re.compile(r"https://raw\.githubusercontent\.com/cyberbotics/webots/([A-Za-z0-9_+-]+)/(.+)")
_TRUE = {"1", "true", "yes", "on"}


class FetchError(DualtwinError):
    """A remote file could not be fetched (network, HTTP status, size limit, offline)."""


class CacheCorruptError(FetchError):
    """A cached file no longer matches the hash recorded when it was fetched."""


def is_remote(url: str) -> bool:
    return url.startswith(("http://", "https://"))


def remote_url(url: str, parent: str | None = None, version: str = WEBOTS_VERSION) -> str | None:
    """The absolute url a declaration stands for, or None when it names a local file.

    ``webots://path`` becomes the official url at the parent's release tag (an official remote parent) or at
    ``version``; a relative url inside a remote file is joined to that file's url. Webots refuses the last two
    for non-official remote parents (a known Webots limitation); we resolve them the obvious way.

    Raises:
        FetchError: a remote file declares a url that is neither relative nor ``http(s)``/``webots``, or the url
            is not one that can be downloaded (malformed, control characters, too long).
    """
    if is_remote(url):
        return _checked_url(url)
    if url.startswith("webots://"):
        tag = version
        if parent is not None:
            m = _OFFICIAL.match(parent)
            if m:
                tag = m.group(1)
        return _checked_url(f"{OFFICIAL_PREFIX}{tag}/{url[len('webots://'):].lstrip('/')}")
    if parent is not None and is_remote(parent):
        try:
            joined = urljoin(parent, url)
        except ValueError as exc:  # "Invalid IPv6 URL"
            raise FetchError(f"{shown_url(parent)}: declares {shown_url(url)}, not a valid url ({exc})") from None
        if not is_remote(joined):
            raise FetchError(f"{shown_url(parent)}: declares {shown_url(url)}; a remote file may only refer to "
                             "http(s) urls")
        return _checked_url(joined)
    return None


def shown_url(url: str) -> str:
    """``url`` for a one-line message: quoted with control characters escaped, long ones shortened."""
    return repr(url if len(url) <= 200 else url[:200] + "...")


def _checked_url(url: str) -> str:
    """``url`` if the downloader can request it. A url comes from an untrusted world or PROTO: one httpx cannot
    parse (a NUL, a newline, ``http://[::1``, a malformed IDNA host, 70k characters) was a traceback at the
    download, so it is refused here, where it is declared, by the same parser the download uses."""
    import httpx

    if len(url) > MAX_URL_LENGTH:
        raise FetchError(f"{shown_url(url)}: a url of {len(url)} characters; at most {MAX_URL_LENGTH}")
    try:
        _ = httpx.URL(url).host  # .host decodes an IDNA host (xn--...), which can fail too
    except (httpx.InvalidURL, ValueError) as exc:  # idna's errors are UnicodeErrors
        raise FetchError(f"{shown_url(url)}: not a valid url ({exc})") from None
    return url


def cache_key(url: str) -> str:
    """SHA-1 hex of the exact url, the name Webots' asset cache gives the file."""
    return hashlib.sha1(url.encode("utf-8")).hexdigest()


def _xdg_cache_home() -> Path:
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    # the XDG spec says relative values are invalid and must be ignored
    return Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache"


def default_cache_root() -> Path:
    """``$DUALTWIN_PROTO_CACHE`` or ``<XDG cache>/dualtwin/protos``."""
    explicit = os.environ.get("DUALTWIN_PROTO_CACHE", "")
    return Path(explicit) if explicit else _xdg_cache_home() / "dualtwin" / "protos"


def webots_assets_dir() -> Path:
    """Where Webots (R2022b+) keeps downloaded assets on Linux."""
    return _xdg_cache_home() / "Cyberbotics" / "Webots" / "assets"


def _say(message: str) -> None:
    print(message, file=sys.stderr)


class ProtoCache:
    """Finds remote files in caches and mirrors, or downloads them, and verifies every file it returns.

    Args:
        root: the writable cache root (default :func:`default_cache_root`).
        mirror: a folder in our layout or an http(s) base url (default ``$DUALTWIN_PROTO_MIRROR``).
        offline: never download (default ``$DUALTWIN_PROTO_OFFLINE``).
        sources: more read-only roots in our layout, read before downloading (``fetch --out`` passes the
            user's cache here so a folder for a cluster is filled without the network where possible).
        webots_assets: Webots' flat asset cache; ``None`` skips it (default :func:`webots_assets_dir`).
        copy_sources: copy hits from read-only roots into ``root`` (``fetch`` wants a complete root; a
            runtime reading a mirror folder does not).
        progress: called with one line per download or import (default: print on stderr).
        timeout: seconds allowed to connect and between received bytes.
        deadline: seconds one download may take in all (a server that sends a byte now and then, within
            ``timeout``, never ends otherwise).
        use_env: read the environment for unset arguments.
    """

    def __init__(
        self,
        root: Path | None = None,
        *,
        mirror: str | None = None,
        offline: bool | None = None,
        sources: Sequence[Path] = (),
        webots_assets: Path | None | bool = True,
        copy_sources: bool = False,
        progress: Callable[[str], None] | None = _say,
        timeout: float = 20.0,
        deadline: float = DOWNLOAD_DEADLINE_S,
        use_env: bool = True,
    ) -> None:
        env = os.environ if use_env else {}
        self.root = Path(root) if root is not None else default_cache_root()
        if mirror is None:
            mirror = env.get("DUALTWIN_PROTO_MIRROR", "") or None
        self.mirror_url: str | None = None
        self.sources = [Path(s) for s in sources]
        if mirror is not None:
            if is_remote(mirror):
                self.mirror_url = mirror if mirror.endswith("/") else mirror + "/"
            elif Path(mirror).is_dir():
                self.sources.insert(0, Path(mirror))
            else:
                raise FetchError(f"DUALTWIN_PROTO_MIRROR {mirror}: neither a folder nor an http(s) base url")
        if offline is None:
            offline = env.get("DUALTWIN_PROTO_OFFLINE", "").strip().lower() in _TRUE
        self.offline = offline
        if webots_assets is True:
            self.webots_assets: Path | None = webots_assets_dir()
        elif webots_assets is False or webots_assets is None:
            self.webots_assets = None
        else:
            self.webots_assets = Path(webots_assets)
        self.copy_sources = copy_sources
        self.progress = progress
        self.timeout = timeout
        self.deadline = deadline
        self._client: Any = None
        self._verified: dict[str, Path] = {}

    # -- reading

    def _entry(self, root: Path, url: str) -> Path | None:
        key = cache_key(url)
        data = root / LAYOUT / key
        meta_path = root / LAYOUT / f"{key}.json"
        if not (data.is_file() and meta_path.is_file()):
            return None  # absent, or a write interrupted before its record: fetch again
        try:
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
            recorded_url, size, digest = meta["url"], int(meta["size"]), str(meta["sha256"])
        except (OSError, ValueError, KeyError, TypeError, OverflowError) as exc:  # ("size": 1e999 overflows int())
            raise CacheCorruptError(
                f"{url}: the cache record {meta_path} is unreadable ({exc}); delete it and {data} to fetch again"
            ) from None
        if recorded_url != url:
            raise CacheCorruptError(f"{url}: the cache record {meta_path} is for another url ({recorded_url})")
        try:
            actual_size = data.stat().st_size
            actual = sha256_file(data) if actual_size == size else ""
        except OSError as exc:
            raise CacheCorruptError(f"{url}: cannot read the cached copy {data}: {exc.strerror or exc}") from None
        if actual != digest:
            raise CacheCorruptError(
                f"{url}: the cached copy {data} does not match the SHA-256 recorded when it was fetched "
                f"(corrupt or changed); delete {data} to download it again"
            )
        return data

    def cached(self, url: str) -> Path | None:
        """The verified local copy of ``url`` from our cache, a mirror folder or Webots' cache; no network.

        Raises:
            CacheCorruptError: a copy exists but does not match its record.
        """
        hit = self._verified.get(url)
        if hit is not None:
            return hit
        path = self._entry(self.root, url)
        if path is None:
            for source in self.sources:
                found = self._entry(source, url)
                if found is not None:
                    path = self._store(url, found.read_bytes(), f"copied {url} from {source}") if (
                        self.copy_sources) else found
                    break
        if path is None and self.webots_assets is not None:
            flat = self.webots_assets / cache_key(url)
            if flat.is_file():
                try:
                    path = self._store(url, flat.read_bytes(), f"imported {url} from Webots' cache {flat}")
                except (FetchError, OSError):
                    path = flat  # our cache is not writable: read Webots' copy as it is
        if path is not None:
            self._verified[url] = path
        return path

    def get(self, url: str, *, asset: bool = False) -> Path:
        """The verified local copy of ``url``, downloaded into the cache if needed.

        Raises:
            CacheCorruptError: a cached copy does not match its record.
            FetchError: not cached, and offline or the download failed (the message names the url).
        """
        hit = self.cached(url)
        if hit is not None:
            return hit
        if not is_remote(url):
            raise FetchError(f"{url}: not an http(s) url")
        if self.offline:
            raise FetchError(f"{url}: not in the PROTO cache {self.root} and downloads are off (DUALTWIN_PROTO_OFFLINE)")
        source = self.source_url(url)
        data = self._download(url, source, ASSET_MAX_BYTES if asset else PROTO_MAX_BYTES)
        via = f" via {source}" if source != url else ""
        path = self._store(url, data, f"downloaded {url}{via} ({len(data)} bytes)")
        self._verified[url] = path
        return path

    def read_text(self, url: str) -> str:
        """A fetched PROTO's bytes as text (decoding errors name the url)."""
        return decode_source(self.get(url).read_bytes(), url)

    # -- downloading and storing

    def describe(self) -> str:
        """Where :meth:`cached` looks, for messages."""
        places = [f"the PROTO cache {self.root}"] + [f"the folder {s}" for s in self.sources]
        if self.webots_assets is not None:
            places.append(f"Webots' cache {self.webots_assets}")
        return ", ".join(places)

    def source_url(self, url: str) -> str:
        """Where ``url`` is downloaded from: the mirror for official Webots urls, else itself."""
        if self.mirror_url is not None and url.startswith(OFFICIAL_PREFIX):
            return self.mirror_url + url[len(OFFICIAL_PREFIX) :]
        return url

    def _download(self, url: str, source: str, limit: int) -> bytes:
        import httpx

        if urlsplit(source).scheme not in ("http", "https"):
            raise FetchError(f"{url}: cannot download from {source} (http and https only)")
        if self._client is None:
            self._client = httpx.Client(
                timeout=httpx.Timeout(self.timeout, connect=min(self.timeout, 10.0)),
                follow_redirects=True,
                max_redirects=5,
                headers={"User-Agent": "dualtwin-proto-fetch"},
            )
        where = f"{url}" + (f" (from {source})" if source != url else "")
        try:
            with self._client.stream("GET", source) as response:
                if response.status_code != 200:
                    raise FetchError(f"cannot download {where}: HTTP {response.status_code} {response.reason_phrase}")
                declared = response.headers.get("content-length")
                if declared is not None and declared.isdigit() and int(declared) > limit:
                    raise FetchError(f"cannot download {where}: {declared} bytes exceeds the {limit}-byte limit")
                buf = bytearray()
                give_up = time.monotonic() + self.deadline
                for chunk in response.iter_bytes():
                    buf += chunk
                    if len(buf) > limit:
                        raise FetchError(f"cannot download {where}: more than the {limit}-byte limit")
                    if time.monotonic() > give_up:
                        raise FetchError(f"cannot download {where}: not complete after {self.deadline:g} s "
                                         f"({len(buf)} bytes so far)")
        # a redirect's Location is the server's: httpx reports a bad one as InvalidURL or (its IDNA host) as a
        # UnicodeError, neither an HTTPError
        except (httpx.HTTPError, httpx.InvalidURL, ValueError) as exc:
            raise FetchError(f"cannot download {where}: {type(exc).__name__}: {exc}") from None
        return bytes(buf)

    def _store(self, url: str, data: bytes, message: str) -> Path:
        key = cache_key(url)
        folder = self.root / LAYOUT
        path = folder / key
        try:
            with atomic_open(path, "wb") as handle:
                handle.write(data)
            write_json(folder / f"{key}.json", {
                "url": url, "size": len(data), "sha256": hashlib.sha256(data).hexdigest(),
            })
        except OSError as exc:
            raise FetchError(f"{url}: cannot write the PROTO cache {folder}: {exc.strerror or exc}") from None
        if self.progress is not None:
            self.progress(message)
        return path

    def entries(self) -> list[dict[str, Any]]:
        """Records of every file in the writable root, sorted by url."""
        folder = self.root / LAYOUT
        out = []
        for meta in sorted(folder.glob("*.json")) if folder.is_dir() else []:
            try:
                out.append(json.loads(meta.read_text(encoding="utf-8")))
            except (OSError, ValueError):
                continue
        return sorted(out, key=lambda m: str(m.get("url", "")))

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

