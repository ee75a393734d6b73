"""Tests of the .wbt/.proto parser, the base-node schema and the writer."""

from __future__ import annotations

import contextlib
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dualtwin.webots import schema
from dualtwin.webots.lexer import WebotsSyntaxError, tokenize
from dualtwin.webots.nodes import Node, tree_equal
from dualtwin.webots.parser import (
    MAX_DEPTH,
    ListValue,
    RawNode,
    RawUse,
    convert_value,
    parse_proto,
    parse_world,
)
from dualtwin.webots.proto_resolver import ProtoError
from dualtwin.webots.protos import load_world, load_world_text
from dualtwin.webots.writer import format_float, set_field, write_node, write_world

HEADER = "#VRML_SIM R2023b utf8\n"
FIXTURES = ("inverted_pendulum.wbt", "four_wheels.wbt", "pioneer3at.wbt")


def world(body: str) -> str:
    return HEADER + body


def error_of(text: str, path: str = "w.wbt") -> WebotsSyntaxError:
    with pytest.raises(WebotsSyntaxError) as info:
        load_world_text(text, path)
    return info.value


def assert_located(err: Exception, line: int, col: int, path: str = "w.wbt") -> None:
    assert str(err).startswith(f"{path}:{line}:{col}: expected "), str(err)
    assert ", found " in str(err)


# --------------------------------------------------------------------------------------------
# fixtures and round trips


@pytest.mark.parametrize("name", FIXTURES)
def test_fixture_worlds_parse(webots_fixtures: Path, name: str) -> None:
    parsed = parse_world((webots_fixtures / name).read_bytes(), str(webots_fixtures / name))
    assert parsed.header == "#VRML_SIM R2023b utf8"
    assert parsed.externprotos and all(e.url.startswith("webots://") for e in parsed.externprotos)
    assert parsed.nodes[0].type_name == "WorldInfo"  # type: ignore[union-attr]
    assert parsed.warnings == []


@pytest.mark.parametrize("name", FIXTURES[:2])
def test_fixture_round_trip(webots_fixtures: Path, name: str) -> None:
    first = load_world(webots_fixtures / name)
    text = write_world(first)
    second = load_world_text(text, "<rewritten>")
    assert len(first.nodes) == len(second.nodes)
    assert all(tree_equal(a, b) for a, b in zip(first.nodes, second.nodes, strict=True))
    assert second.externprotos == first.externprotos
    assert write_world(second) == text  # writing is deterministic


