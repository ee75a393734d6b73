"""EXTERNPROTO fetching into a verified cache, offline reuse and ``webots fetch`` (issue 16.1).

Every test serves PROTO files from a real HTTP server on loopback. The served files are our own test doubles
(Webots' PROTO files may not be copied into this project) laid out as in Webots' repository under a
``R2023b/`` folder; ``DUALTWIN_PROTO_MIRROR`` points official urls at the server. Fixture worlds from
``../shared/fixtures/webots`` are copied beside them.
"""

from __future__ import annotations

import hashlib
import http.server
import json
import os
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from functools import partial
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.webots import load_world
from dualtwin.webots.fetch import fetch_command, fetch_worlds
from dualtwin.webots.physics import Simulation
from dualtwin.webots.proto_cache import (
    OFFICIAL_PREFIX,
    CacheCorruptError,
    FetchError,
    ProtoCache,
    cache_key,
    remote_url,
)
from dualtwin.webots.proto_resolver import ProtoNotFoundError
from dualtwin.webots.standins import STANDIN_PROTOS
from tests.support.mesh_writers import ascii_stl, box_triangles

OFFICIAL = OFFICIAL_PREFIX + "R2023b/"
HEADER = "#VRML_SIM R2023b utf8\n"

SANDY = HEADER + """PROTO SandyGround [
  field SFColor colorOverride 1 1 1
  field SFNode textureTransform NULL
]
{
  PBRAppearance { baseColor IS colorOverride roughness 1 metalness 0 }
}
"""

TIRE = HEADER + """PROTO TireRubber [ ]
{
  PBRAppearance { baseColor 0.1 0.1 0.1 roughness 1 metalness 0 }
}
"""

# Relative url -> joined to the Pioneer3at url; it declares TireRubber by webots:// -> the parent's tag.
WHEEL = HEADER + """EXTERNPROTO "webots://projects/appearances/protos/TireRubber.proto"
PROTO Pioneer3atWheel [
  field SFVec3f anchor 0 0 0
  field SFString name "wheel"
]
{
  HingeJoint {
    jointParameters HingeJointParameters { axis 0 1 0 anchor IS anchor }
    device [ RotationalMotor { name IS name maxVelocity 6.4 maxTorque 20 } ]
    endPoint Solid {
      translation IS anchor
      name IS name
      children [ Shape { appearance TireRubber { } geometry DEF TIRE Cylinder { radius 0.11 height 0.095 } } ]
      boundingObject Pose { rotation 1 0 0 1.5708 children [ Cylinder { radius 0.11 height 0.095 } ] }
      physics Physics { density -1 mass 0.8 }
    }
  }
}
"""

PIONEER = HEADER + """EXTERNPROTO "Pioneer3atWheel.proto"
PROTO Pioneer3at [
  field SFVec3f    translation   0 0 0
  field SFRotation rotation      0 0 1 0
  field SFString   name          "Pioneer 3-AT"
  field SFString   controller    "<generic>"
  field MFString   controllerArgs []
  field SFBool     supervisor    FALSE
  field MFNode     extensionSlot []
]
{
  Robot {
    translation IS translation
    rotation IS rotation
    children [
      Pioneer3atWheel { anchor -0.1331 0.197 0.11 name "back left wheel" }
      Pioneer3atWheel { anchor -0.1331 -0.197 0.11 name "back right wheel" }
      Pioneer3atWheel { anchor 0.1331 0.197 0.11 name "front left wheel" }
      Pioneer3atWheel { anchor 0.1331 -0.197 0.11 name "front right wheel" }
      Pose { translation 0 0 0.2 children IS extensionSlot }
    ]
    name IS name
    model "Adept Pioneer 3-AT"
    controller IS controller
    controllerArgs IS controllerArgs
    supervisor IS supervisor
    boundingObject Pose { translation 0 0 0.173 children [ Box { size 0.402 0.197 0.2 } ] }
    physics Physics { density -1 mass 8.8 }
  }
}
"""

SICK = HEADER + """PROTO SickLms291 [
  field SFVec3f translation 0 0 0
  field SFRotation rotation 0 0 1 0
  field SFString name "Sick LMS 291"
]
{
  Lidar {
    translation IS translation
    rotation IS rotation
    name IS name
    boundingObject Box { size 0.15 0.15 0.2 }
    physics Physics { density -1 mass 4.5 }
  }
}
"""

