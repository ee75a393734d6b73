"""Tests of PROTO resolution and expansion (IS, derived and procedural PROTOs, stand-ins, search path)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dualtwin.webots import ProtoNotFoundError, WebotsSyntaxError, load_world, load_world_text
from dualtwin.webots.nodes import Node, tree_equal
from dualtwin.webots.proto_resolver import ProtoError
from dualtwin.webots.writer import write_world

HEADER = "#VRML_SIM R2023b utf8\n"

# Our own test double with the documented Pioneer 3-AT facts (not the Webots file).
PIONEER_DOUBLE = """#VRML_SIM R2023b utf8
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
      DEF BACK_LEFT_WHEEL HingeJoint {
        jointParameters HingeJointParameters { axis 0 1 0 anchor -0.1331 0.197 0.11 }
        device [ RotationalMotor { name "back left wheel" maxVelocity 6.4 maxTorque 20 } ]
        endPoint Solid {
          translation -0.1331 0.197 0.11
          name "back left wheel"
          boundingObject DEF BOUNDING_WHEEL Pose {
            rotation 1 0 0 1.5708
            children [ Cylinder { radius 0.11 height 0.095 } ]
          }
          physics DEF WHEEL_PHYSICS Physics { density -1 mass 0.8 }
        }
      }
      DEF BACK_RIGHT_WHEEL HingeJoint {
        jointParameters HingeJointParameters { axis 0 1 0 anchor -0.1331 -0.197 0.11 }
        device [ RotationalMotor { name "back right wheel" maxVelocity 6.4 maxTorque 20 } ]
        endPoint Solid {
          translation -0.1331 -0.197 0.11
          name "back right wheel"
          boundingObject USE BOUNDING_WHEEL
          physics USE WHEEL_PHYSICS
        }
      }
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

