"""``webots fetch`` against hostile input: urls the downloader cannot parse, and a server that never finishes.

Found by fuzzing ``dualtwin webots fetch`` with a hostile loopback server. Each case here was a traceback or a
hang before; each must be one :class:`FetchError` naming the declaration.
"""

from __future__ import annotations

import http.server
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from dualtwin.webots.fetch import fetch_worlds
from dualtwin.webots.proto_cache import FetchError, ProtoCache

HEADER = "#VRML_SIM R2023b utf8\n"


class _Hostile(http.server.BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib signature
        pass

    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        try:
            if self.path == "/drip.proto":
                # a byte every 50 ms, well within any read timeout, for 20 s: without a deadline on the whole
                # download the client waits for all of it (a real hostile server never stops)
                self.send_response(200)
                self.end_headers()
                self.wfile.write(HEADER.encode())
                for _ in range(400):
                    self.wfile.write(b"#")
                    self.wfile.flush()
                    time.sleep(0.05)
                return
            body = {
                "/bad-join.proto": HEADER + 'EXTERNPROTO "http://[::1"\nPROTO A [ ]\n{ Solid { } }\n',
                "/bad-host-redirect.proto": None,
            }.get(self.path)
            if self.path == "/bad-host-redirect.proto":
                self.send_response(302)
                self.send_header("Location", "http://xn--.proto/A.proto")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            data = (body or "").encode()
            self.send_response(200 if body else 404)
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client gave up, as it should


@pytest.fixture
def hostile() -> Iterator[str]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Hostile)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def _world(tmp_path: Path, url: str) -> Path:
    world = tmp_path / "w.wbt"
    world.write_bytes((HEADER + f'EXTERNPROTO "{url}"\nWorldInfo {{ }}\n').encode("utf-8"))
    return world


@pytest.mark.parametrize("url", [
    "http://127.0.0.1:1/a\x00b.proto",  # httpx.InvalidURL: non-printable character
    "http://[::1",  # ValueError: Invalid IPv6 URL (urlsplit)
    "http://xn--.proto/A.proto",  # idna.IDNAError: a malformed A-label
    "http://127.0.0.1:1/" + "a" * 70_000 + ".proto",  # httpx.InvalidURL: URL too long
], ids=["nul", "ipv6", "idna", "long"])
def test_a_url_the_downloader_cannot_parse_is_refused_where_it_is_declared(tmp_path: Path, url: str) -> None:
    cache = ProtoCache(tmp_path / "cache", progress=None, offline=False, use_env=False)
    with pytest.raises(FetchError) as info:
        fetch_worlds([_world(tmp_path, url)], cache)
    message = str(info.value)
    assert "w.wbt:2:1: EXTERNPROTO" in message and "\n" not in message and len(message) < 1000
    assert not (tmp_path / "cache").exists()


def test_bad_urls_inside_a_served_proto_and_its_redirects_are_refused(tmp_path: Path, hostile: str) -> None:
    cache = ProtoCache(tmp_path / "cache", progress=None, offline=False, use_env=False)
    with pytest.raises(FetchError, match=r"bad-join.proto:2:1: EXTERNPROTO 'http://\[::1'.*not a valid url"):
        fetch_worlds([_world(tmp_path, f"{hostile}/bad-join.proto")], cache)
    with pytest.raises(FetchError, match="bad-host-redirect.proto.*cannot download"):
        fetch_worlds([_world(tmp_path, f"{hostile}/bad-host-redirect.proto")], cache)


def test_a_download_that_never_finishes_is_given_up(tmp_path: Path, hostile: str) -> None:
    cache = ProtoCache(tmp_path / "cache", progress=None, offline=False, use_env=False, deadline=0.5)
    with pytest.raises(FetchError, match=r"drip.proto.*not complete after 0.5 s"):
        fetch_worlds([_world(tmp_path, f"{hostile}/drip.proto")], cache)
    cache.close()
    assert not list((tmp_path / "cache").rglob("*.proto*"))  # a failed download stores nothing


@pytest.mark.skipif(not Path("/proc/self/mem").is_file(), reason="needs Linux's /proc")
def test_a_local_externproto_that_cannot_be_read_is_named(tmp_path: Path) -> None:
    """Before, only the OS's words came out ("error: Input/output error"), naming no file."""
    from dualtwin.errors import DualtwinError

    cache = ProtoCache(tmp_path / "cache", progress=None, offline=True, use_env=False)
    (tmp_path / "Mem.proto").symlink_to("/proc/self/mem")  # a file that exists and cannot be read, even by root
    with pytest.raises(DualtwinError, match=r"w.wbt:2:1: EXTERNPROTO .*Mem.proto: cannot read it: "):
        fetch_worlds([_world(tmp_path, str(tmp_path / "Mem.proto"))], cache)