def test_round_trip_all_types_and_defaults() -> None:
    text = world(
        """
        DEF ROOT Robot {
          translation 1 -2.5 3e-3 rotation 0 0 1 -1.5708
          name "a \\"quoted\\" \\\\ name"
          controllerArgs [ "--x" "y" ]
          battery [ 1, 2, 3 ]
          recognitionColors [ 1 0 0, 0 1 0 ]
          children [
            Shape { geometry IndexedFaceSet {
              coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0, 0 0 1, 1 1 1, 2 2 2, 3 3 3, 4 4 4, 5 5 5 ] }
              texCoord TextureCoordinate { point [ 0 0, 1 0, 0 1 ] }
              coordIndex [ 0 1 2 -1 0 2 3 -1 ] } }
            Group { children Pose { } }
            ElevationGrid { height 1 xDimension 0x10 }
          ]
          selfCollision TRUE
          physics Physics { centerOfMass 0 0 0.1 }
          linearVelocity 0.5 0 0
        }
        """
    )
    first = load_world_text(text)
    robot = first.nodes[0]
    assert robot["name"] == 'a "quoted" \\ name'
    assert robot["battery"] == [1.0, 2.0, 3.0]
    assert robot["recognitionColors"] == [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    assert robot["physics"]["centerOfMass"] == [(0.0, 0.0, 0.1)]  # MF single value without brackets
    assert robot.children()[1].children()[0].type_name == "Pose"
    grid = robot.children()[2]
    assert grid["height"] == [1.0] and grid["xDimension"] == 16 and isinstance(grid["xDimension"], int)
    assert robot["linearVelocity"] == (0.5, 0.0, 0.0)  # a base node's hidden field, written plainly
    text2 = write_world(first)
    second = load_world_text(text2)
    assert tree_equal(first.nodes[0], second.nodes[0])


def test_float_formatting_reads_back() -> None:
    for value in (0.1, 1.0, -0.0, 1e-7, 123456789.123, 1e300, 2.0**60, float("inf"), -float("inf")):
        tok = tokenize(format_float(value))[0]
        assert tok.kind == "number" and float(tok.value) == value
    assert format_float(1.0) == "1" and format_float(2.5) == "2.5"


# --------------------------------------------------------------------------------------------
# tokens, values and schema


def test_tokenizer_comments_commas_strings() -> None:
    toks = tokenize('a, b # comment "x"\n"s\\"t\\\\u" [1,2] {} -1.5e3 0x1F')
    kinds = [(t.kind, t.value if t.kind in ("string", "number") else t.text) for t in toks]
    assert kinds == [
        ("ident", "a"),
        ("ident", "b"),
        ("string", 's"t\\u'),
        ("[", "["),
        ("number", 1),
        ("number", 2),
        ("]", "]"),
        ("{", "{"),
        ("}", "}"),
        ("number", -1500.0),
        ("number", 31),
        ("eof", ""),
    ]


def test_types_decide_parsing() -> None:
    w = load_world_text(world("PointLight { color 1 0.5 0 attenuation 0 0 1 } Sphere { subdivision 3 }"))
    light, sphere = w.nodes
    assert light["color"] == (1.0, 0.5, 0.0) and light["attenuation"] == (0.0, 0.0, 1.0)
    assert sphere["subdivision"] == 3 and isinstance(sphere["subdivision"], int)
    assert isinstance(light["intensity"], float)


def test_every_base_node_has_all_fields_with_defaults() -> None:
    names = sorted(schema.BASE_NODES)
    w = load_world_text(world("\n".join(f"{n} {{ }}" for n in names)))
    for name, node in zip(names, w.nodes, strict=True):
        assert node.type_name == name
        assert list(node.fields) == list(schema.BASE_NODES[name].fields)
        for fname, spec in schema.BASE_NODES[name].fields.items():
            assert node.fields[fname] == spec.default


def test_schema_covers_required_nodes_and_defaults() -> None:
    required = ["WorldInfo", "Viewpoint", "Background", "DirectionalLight", "PointLight", "SpotLight", "Fog", "Group", "Transform", "Pose", "Solid", "Robot", "Physics", "Damping", "ContactProperties", "Shape", "Appearance", "PBRAppearance", "Material", "ImageTexture", "TextureTransform", "Box", "Sphere", "Cylinder", "Capsule", "Cone", "Plane", "IndexedFaceSet", "IndexedLineSet", "Coordinate", "Normal", "TextureCoordinate", "Color", "ElevationGrid", "Mesh", "CadShape", "HingeJoint", "HingeJointParameters", "JointParameters", "SliderJoint", "BallJoint", "BallJointParameters", "Hinge2Joint", "RotationalMotor", "LinearMotor", "PositionSensor", "Brake", "InertialUnit", "GPS", "Gyro", "Accelerometer", "Compass", "Camera", "DistanceSensor", "TouchSensor", "Lidar", "RangeFinder", "Emitter", "Receiver", "LED", "Display", "Speaker", "Pen", "Charger", "Connector", "Track", "TrackWheel", "SolidReference", "Slot", "Propeller", "Muscle"]
    assert not set(required) - set(schema.BASE_NODES)
    d = schema.default_fields
    assert d("WorldInfo")["basicTimeStep"] == 32.0 and d("WorldInfo")["CFM"] == 0.00001
    assert d("ContactProperties")["coulombFriction"] == [1.0] and d("ContactProperties")["softCFM"] == 0.001
    assert d("HingeJointParameters")["axis"] == (1.0, 0.0, 0.0)
    assert d("JointParameters")["axis"] == (0.0, 0.0, 1.0)
    assert d("RotationalMotor")["maxVelocity"] == 10.0 and d("RotationalMotor")["controlPID"] == (10.0, 0.0, 0.0)
    assert d("Physics")["density"] == 1000.0 and d("Physics")["mass"] == -1.0
    assert d("Box")["size"] == (2.0, 2.0, 2.0) and d("Robot")["selfCollision"] is False
    assert "Camera" in schema.SOLID_TYPES and "RotationalMotor" not in schema.USE_FORBIDDEN_TYPES
    assert d("Solid")["children"] is not d("Solid")["children"]  # fresh mutable defaults


def test_def_use_is_deep_copy_and_find_def() -> None:
    w = load_world_text(
        world(
            """DEF S Solid { children [ DEF SH Shape { geometry DEF B Box { size 1 2 3 } } ]
               boundingObject USE SH }
               Solid { name "s2" boundingObject USE B }"""
        )
    )
    s1, s2 = w.nodes
    copy = s1["boundingObject"]
    assert copy.use_name == "SH" and copy.def_name is None
    assert tree_equal(copy["geometry"], s1.children()[0]["geometry"]) is False  # inner DEF not copied
    assert copy["geometry"]["size"] == (1.0, 2.0, 3.0)
    copy["geometry"].fields["size"] = (9.0, 9.0, 9.0)
    assert s1.children()[0]["geometry"]["size"] == (1.0, 2.0, 3.0)
    assert s2["boundingObject"]["size"] == (1.0, 2.0, 3.0)
    assert w.find_def("B") is s1.children()[0]["geometry"]
    assert w.find_def("S") is s1


@pytest.mark.parametrize("name", ["TEST`", "a-b", "_x", "caf\u00e9", "x@y:z", "A|B"])
def test_def_names_follow_the_vrml97_identifier_rule(name: str) -> None:
    # any printable character but " # ' , . [ \\ ] { } (and no leading digit, '+' or '-'), as Webots reads them
    w = load_world_text(world(f"Solid {{ boundingObject DEF {name} Box {{ }} }}\nSolid {{ boundingObject USE {name} }}"))
    assert w.find_def(name) is w.nodes[0]["boundingObject"]
    assert w.nodes[1]["boundingObject"].use_name == name


@pytest.mark.parametrize("name", ["1x", "-x", "+x", "a.b", "a'b", "a\\\\b"])
def test_def_names_outside_the_vrml97_rule_are_rejected(name: str) -> None:
    assert re.search(r"expected a name after DEF|expected a name, number", str(error_of(world(f"DEF {name} Solid {{ }}"))))


def test_hidden_fields_kept_aside() -> None:
    w = load_world_text(
        world("Solid { hidden translation_1 0 0 1 hidden position_0_0 0.5 hidden customThing \"x\" }")
    )
    node = w.nodes[0]
    assert node.hidden == {"translation_1": (0.0, 0.0, 1.0), "position_0_0": 0.5, "customThing": "x"}
    assert set(node.fields) == set(schema.BASE_NODES["Solid"].fields)
    again = load_world_text(write_world(w))
    assert again.nodes[0].hidden == node.hidden


def test_externproto_and_importable() -> None:
    w = load_world_text(
        world('EXTERNPROTO "a/B.proto"\nIMPORTABLE EXTERNPROTO "webots://x/C.proto"\nWorldInfo { }\n')
    )
    assert w.externprotos == ["a/B.proto"] and w.importable_externprotos == ["webots://x/C.proto"]
    parsed = parse_world(world('EXTERNPROTO "a/B.proto"'))
    assert parsed.externprotos[0].name == "B"


def test_proto_interface_parsing() -> None:
    proto = parse_proto(
        """#VRML_OBJ R2023b utf8
        # license: test
        # template language: javascript
        EXTERNPROTO "Other.proto"
        PROTO Thing [
          field SFString{"a", "b"} mode "a"
          unconnectedField MFVec3f points [ 0 0 0, 1 1 1 ]
          hiddenField SFNode physics Physics { mass 2 }
          vrmlField SFColor c 1 0 0
        ]
        {
          Solid { name IS mode physics IS physics }
        }
        """,
        "Thing.proto",
    )
    assert proto.name == "Thing" and proto.metadata["license"] == "test"
    assert [e.name for e in proto.externprotos] == ["Other"]
    assert proto.interface["mode"].restrictions == ["a", "b"]
    assert proto.interface["points"].typed_default == [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)]
    assert isinstance(proto.interface["physics"].default, RawNode)
    assert proto.interface["c"].typed_default == (1.0, 0.0, 0.0)
    assert proto.body is not None and proto.template is None
    assert parse_proto("#VRML V2.0 utf8\nPROTO P [] { Group {} }").name == "P"