# Meshes the twin reads (a bounding object's, a drawn Shape's, a CadShape's) and a texture it never needs.
MESHY = HEADER + """PROTO Meshy [ ]
{
  Solid {
    children [
      Shape {
        appearance PBRAppearance { baseColorMap ImageTexture { url [ "textures/skin.png" ] } }
        geometry Mesh { url [ "meshes/visual.obj" ] }
      }
      CadShape { url [ "meshes/body.dae" ] }
    ]
    boundingObject Mesh { url [ "meshes/hull.obj" ] }
  }
}
"""

SERVED = {
    "projects/objects/backgrounds/protos/TexturedBackground.proto": STANDIN_PROTOS["TexturedBackground"],
    "projects/objects/backgrounds/protos/TexturedBackgroundLight.proto": STANDIN_PROTOS["TexturedBackgroundLight"],
    "projects/objects/floors/protos/Floor.proto": STANDIN_PROTOS["Floor"],
    "projects/objects/floors/protos/RectangleArena.proto": STANDIN_PROTOS["RectangleArena"],
    "projects/appearances/protos/SandyGround.proto": SANDY,
    "projects/appearances/protos/TireRubber.proto": TIRE,
    "projects/robots/adept/pioneer3/protos/Pioneer3at.proto": PIONEER,
    "projects/robots/adept/pioneer3/protos/Pioneer3atWheel.proto": WHEEL,
    "projects/devices/sick/protos/SickLms291.proto": SICK,
    "projects/objects/meshy/protos/Meshy.proto": MESHY,
    "projects/objects/meshy/protos/meshes/hull.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "projects/objects/meshy/protos/meshes/visual.obj": "v 0 0 0\n",
    "projects/objects/meshy/protos/meshes/body.dae": "<COLLADA/>",
    "projects/objects/meshy/protos/meshes/arm.stl": "solid arm\nendsolid arm\n",
    "projects/default/worlds/sounds/bump.wav": "not really a sound",
    "projects/objects/meshy/protos/textures/skin.png": "not really a png",
}