SICK_DOUBLE = """#VRML_SIM R2023b utf8
PROTO SickLms291 [
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


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def proto(name: str, interface: str, body: str) -> str:
    return f"{HEADER}PROTO {name} [\n{interface}\n]\n{{\n{body}\n}}\n"


@pytest.fixture(autouse=True)
def _clean_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DUALTWIN_PROTO_PATH", raising=False)
    monkeypatch.delenv("WEBOTS_HOME", raising=False)


# --------------------------------------------------------------------------------------------
# fixture worlds


def test_inverted_pendulum_loads_with_floor_standin(webots_fixtures: Path) -> None:
    w = load_world(webots_fixtures / "inverted_pendulum.wbt")
    assert [n.type_name for n in w.nodes] == ["WorldInfo", "Viewpoint", "Background", "Solid", "Robot"]
    floor = w.nodes[3]
    assert floor.proto_name == "Floor" and floor["name"] == "floor" and floor["contactMaterial"] == "default"
    assert floor["boundingObject"].type_name == "Plane" and floor["physics"] is None
    assert floor["boundingObject"]["size"] == (1000.0, 2.0)
    assert floor.location is not None and floor.location.line == 28
    hip = w.find_def("HIP")
    assert hip is not None and hip["jointParameters"]["axis"] == (0.0, 1.0, 0.0)
    info = w.world_info()
    assert info is not None and info["contactProperties"][0]["coulombFriction"] == [0.2]
    assert w.warnings == []


def test_four_wheels_loads_with_rectangle_arena(webots_fixtures: Path) -> None:
    w = load_world(webots_fixtures / "four_wheels.wbt")
    arena = next(n for n in w.nodes if n.proto_name == "RectangleArena")
    assert arena.type_name == "Solid" and arena["boundingObject"].type_name == "Plane"
    assert arena["boundingObject"]["size"] == (3.0, 3.0)
    walls = [c for c in arena.children() if c.type_name == "Solid"]
    assert len(walls) == 4 and all(wall["physics"] is None for wall in walls)
    assert {wall["translation"] for wall in walls} == {
        (1.505, 0.0, 0.05), (-1.505, 0.0, 0.05), (0.0, 1.505, 0.05), (0.0, -1.505, 0.05)
    }
    assert walls[0]["boundingObject"]["size"] == (0.01, 3.02, 0.1)
    robots = [n for n in w.nodes if n.type_name == "Robot"]
    assert len(robots) == 3
    info = w.world_info()
    assert info is not None and info["basicTimeStep"] == 16.0


def test_pioneer_world_without_model_names_it(webots_fixtures: Path) -> None:
    with pytest.raises(ProtoNotFoundError) as info:
        load_world(webots_fixtures / "pioneer3at.wbt")
    msg = str(info.value)
    assert "PROTO 'Pioneer3at'" in msg
    assert re.search(r"pioneer3at\.wbt:387:17: ", msg)
    assert "webots://projects/robots/adept/pioneer3/protos/Pioneer3at.proto" in msg
    assert "protos/**/Pioneer3at.proto" in msg and "$WEBOTS_HOME (not set)" in msg


def test_pioneer_world_with_user_proto_folder(webots_fixtures: Path, tmp_path: Path) -> None:
    write(tmp_path / "robots" / "Pioneer3at.proto", PIONEER_DOUBLE)
    write(tmp_path / "devices" / "SickLms291.proto", SICK_DOUBLE)
    w = load_world(webots_fixtures / "pioneer3at.wbt", proto_paths=[tmp_path])
    robot = w.find_def("PIONEER_3AT")
    assert robot is not None and robot.type_name == "Robot" and robot.proto_name == "Pioneer3at"
    assert robot["controller"] == "pioneer3at_obstacle_avoidance_with_lidar"
    assert robot["rotation"] == (0.0, 0.0, 1.0, -0.25) and robot["name"] == "Pioneer 3-AT"
    lidar = next(n for n in robot.walk() if n.type_name == "Lidar")
    assert lidar.proto_name == "SickLms291" and lidar["translation"] == (0.136, 0.0, 0.35)
    wheels = [n for n in robot.walk() if n.type_name == "HingeJoint"]
    assert [j.proto_def_name for j in wheels] == ["BACK_LEFT_WHEEL", "BACK_RIGHT_WHEEL"]
    assert all(j.def_name is None for j in wheels)  # PROTO-internal DEFs are not world DEFs
    assert w.find_def("BACK_LEFT_WHEEL") is None
    right = wheels[1]["endPoint"]
    assert right["physics"]["mass"] == 0.8 and right["physics"].use_name == "WHEEL_PHYSICS"
    assert right["boundingObject"].children()[0]["radius"] == 0.11
    assert any("SandyGround" in m and "visual only" in m for m in w.warnings)
    arena = next(n for n in w.nodes if n.proto_name == "RectangleArena")
    assert arena.children()[0]["appearance"] is None  # skipped SandyGround appearance
    assert len([n for n in w.nodes if n.type_name == "Solid" and n["name"].startswith("obstacle")]) == 40


def test_missing_device_proto_is_named(webots_fixtures: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write(tmp_path / "Pioneer3at.proto", PIONEER_DOUBLE)
    monkeypatch.setenv("DUALTWIN_PROTO_PATH", str(tmp_path))  # env folders work like proto_paths
    with pytest.raises(ProtoNotFoundError, match=r"pioneer3at\.wbt:391:5: PROTO 'SickLms291'"):
        load_world(webots_fixtures / "pioneer3at.wbt")


# --------------------------------------------------------------------------------------------
# expansion semantics

BOX_PROTO = proto(
    "MyBox",
    """  field SFVec3f translation 0 0 0
  field SFVec3f size 0.1 0.2 0.3
  field SFColor color 1 0 0
  field SFNode physics Physics { mass 2 }
  field MFNode extra []""",
    """  Solid {
    translation IS translation
    children [
      DEF SHAPE Shape {
        appearance PBRAppearance { baseColor IS color }
        geometry Box { size IS size }
      }
      Group { children IS extra }
    ]
    boundingObject USE SHAPE
    physics IS physics
  }""",
)


def test_is_defaults_overrides_and_copies(tmp_path: Path) -> None:
    write(tmp_path / "protos" / "MyBox.proto", BOX_PROTO)
    w = load_world(
        write(
            tmp_path / "w.wbt",
            HEADER + 'EXTERNPROTO "../protos/MyBox.proto"\n'
            "DEF A MyBox { size 1 1 1 extra [ DEF INNER Pose { } ] }\n"
            "MyBox { translation 0 0 1 physics NULL }\n",
        )
    )
    a, b = w.nodes
    assert a.type_name == "Solid" and a.proto_name == "MyBox" and a.def_name == "A"
    assert a.children()[0]["geometry"]["size"] == (1.0, 1.0, 1.0)
    assert a.children()[0]["appearance"]["baseColor"] == (1.0, 0.0, 0.0)
    assert a["boundingObject"]["geometry"]["size"] == (1.0, 1.0, 1.0)
    assert a["physics"]["mass"] == 2.0  # SFNode default expanded
    assert b["physics"] is None and b["translation"] == (0.0, 0.0, 1.0)
    assert a.children()[0].proto_def_name == "SHAPE" and a.children()[0].def_name is None
    assert w.find_def("INNER") is a.children()[1].children()[0]  # world-scope DEF kept through IS
    a["physics"].fields["mass"] = 5.0
    assert b["physics"] is None and a.proto_fields is not None
    assert list(a.proto_fields) == ["translation", "size", "color", "physics", "extra"]


def test_derived_proto_and_def_scopes(tmp_path: Path) -> None:
    write(tmp_path / "protos" / "MyBox.proto", BOX_PROTO)
    write(
        tmp_path / "protos" / "BigBox.proto",
        HEADER
        + 'EXTERNPROTO "MyBox.proto"\nPROTO BigBox [\n  field SFVec3f translation 0 0 0\n  field SFFloat k 3\n]\n'
        "{\n  MyBox { translation IS translation size 2 2 2 color 0 0 1 }\n}\n",
    )
    w = load_world(
        write(
            tmp_path / "worlds" / "w.wbt",
            HEADER + 'EXTERNPROTO "../protos/BigBox.proto"\nDEF SHAPE Shape { }\n'
            "DEF BIG BigBox { translation 1 2 3 }\nBigBox { }\nPose { children [ USE SHAPE ] }\n",
        )
    )
    big = w.nodes[1]
    assert big.proto_name == "BigBox" and big.def_name == "BIG" and big.type_name == "Solid"
    assert big["translation"] == (1.0, 2.0, 3.0)
    assert big.children()[0]["appearance"]["baseColor"] == (0.0, 0.0, 1.0)
    assert big.children()[0]["geometry"]["size"] == (2.0, 2.0, 2.0)
    assert w.find_def("SHAPE") is w.nodes[0]  # PROTO bodies' DEF SHAPE do not shadow the world's
    used = w.nodes[3].children()[0]
    assert used.use_name == "SHAPE" and used["geometry"] is None  # the world's empty Shape, not MyBox's


def test_proto_errors_are_located(tmp_path: Path) -> None:
    write(tmp_path / "protos" / "MyBox.proto", BOX_PROTO)
    w = tmp_path / "w.wbt"

    def err(body: str) -> str:
        write(w, HEADER + 'EXTERNPROTO "protos/MyBox.proto"\n' + body)
        with pytest.raises((WebotsSyntaxError, ProtoError)) as info:
            load_world(w)
        return str(info.value)

    msg = err("MyBox { sise 1 1 1 }")
    assert msg.startswith(f"{w}:3:9: expected a field of PROTO MyBox (translation, size, color, physics, extra)")
    assert err("MyBox { size 1 1 }").startswith(f"{w}:3:14: expected SFVec3f (3 numbers), found 2 numbers")
    assert "found USE of MyBox (a Solid) 'A'" in err("DEF A MyBox { }\nGroup { children [ USE A ] }")
    bad_is = proto("BadIs", "  field SFVec2f s 1 1", "  Box { size IS s }")
    write(tmp_path / "protos" / "BadIs.proto", bad_is)
    assert re.search(r"BadIs\.proto:6:14: expected IS to a field of type SFVec3f, found 's' of type SFVec2f", err("BadIs { }"))
    write(tmp_path / "protos" / "Loop.proto", proto("Loop", "", "  Group { children [ Loop { } ] }"))
    assert "instantiates itself" in err("Loop { }")
    write(tmp_path / "protos" / "Wrong.proto", proto("Other", "", "  Group { }"))
    assert "expected PROTO Wrong (as the file name says), found PROTO Other" in err("Wrong { }")


def test_unknown_visual_proto_skipped_other_rejected(tmp_path: Path) -> None:
    w = load_world_text(
        HEADER + 'EXTERNPROTO "https://example.org/protos/Parquetry.proto"\n'
        "Shape { appearance Parquetry { } }\n",
        tmp_path / "w.wbt",
    )
    assert w.nodes[0]["appearance"] is None and "Parquetry" in w.warnings[0]
    with pytest.raises(ProtoNotFoundError, match=r"w\.wbt:2:1: PROTO 'Table' \(no EXTERNPROTO declares it\)"):
        load_world_text(HEADER + "Table { }\n", tmp_path / "w.wbt")


def test_hidden_fields_override_proto_body(tmp_path: Path) -> None:
    write(tmp_path / "Pioneer3at.proto", PIONEER_DOUBLE)
    w = load_world_text(
        HEADER + 'EXTERNPROTO "Pioneer3at.proto"\n'
        "DEF P Pioneer3at {\n  hidden position_0_0 1.5\n  hidden rotation_1 0 1 0 1.5\n"
        "  hidden linearVelocity_0 0.1 0 0\n  hidden position_0_7 2\n  translation 0 0 0.1\n}\n",
        tmp_path / "w.wbt",
    )
    robot = w.nodes[0]
    assert robot.hidden["position_0_0"] == 1.5 and robot.hidden["rotation_1"] == (0.0, 1.0, 0.0, 1.5)
    joints = [n for n in robot.walk() if n.type_name == "HingeJoint"]
    assert joints[0]["jointParameters"]["position"] == 1.5 and joints[1]["jointParameters"]["position"] == 0.0
    assert joints[0]["endPoint"]["rotation"] == (0.0, 1.0, 0.0, 1.5)
    assert robot["linearVelocity"] == (0.1, 0.0, 0.0) and robot["translation"] == (0.0, 0.0, 0.1)
    assert any("position_0_7" in m for m in w.warnings)
    again = load_world_text(write_world(w))  # hidden values survive a write/read cycle
    assert tree_equal(again.nodes[0], robot)


def test_field_restrictions_fall_back_to_default(tmp_path: Path) -> None:
    write(tmp_path / "R.proto", proto("R", '  field SFString{"a", "b"} mode "a"', "  Solid { name IS mode }"))
    w = load_world_text(HEADER + 'EXTERNPROTO "R.proto"\nR { mode "b" }\nR { mode "zzz" }\n', tmp_path / "w.wbt")
    assert [n["name"] for n in w.nodes] == ["b", "a"]
    assert "not one of the values allowed" in w.warnings[0]


# --------------------------------------------------------------------------------------------
# procedural PROTOs

BOXES_PROTO = """#VRML_SIM R2023b utf8
# template language: javascript
PROTO Boxes [
  field SFInt32    count  3
  field SFVec3f    size   0.1 0.1 0.1
  field SFColor    color  0 1 0
  field SFRotation tilt   0 0 1 0.5
  field SFVec2f    step   0.5 0
  field MFFloat    heights [ 1 2 ]
  field SFNode     physics Physics { mass 1 }
  field SFString   label  "a`b${c}\\\\d"
]
{
  %<
    import * as wbgeometry from 'wbgeometry.js';
    import * as v3 from 'wbvector3.js';
    const n = fields.count.value;
    const s = fields.size.value;
    if (fields.color.value.g !== 1 || fields.tilt.value.a !== 0.5) throw new Error('conversion');
    if (fields.heights.value.length !== 2 || fields.count.defaultValue !== 3) throw new Error('mf');
    if (fields.physics.value.node_name !== 'Physics') throw new Error('node');
    if (context.coordinate_system !== 'ENU' || context.webots_version.major !== 'R2023b') throw new Error('ctx');
    const pts = wbgeometry.circle(1, 4);
    const len = v3.norm({x: 3, y: 4, z: 0});
  >%
  Group {
    children [
      %< for (let i = 0; i < n; ++i) { >%
      Solid {
        translation %<= i * fields.step.value.x >% 0 %<= s.z / 2 >%
        name "box %<= i >%"
        description "raw `chunk` with ${braces} and \\"quotes\\" \\\\ kept"
        model "%<= len >% %<= pts.length >%"
        boundingObject Box { size %<= s.x >% %<= s.y >% %<= s.z >% }
        physics IS physics
      }
      %< } >%
    ]
  }
}
"""


def test_procedural_proto_generates_boxes(tmp_path: Path) -> None:
    write(tmp_path / "protos" / "Boxes.proto", BOXES_PROTO)
    w = load_world_text(
        HEADER + 'EXTERNPROTO "../protos/Boxes.proto"\nDEF B Boxes { count 4 size 1 2 3 physics Physics { mass 3 } }\n'
        "Boxes { }\n",
        tmp_path / "worlds" / "w.wbt",
    )
    group, default = w.nodes
    assert group.type_name == "Group" and group.proto_name == "Boxes" and group.def_name == "B"
    boxes = group.children()
    assert len(boxes) == 4 and len(default.children()) == 3
    assert [b["translation"] for b in boxes] == [(i * 0.5, 0.0, 1.5) for i in range(4)]
    assert [b["name"] for b in boxes] == ["box 0", "box 1", "box 2", "box 3"]
    assert boxes[0]["boundingObject"]["size"] == (1.0, 2.0, 3.0)
    assert all(b["physics"]["mass"] == 3.0 for b in boxes)
    assert boxes[0]["description"] == 'raw `chunk` with ${braces} and "quotes" \\ kept'
    assert boxes[0]["model"] == "5 4"


def test_procedural_proto_js_error_and_lua(tmp_path: Path) -> None:
    write(tmp_path / "Bad.proto", proto("Bad", "", "  %< throw new Error('boom'); >%\n  Group { }"))
    with pytest.raises(ProtoError, match=r"w\.wbt:3:1: template of PROTO Bad .*failed: Error: boom$"):
        load_world_text(HEADER + 'EXTERNPROTO "Bad.proto"\nBad { }\n', tmp_path / "w.wbt")
    write(tmp_path / "Lua.proto", proto("Lua", "  field SFInt32 n 1", "  %{ for i = 1, fields.n.value do }%\n  Group { }\n  %{ end }%"))
    with pytest.raises(ProtoError, match=r"PROTO Lua .*legacy Lua template"):
        load_world_text(HEADER + 'EXTERNPROTO "Lua.proto"\nLua { }\n', tmp_path / "w.wbt")
    write(tmp_path / "Open.proto", proto("Open", "", "  %< const x = 1;\n  Group { }"))
    with pytest.raises(ProtoError, match=r"Open\.proto:6:3: expected '>%'"):
        load_world_text(HEADER + 'EXTERNPROTO "Open.proto"\nOpen { }\n', tmp_path / "w.wbt")


def test_missing_quickjs_names_the_proto(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write(tmp_path / "Boxes.proto", BOXES_PROTO)
    monkeypatch.setitem(sys.modules, "quickjs", None)  # makes `import quickjs` fail
    with pytest.raises(ProtoError, match=r"PROTO Boxes is procedural .*'quickjs' package"):
        load_world_text(HEADER + 'EXTERNPROTO "Boxes.proto"\nBoxes { }\n', tmp_path / "w.wbt")


# --------------------------------------------------------------------------------------------
# search path


def test_webots_home_urls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    home = tmp_path / "webots"
    write(home / "projects" / "objects" / "floors" / "protos" / "Floor.proto",
          proto("Floor", "  field SFVec2f size 2 2", "  Solid { name \"real floor\" boundingObject Plane { size IS size } }"))
    write(home / "projects" / "objects" / "misc" / "protos" / "Crate.proto",
          proto("Crate", "", '  Solid { name "crate" }'))
    world = (
        HEADER
        + 'EXTERNPROTO "webots://projects/objects/floors/protos/Floor.proto"\n'
        + 'EXTERNPROTO "https://raw.githubusercontent.com/cyberbotics/webots/R2023b/projects/objects/misc/protos/Crate.proto"\n'
        + "Floor { size 5 5 }\nCrate { }\n"
    )
    standin = load_world_text(world.replace("Crate { }\n", ""), tmp_path / "w.wbt")
    assert standin.nodes[0]["name"] == "floor"  # no WEBOTS_HOME: our stand-in
    monkeypatch.setenv("WEBOTS_HOME", str(home))
    w = load_world_text(world, tmp_path / "w.wbt")
    assert w.nodes[0]["name"] == "real floor" and w.nodes[0]["boundingObject"]["size"] == (5.0, 5.0)
    assert w.nodes[1]["name"] == "crate"
    assert w.nodes[1].location is not None and w.nodes[1].location.line == 5


def test_search_order_project_before_user(tmp_path: Path) -> None:
    write(tmp_path / "project" / "protos" / "Thing.proto", proto("Thing", "", '  Solid { name "project" }'))
    write(tmp_path / "user" / "deep" / "Thing.proto", proto("Thing", "", '  Solid { name "user" }'))
    write(tmp_path / "user" / "Other.proto", proto("Other", "", '  Solid { name "other" }'))
    world = write(
        tmp_path / "project" / "worlds" / "w.wbt",
        HEADER + 'EXTERNPROTO "webots://projects/x/Thing.proto"\nEXTERNPROTO "webots://y/Other.proto"\n'
        "Thing { }\nOther { }\n",
    )
    w = load_world(world, proto_paths=[tmp_path / "user"])
    assert [n["name"] for n in w.nodes] == ["project", "other"]


def test_relative_externproto_inside_proto(tmp_path: Path) -> None:
    write(tmp_path / "lib" / "parts" / "Wheel.proto", proto("Wheel", "  field SFFloat r 0.1", "  Cylinder { radius IS r }"))
    write(
        tmp_path / "lib" / "Car.proto",
        HEADER + 'EXTERNPROTO "parts/Wheel.proto"\nPROTO Car [ field SFFloat wheelRadius 0.3 ]\n'
        "{ Shape { geometry Wheel { r IS wheelRadius } } }\n",
    )
    w = load_world_text(HEADER + 'EXTERNPROTO "lib/Car.proto"\nCar { }\n', tmp_path / "w.wbt")
    assert w.nodes[0]["geometry"]["radius"] == 0.3 and w.nodes[0]["geometry"].proto_name == "Wheel"


# --------------------------------------------------------------------------------------------
# fuzzing expansion: only our ValueError subclasses may escape

_FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@_FUZZ
@given(
    st.lists(st.tuples(st.integers(0, 400), st.integers(0, 6), st.sampled_from(
        ["", " ", "{", "}", "[", "]", "IS ", "USE SHAPE ", "DEF X ", "1 ", '"s" ', "NULL ", "%<", ">%", "0x", "-"]
    )), max_size=4)
)
def test_fuzz_proto_expansion(tmp_path_factory: pytest.TempPathFactory, edits: list[tuple[int, int, str]]) -> None:
    text = BOX_PROTO
    for pos, cut, insert in edits:
        pos = min(pos, len(text))
        text = text[:pos] + insert + text[pos + cut :]
    folder = tmp_path_factory.mktemp("fz")
    write(folder / "MyBox.proto", text)
    try:
        w = load_world_text(HEADER + 'EXTERNPROTO "MyBox.proto"\nMyBox { size 1 2 3 }\n', folder / "w.wbt")
    except (WebotsSyntaxError, ProtoError):
        return
    assert all(isinstance(n, Node) for n in w.nodes)