def test_mf_node_list_and_convert_value_errors() -> None:
    raw = parse_world(world("DEF X Box { } Group { children [ Pose { } USE X ] }")).nodes[1]
    assert isinstance(raw, RawNode)
    value = raw.fields["children"].value
    assert isinstance(value, ListValue) and isinstance(value.items[1], RawUse)
    with pytest.raises(WebotsSyntaxError, match="expected SFVec3f"):
        convert_value(value, "SFVec3f")


# --------------------------------------------------------------------------------------------
# errors: each kind, with file:line:col


@pytest.mark.parametrize(
    ("text", "line", "col", "fragment"),
    [
        ("#VRML_SIM R2023b\nWorldInfo {}", 1, 1, "expected header '#VRML_SIM R2023b utf8'"),
        ("#VRML V2.0 utf8\nWorldInfo {}", 1, 1, "found '#VRML V2.0 utf8'"),
        (HEADER + 'WorldInfo { title "abc }', 2, 19, "closing '\"'"),
        (HEADER + "WorldInfo { gravity 1 2 }", 2, 21, "expected SFFloat (a number), found 2 numbers"),
        (HEADER + "Box { size 1 2 }", 2, 12, "expected SFVec3f (3 numbers), found 2 numbers"),
        (HEADER + "Sphere { subdivision 1.5 }", 2, 22, "expected SFInt32 (an integer), found number 1.5"),
        (HEADER + "Solid { name 3 }", 2, 14, "expected SFString (a string), found number 3"),
        (HEADER + "Solid { locked 1 }", 2, 16, "expected SFBool (TRUE or FALSE)"),
        (HEADER + "Solid { children 1 }", 2, 18, "expected MFNode"),
        (HEADER + "Solid { boundingObject [ Box {} ] }", 2, 24, "expected SFNode (a node or NULL)"),
        (HEADER + "Physics { centerOfMass [ 0 0 ] }", 2, 24, "a multiple of 3 numbers"),
        (HEADER + "Solid {\n  translaton 0 0 1\n}", 3, 3, "unknown field 'translaton'"),
        (HEADER + "Solid { children [ Box { } ", 2, 28, "found end of file"),
        (HEADER + "Solid { name }", 2, 14, "expected a field value, found '}'"),
        (HEADER + "Solid { name IS x }", 2, 14, "IS is only allowed inside a PROTO body"),
        (HEADER + "Solid { boundingObject USE NOPE }", 2, 28, "USE of undefined 'NOPE'"),
        (HEADER + "Solid { children [ Box { size 1 1 1 %<= 2 >% } ] }", 2, 37, "template code"),
        (HEADER + "Solid { x.y 1 }", 2, 9, "found 'x.y'"),
        (HEADER + "Solid { x@y 1 }", 2, 9, "unknown field 'x@y'"),  # VRML97: '@' may be in a name
        (HEADER + "PROTO A [] { Group {} }", 2, 1, "PROTO definitions belong"),
        (HEADER + "Solid { } ]", 2, 11, "expected a node type name, found ']'"),
        (HEADER + "Sphere { subdivision 99999999999 }", 2, 22, "out-of-range integer"),
        (HEADER + "DEF 3 Solid { }", 2, 5, "expected a name after DEF, found number 3"),
        (HEADER + 'Solid { hidden rotation_1 "x" }', 2, 27, "expected SFRotation"),
    ],
)
def test_syntax_errors_are_located(text: str, line: int, col: int, fragment: str) -> None:
    err = error_of(text)
    assert_located(err, line, col)
    assert fragment in str(err)