class _Server:
    def __init__(self, root: Path) -> None:
        self.root = root
        self.requests: list[str] = []
        requests = self.requests

        class Handler(http.server.SimpleHTTPRequestHandler):
            def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib signature
                requests.append(self.path)

        class Quiet(http.server.ThreadingHTTPServer):
            def handle_error(self, request: object, client_address: object) -> None:
                pass  # a client that stops reading (the size-limit test) is expected, not a server error

        self.httpd = Quiet(("127.0.0.1", 0), partial(Handler, directory=str(root)))
        self.base = f"http://127.0.0.1:{self.httpd.server_address[1]}/"
        self.thread = threading.Thread(target=self.httpd.serve_forever, args=(0.05,), daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()


@pytest.fixture
def server(tmp_path: Path) -> Iterator[_Server]:
    root = tmp_path / "served"
    for rel, text in SERVED.items():
        path = root / "R2023b" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    srv = _Server(root)
    yield srv
    srv.stop()


@pytest.fixture
def online(server: _Server, monkeypatch: pytest.MonkeyPatch) -> _Server:
    """The runtime's documented configuration: a mirror url and downloads allowed."""
    monkeypatch.setenv("DUALTWIN_PROTO_MIRROR", server.base)
    monkeypatch.delenv("DUALTWIN_PROTO_OFFLINE")
    return server


def _cache_root(cache_home: Path) -> Path:
    return cache_home / "dualtwin" / "protos"


def _copy_world(webots_fixtures: Path, tmp_path: Path, name: str) -> Path:
    dest = tmp_path / "project" / "worlds" / name
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(webots_fixtures / name, dest)
    return dest


def test_remote_url_resolution() -> None:
    parent = OFFICIAL + "projects/robots/x/protos/X.proto"
    assert remote_url("webots://projects/a/A.proto") == OFFICIAL + "projects/a/A.proto"
    other_tag = OFFICIAL_PREFIX + "R2022b/projects/robots/x/protos/X.proto"
    assert remote_url("webots://projects/a/A.proto", other_tag) == OFFICIAL_PREFIX + "R2022b/projects/a/A.proto"
    assert remote_url("../../y/protos/Y.proto", parent) == OFFICIAL + "projects/robots/y/protos/Y.proto"
    assert remote_url("Sub.proto", None) is None  # local beside the declaring file
    with pytest.raises(FetchError, match="only refer to http"):
        remote_url("file:///etc/Evil.proto", parent)


def test_world_downloads_transitively_then_loads_offline(
    webots_fixtures: Path, tmp_path: Path, online: _Server, monkeypatch: pytest.MonkeyPatch,
    _isolated_proto_cache: Path,
) -> None:
    world = _copy_world(webots_fixtures, tmp_path, "pioneer3at.wbt")
    first = load_world(world)
    assert first.warnings == []
    robot = first.find_def("PIONEER_3AT")
    assert robot is not None and robot.location is not None
    wheels = [n for n in robot.walk() if n.type_name == "HingeJoint"]
    assert len(wheels) == 4 and wheels[0]["endPoint"]["physics"]["mass"] == 0.8
    # the served files were used, not our stand-ins: locations name the official urls
    arena = next(n for n in first.nodes if n.proto_name == "RectangleArena")
    assert arena.location is not None
    tire = wheels[0]["endPoint"].children()[0]["appearance"]
    assert tire.proto_name == "TireRubber"
    assert any(loc.file == OFFICIAL + "projects/appearances/protos/TireRubber.proto" for loc in tire.field_locations.values())
    fetched = {p.removeprefix("/R2023b/") for p in online.requests}
    assert "projects/robots/adept/pioneer3/protos/Pioneer3atWheel.proto" in fetched  # relative, transitive
    assert "projects/appearances/protos/TireRubber.proto" in fetched  # webots:// inside a remote PROTO
    # Floor/RectangleArena have stand-ins, so loading never asks the network for them
    assert "projects/objects/floors/protos/RectangleArena.proto" not in fetched
    cache = _cache_root(_isolated_proto_cache) / "v1"
    url = OFFICIAL + "projects/robots/adept/pioneer3/protos/Pioneer3at.proto"
    meta = json.loads((cache / f"{cache_key(url)}.json").read_text())
    assert meta == {"url": url, "size": len(PIONEER.encode()), "sha256": hashlib.sha256(PIONEER.encode()).hexdigest()}

    online.stop()  # offline reuse: the server is gone and downloads are forbidden
    monkeypatch.setenv("DUALTWIN_PROTO_OFFLINE", "1")
    n_requests = len(online.requests)
    again = load_world(world)
    assert again.warnings == [] and len(online.requests) == n_requests
    assert [n.type_name for n in again.nodes] == [n.type_name for n in first.nodes]


def test_offline_without_cache_names_the_url(webots_fixtures: Path, tmp_path: Path) -> None:
    world = _copy_world(webots_fixtures, tmp_path, "pioneer3at.wbt")
    with pytest.raises(ProtoNotFoundError) as info:
        load_world(world)
    message = str(info.value)
    assert "Pioneer3at" in message and "DUALTWIN_PROTO_OFFLINE" in message and "webots fetch" in message


def test_corrupt_or_changed_cache_file_is_an_error_naming_the_url(
    webots_fixtures: Path, tmp_path: Path, online: _Server, _isolated_proto_cache: Path
) -> None:
    world = _copy_world(webots_fixtures, tmp_path, "pioneer3at.wbt")
    load_world(world)
    url = OFFICIAL + "projects/devices/sick/protos/SickLms291.proto"
    cached = _cache_root(_isolated_proto_cache) / "v1" / cache_key(url)
    text = cached.read_text()
    cached.write_text(text.replace("mass 4.5", "mass 9.5"))  # same size, different content
    with pytest.raises(CacheCorruptError) as info:
        load_world(world)
    assert url in str(info.value) and "SHA-256" in str(info.value)
    cached.write_bytes(b"\x00" * 10)  # truncated
    with pytest.raises(CacheCorruptError, match="SickLms291.proto"):
        load_world(world)
    # a record whose size overflows an integer (1e999 reads as infinity): an OverflowError traceback before
    record = cached.with_name(cached.name + ".json")
    record.write_text(record.read_text().replace('"size": ', '"size": 1e999, "was": '))
    with pytest.raises(CacheCorruptError, match=r"SickLms291.proto: the cache record .* is unreadable"):
        load_world(world)


def test_fetch_then_fixture_worlds_load_offline_without_warnings(
    webots_fixtures: Path, tmp_path: Path, online: _Server, monkeypatch: pytest.MonkeyPatch,
) -> None:
    worlds = [_copy_world(webots_fixtures, tmp_path, n) for n in ("inverted_pendulum.wbt", "four_wheels.wbt",
                                                                 "pioneer3at.wbt")]
    out = tmp_path / "for-cluster"
    report, root = fetch_command(worlds, out, say=None)
    assert root == out and report.warnings == []
    assert OFFICIAL + "projects/objects/floors/protos/Floor.proto" in report.protos
    assert OFFICIAL + "projects/robots/adept/pioneer3/protos/Pioneer3atWheel.proto" in report.protos
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["kind"] == "proto-cache" and len(manifest["files"]) == len(report.protos)
    assert all((out / "v1" / cache_key(f["url"])).is_file() for f in manifest["files"])

    # the "cluster": no server, no network, a fresh user cache, only the copied folder
    online.stop()
    monkeypatch.setenv("DUALTWIN_PROTO_OFFLINE", "1")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "fresh-cache"))
    monkeypatch.setenv("DUALTWIN_PROTO_MIRROR", str(out))
    for world in worlds:
        loaded = load_world(world)
        assert loaded.warnings == [], world
        # the fetched real files win over the stand-ins
        floorish = next(n for n in loaded.nodes if n.proto_name in ("Floor", "RectangleArena"))
        assert all(loc.file.startswith(OFFICIAL) for loc in floorish.field_locations.values())
    assert not (tmp_path / "fresh-cache").exists()  # a mirror folder is read in place