def test_unknown_field_lists_valid_fields() -> None:
    msg = str(error_of(world("Box { sise 1 1 1 }")))
    assert "expected a field of Box (size), found unknown field 'sise'" in msg


@pytest.mark.parametrize(
    "kind", ["Solid", "Robot", "Camera", "HingeJoint", "SliderJoint", "JointParameters", "BallJointParameters"]
)
def test_use_of_unique_nodes_rejected(kind: str) -> None:
    err = error_of(world(f"DEF X {kind} {{ }}\nGroup {{ children [ USE X ] }}"))
    assert_located(err, 3, 20)
    assert f"found USE of {kind} 'X'" in str(err)


def test_use_of_shapes_geometry_and_physics_allowed() -> None:
    w = load_world_text(
        world("DEF P Physics { mass 2 } DEF G Box { } Solid { physics USE P boundingObject USE G }")
    )
    assert w.nodes[2]["physics"]["mass"] == 2.0


def test_invalid_utf8_and_nesting_limits() -> None:
    with pytest.raises(WebotsSyntaxError, match=r"w\.wbt:2:7: expected UTF-8 text, found byte 0xff"):
        load_world_text(HEADER.encode() + b"Solid \xff{ }", "w.wbt")
    deep = world("Group { children [ " * (MAX_DEPTH + 5) + "]}" * (MAX_DEPTH + 5))
    with pytest.raises(WebotsSyntaxError, match="nesting of at most"):
        parse_world(deep)


def test_proto_file_errors_are_located() -> None:
    with pytest.raises(WebotsSyntaxError, match=r"P\.proto:3:9: expected a field type"):
        parse_proto("#VRML_SIM R2023b utf8\nPROTO P [\n  field SFVec4f x 0 0 0 0\n] { Group {} }", "P.proto")
    with pytest.raises(WebotsSyntaxError, match=r"P\.proto:2:25: expected end of file"):
        parse_proto("#VRML_SIM R2023b utf8\nPROTO P [] { Group {} } Group {}", "P.proto")
    with pytest.raises(WebotsSyntaxError, match=r"P\.proto:2:27: expected a value \(IS is only allowed inside a PROTO body\)"):
        parse_proto("#VRML_SIM R2023b utf8\nPROTO P [ field SFFloat x IS y ] { Group {} }", "P.proto")


# --------------------------------------------------------------------------------------------
# writer and set_field

EDIT_WORLD = world(
    """# a comment that must survive
EXTERNPROTO "webots://projects/objects/floors/protos/Floor.proto"
WorldInfo { basicTimeStep 16 }
Floor { size 4 4 }
DEF BOT Robot {
  children [
    DEF HIP HingeJoint {
      jointParameters HingeJointParameters { axis 0 1 0 }
      endPoint Solid { physics Physics { mass 1 } }
    }
  ]
  physics Physics { }
}
"""
)


def test_set_field_text_keeps_the_rest() -> None:
    text = set_field(EDIT_WORLD, "BOT", "translation", [0, 0, 0.5])
    text = set_field(text, "HIP", "jointParameters.position", 0.25)
    text = set_field(text, "HIP", "jointParameters.axis", (1, 0, 0))
    assert "# a comment that must survive" in text and "Floor { size 4 4 }" in text
    w = load_world_text(text)
    bot = w.find_def("BOT")
    assert bot is not None and bot["translation"] == (0.0, 0.0, 0.5)
    hip = w.find_def("HIP")
    assert hip is not None
    assert hip["jointParameters"]["position"] == 0.25 and hip["jointParameters"]["axis"] == (1.0, 0.0, 0.0)
    assert len(re.findall(r"\baxis\b", text)) == 1  # replaced, not duplicated