def test_every_mesh_and_cad_shape_fetched_textures_and_sounds_not(tmp_path: Path, online: _Server) -> None:
    world = tmp_path / "meshy.wbt"
    # an official https url written out in the world, as Webots R2023b saves them; a webots:// mesh url in a
    # Shape of the world itself; contact sounds (ContactProperties' default bumpSound is a webots url too)
    world.write_text(HEADER + f'EXTERNPROTO "{OFFICIAL}projects/objects/meshy/protos/Meshy.proto"\n'
                     "WorldInfo { contactProperties [ ContactProperties { bumpSound "
                     '"webots://projects/default/worlds/sounds/bump.wav" } ] }\n'
                     'Meshy { }\nSolid { name "arm" children [ Shape { geometry Mesh { url '
                     '"webots://projects/objects/meshy/protos/meshes/arm.stl" } } ] }\n')
    cache = ProtoCache(tmp_path / "cache", progress=None)
    report = fetch_worlds([world], cache)
    meshes = OFFICIAL + "projects/objects/meshy/protos/meshes/"
    assert sorted(report.assets) == [meshes + name for name in ("arm.stl", "body.dae", "hull.obj", "visual.obj")]
    paths = set(online.requests)
    assert {"/R2023b/projects/objects/meshy/protos/meshes/" + n for n in ("hull.obj", "visual.obj", "body.dae")} <= paths
    assert not any("skin.png" in p or ".wav" in p for p in paths)


def test_http_errors_and_size_limit_name_the_url(tmp_path: Path, online: _Server) -> None:
    cache = ProtoCache(tmp_path / "cache", progress=None)
    missing = OFFICIAL + "projects/nothing/Nothing.proto"
    with pytest.raises(FetchError) as info:
        cache.get(missing)
    assert missing in str(info.value) and "HTTP 404" in str(info.value)
    assert not (tmp_path / "cache" / "v1" / cache_key(missing)).exists()  # failures store nothing
    big = online.root / "R2023b" / "big.proto"
    big.write_bytes(b"#" * (17 * 1024 * 1024))
    with pytest.raises(FetchError, match="limit"):
        cache.get(OFFICIAL + "big.proto")


def test_webots_asset_cache_is_read_and_then_verified(
    webots_fixtures: Path, tmp_path: Path, _isolated_proto_cache: Path
) -> None:
    # Webots' own cache: flat files named by sha1(url), beside ours under the XDG cache folder
    assets = _isolated_proto_cache / "Cyberbotics" / "Webots" / "assets"
    assets.mkdir(parents=True)
    for rel in ("robots/adept/pioneer3/protos/Pioneer3at.proto", "robots/adept/pioneer3/protos/Pioneer3atWheel.proto",
                "appearances/protos/TireRubber.proto", "appearances/protos/SandyGround.proto",
                "devices/sick/protos/SickLms291.proto"):
        url = OFFICIAL + "projects/" + rel
        (assets / cache_key(url)).write_text(SERVED["projects/" + rel])
    world = _copy_world(webots_fixtures, tmp_path, "pioneer3at.wbt")
    loaded = load_world(world)  # offline (conftest): everything comes from Webots' cache
    assert loaded.warnings == [] and loaded.find_def("PIONEER_3AT") is not None
    ours = _cache_root(_isolated_proto_cache) / "v1"
    assert len(list(ours.glob("*.json"))) == 5