def test_set_field_tree_and_errors() -> None:
    w = load_world_text(EDIT_WORLD)
    set_field(w, "HIP", "jointParameters.minStop", -1)
    hip = w.find_def("HIP")
    assert hip is not None and hip["jointParameters"]["minStop"] == -1.0
    assert isinstance(hip["jointParameters"]["minStop"], float)
    reread = load_world_text(write_world(w))
    assert tree_equal(reread.nodes[-1], w.nodes[-1])
    with pytest.raises(ValueError, match="no field 'sise'"):
        set_field(w, "BOT", "sise", 1)
    with pytest.raises(ValueError, match="expected a SFVec3f value"):
        set_field(EDIT_WORLD, "BOT", "translation", [1, 2])
    with pytest.raises(ValueError, match="no DEF NOPE"):
        set_field(EDIT_WORLD, "NOPE", "translation", [1, 2, 3])
    with pytest.raises(ValueError, match="not written as a node"):
        set_field(EDIT_WORLD, "BOT", "boundingObject.size", [1, 2, 3])
    node = set_field(Node("Box", schema.default_fields("Box"), def_name="B"), "B", "size", (1, 1, 1))
    assert node["size"] == (1.0, 1.0, 1.0)


def test_write_node_uses_use_only_for_identical_content() -> None:
    w = load_world_text(world("Group { children [ DEF S Shape { } USE S ] }"))
    text = write_node(w.nodes[0])
    assert "USE S" in text
    w.nodes[0].children()[1].fields["castShadows"] = False  # the copy now differs from its DEF
    assert "USE S" not in write_node(w.nodes[0])


# --------------------------------------------------------------------------------------------
# fuzzing: nothing but WebotsSyntaxError may escape the parser

_SEED_WORLD = world(
    """EXTERNPROTO "protos/Thing.proto"
WorldInfo { info [ "a" "b" ] basicTimeStep 8 contactProperties [ ContactProperties { coulombFriction [ 0.5 ] } ] }
DEF R Robot {
  translation 0 0 0.1 rotation 0 0 1 0.5
  children [
    DEF H HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 }
      device [ RotationalMotor { name "m" } ]
      endPoint Solid { boundingObject DEF C Cylinder { radius 0.1 } physics Physics { } } }
    Shape { geometry USE C }
  ]
  name "r\\"x" hidden translation_1 0 0 1
}
Thing { size 1 2 }
"""
)
_TOKENS = [
    "{", "}", "[", "]", "DEF", "USE", "IS", "NULL", "TRUE", "FALSE", "Solid", "Box", "size", "1", "-2.5e3",
    '"s"', "children", "hidden", "x_1", "EXTERNPROTO", "IMPORTABLE", "PROTO", "field", "SFVec3f",
    "translation", "boundingObject", "Group", "A", "inf", "nan", "%<", ">%", "#", ",", "\n", "0x7f",
]
_FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@_FUZZ
@given(
    st.lists(
        st.tuples(st.integers(0, len(_SEED_WORLD)), st.integers(0, 8), st.text(max_size=6)), max_size=6
    )
)
def test_fuzz_mutated_world(edits: list[tuple[int, int, str]]) -> None:
    text = _SEED_WORLD
    for pos, cut, insert in edits:
        pos = min(pos, len(text))
        text = text[:pos] + insert + text[pos + cut :]
    try:
        parse_world(text, "fuzz.wbt")
    except WebotsSyntaxError as exc:
        assert re.match(r"fuzz\.wbt:\d+:\d+: expected .+, found ", str(exc), re.S)


@_FUZZ
@given(st.binary(max_size=200))
def test_fuzz_bytes(data: bytes) -> None:
    with contextlib.suppress(WebotsSyntaxError):
        parse_world(HEADER.encode() + data, "fuzz.wbt")


@_FUZZ
@given(st.lists(st.sampled_from(_TOKENS), max_size=60))
def test_fuzz_token_soup(tokens: list[str]) -> None:
    text = HEADER + " ".join(tokens)
    with contextlib.suppress(WebotsSyntaxError):
        parse_world(text, "soup.wbt")
    with contextlib.suppress(WebotsSyntaxError):
        parse_proto("#VRML_SIM R2023b utf8\nPROTO P [ " + " ".join(tokens), "P.proto")
    with contextlib.suppress(WebotsSyntaxError, ProtoError):  # expansion: only our errors may escape
        load_world_text(text, "soup.wbt")