def test_cli_fetch_into_user_cache_and_bad_out(
    webots_fixtures: Path, tmp_path: Path, online: _Server, monkeypatch: pytest.MonkeyPatch
) -> None:
    world = _copy_world(webots_fixtures, tmp_path, "inverted_pendulum.wbt")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cli-cache"), "DUALTWIN_PROTO_MIRROR": online.base}
    env.pop("DUALTWIN_PROTO_OFFLINE", None)
    cmd = [sys.executable, "-m", "dualtwin.cli", "webots", "fetch"]
    ok = subprocess.run([*cmd, str(world)], capture_output=True, text=True, env=env, timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert "2 PROTO files" in ok.stdout and "downloaded" in ok.stderr
    assert len(list((tmp_path / "cli-cache" / "dualtwin" / "protos" / "v1").glob("*.json"))) == 2
    # offline, from the cache the command filled: the served Floor, not our stand-in, and no warnings
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cli-cache"))
    monkeypatch.setenv("DUALTWIN_PROTO_OFFLINE", "1")
    loaded = load_world(world)
    floor = next(n for n in loaded.nodes if n.proto_name == "Floor")
    assert loaded.warnings == [] and all(loc.file.startswith(OFFICIAL) for loc in floor.field_locations.values())
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("mine")
    bad = subprocess.run([*cmd, str(world), "--out", str(busy)], capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "--out" in bad.stderr
    assert (busy / "notes.txt").read_text() == "mine"


def test_interrupted_fetch_into_a_folder_resumes(tmp_path: Path, online: _Server) -> None:
    world = tmp_path / "two.wbt"
    world.write_text(
        HEADER
        + 'EXTERNPROTO "webots://projects/appearances/protos/TireRubber.proto"\n'
        + 'EXTERNPROTO "webots://projects/later/protos/Later.proto"\n'
        + "Solid { children [ Shape { appearance TireRubber { } } ] }\nLater { }\n"
    )
    out = tmp_path / "folder"
    with pytest.raises(FetchError) as info:
        fetch_command([world], out, say=None)
    assert "two.wbt:3:1" in str(info.value) and "Later.proto" in str(info.value) and "HTTP 404" in str(info.value)
    manifest = json.loads((out / "manifest.json").read_text())
    assert [f["url"] for f in manifest["files"]] == [OFFICIAL + "projects/appearances/protos/TireRubber.proto"]
    assert manifest["complete"] is False and "Later.proto" in manifest["error"]  # not mistaken for a mirror
    later = online.root / "R2023b" / "projects" / "later" / "protos" / "Later.proto"
    later.parent.mkdir(parents=True)
    later.write_text(HEADER + "PROTO Later [ ] { Solid { } }\n")
    report, _ = fetch_command([world], out, say=None)  # the same folder: continued, not refused
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["files"]) == 2 and manifest["complete"] is True and report.warnings == []


@pytest.mark.parametrize("linked", ["v1", "manifest.json", "v1 file"])
def test_a_symbolic_link_in_the_out_folder_is_refused_before_writing(
    tmp_path: Path, online: _Server, linked: str
) -> None:
    """A fetch folder is continued, so a link in it was followed: files were written through a ``v1`` link into
    wherever it pointed (a linked file or manifest was read as the fetch's own). Refused with one line, and
    nothing is written, here or where the link points."""
    world = tmp_path / "one.wbt"
    world.write_text(HEADER + 'EXTERNPROTO "webots://projects/appearances/protos/TireRubber.proto"\n'
                     + "Solid { children [ Shape { appearance TireRubber { } } ] }\n")
    out = tmp_path / "folder"
    fetch_command([world], out, say=None)
    target = {"v1": out / "v1", "manifest.json": out / "manifest.json",
              "v1 file": next(p for p in (out / "v1").iterdir() if p.suffix != ".json")}[linked]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    moved = elsewhere / target.name
    shutil.move(target, moved)
    target.symlink_to(moved)
    # a second world needs one more file: the fetch would store it (and rewrite the manifest)
    world.write_text(HEADER + 'EXTERNPROTO "webots://projects/appearances/protos/TireRubber.proto"\n'
                     + 'EXTERNPROTO "webots://projects/appearances/protos/SandyGround.proto"\n'
                     + "Solid { children [ Shape { appearance TireRubber { } } Shape { appearance SandyGround { } } ] }\n")

    def snapshot() -> dict[str, bytes]:
        return {str(p.relative_to(tmp_path)): p.read_bytes() for root in (out, elsewhere)
                for p in sorted(root.rglob("*")) if p.is_file() and not p.is_symlink()}

    before = snapshot()
    with pytest.raises(DualtwinError) as info:
        fetch_command([world], out, say=None)
    message = str(info.value)
    assert message == (f"--out {out}: {target} is a symbolic link; a fetch folder holds only the files fetch "
                       "wrote there (a link would be written through or read as a fetched copy)")
    assert snapshot() == before and target.is_symlink()


def test_a_fetch_that_fetched_nothing_leaves_nothing(tmp_path: Path, online: _Server) -> None:
    """A failed fetch into a new folder removes it; into the user's empty folder, leaves it empty."""
    world = tmp_path / "missing.wbt"
    world.write_text(HEADER + 'EXTERNPROTO "webots://projects/nowhere/protos/Nowhere.proto"\nNowhere { }\n')
    for out, existed in ((tmp_path / "new", False), (tmp_path / "empty", True)):
        if existed:
            out.mkdir()
        with pytest.raises(FetchError, match="Nowhere.proto"):
            fetch_command([world], out, say=None)
        assert out.exists() == existed and (not existed or not any(out.iterdir()))


def test_mirror_that_is_neither_folder_nor_url_is_named(
    webots_fixtures: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DUALTWIN_PROTO_MIRROR", str(tmp_path / "no-such-folder"))
    with pytest.raises(FetchError, match="DUALTWIN_PROTO_MIRROR .*no-such-folder"):
        load_world(_copy_world(webots_fixtures, tmp_path, "pioneer3at.wbt"))


def test_a_fetched_bounding_mesh_weighs_and_collides_offline_from_the_cache_the_environment_names(
    tmp_path: Path, online: _Server, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``fetch`` fills the cache; the physics then reads the mesh from there with downloads off. Twice in one
    process, each time with another cache folder and another file at the url: the second world must weigh what
    its own cache holds (a cache kept from the first environment would serve the first file)."""
    url = "webots://projects/objects/meshy/protos/meshes/cube.stl"
    world = tmp_path / "project" / "worlds" / "w.wbt"
    world.parent.mkdir(parents=True)
    world.write_text(HEADER + f'WorldInfo {{ basicTimeStep 8 }}\nSolid {{ name "floor" boundingObject Plane {{ }} }}\n'
                     f'Solid {{ translation 0 0 1 boundingObject Mesh {{ url "{url}" }} physics Physics {{ }} }}\n')
    served = online.root / "R2023b" / "projects/objects/meshy/protos/meshes/cube.stl"
    for run, half in enumerate((0.125, 0.25)):
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / f"cache-{run}"))
        monkeypatch.delenv("DUALTWIN_PROTO_OFFLINE", raising=False)
        monkeypatch.setenv("DUALTWIN_PROTO_MIRROR", online.base)
        served.write_text(ascii_stl(box_triangles((-half, -half, -half), (half, half, half))))
        report = fetch_worlds([world], ProtoCache(progress=None))
        assert report.assets == [OFFICIAL + "projects/objects/meshy/protos/meshes/cube.stl"]
        monkeypatch.setenv("DUALTWIN_PROTO_OFFLINE", "1")
        monkeypatch.delenv("DUALTWIN_PROTO_MIRROR")
        sim = Simulation(load_world(world))
        try:
            (body,) = sim.bodies
            assert body.mass == pytest.approx(1000 * (2 * half) ** 3, abs=1e-9)
            sim.step(250)
            assert body.pose().t[2] == pytest.approx(half, abs=1e-2)  # on the floor (soft contact), not through it
        finally:
            sim.close()
