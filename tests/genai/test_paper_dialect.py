"""The paper's primitive-robot JSON schema as an input dialect: detection, lenient reading of messy answers with
every assumption recorded, inconsistencies that name the part and the fix, and a paper-schema CartPole that runs
the bundled suite in both twins."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
import yaml

from dualtwin.errors import DualtwinError
from dualtwin.genai.generate import Source, generate
from dualtwin.genai.llm import LLMConfig, OpenAIChatClient
from dualtwin.genai.paper_dialect import (
    DialectProblem,
    detect,
    load_any_description,
    read_description,
    translate,
)
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.runner import SuiteRun
from tests.support.llm_replay import Reply, replay_server

HERE = Path(__file__).parent / "paper"
CARTPOLE = json.loads((HERE / "cartpole_paper.json").read_text())


def paper_cartpole() -> dict[str, Any]:
    return copy.deepcopy(CARTPOLE)


def part(data: dict[str, Any], name: str) -> dict[str, Any]:
    return next(p for p in data["parts"] if p["name"] == name)


def test_detects_the_paper_schema_and_ours() -> None:
    assert detect(paper_cartpole()) == "paper"
    ours = json.loads((Path(__file__).resolve().parents[2] / "src/dualtwin/genai/cases/cartpole.json").read_text())
    assert detect(ours) == "dualtwin"
    # one paper-only feature is enough: an Euler triple, a size object, a material
    minimal = {"robot_name": "r", "parts": [{"name": "a", "type": "box", "dimensions": [1, 1, 1], "mass": 1,
                                             "orientation": [0, 0, 0]}]}
    assert detect(minimal) == "paper"


def test_paper_cartpole_runs_the_bundled_suite_in_both_twins(tmp_path: Path) -> None:
    result = generate(Source.from_json(HERE / "cartpole_paper.json"), tmp_path / "gen")
    assert result.converged and result.dialect == "paper"
    model = mujoco.MjModel.from_xml_path(str(result.files["xml"]))
    assert model.body("pole").mass[0] == pytest.approx(0.2)
    assert model.nu == 4  # the wheel hinges became motors (an assumption, recorded)
    # every assumption is in the transcript and in generation.json
    transcript = json.loads(result.files["transcript"].read_text())
    record = json.loads((tmp_path / "gen" / "generation.json").read_text())
    assert transcript[0]["dialect"] == "paper" and transcript[0]["assumptions"] == record["assumptions"]
    joined = "\n".join(record["assumptions"])
    for expected in ("roll, pitch, yaw", "parent part's frame", "placeholder", "velocity motors", "anchor"):
        assert expected in joined, expected
    # materials are kept as labels
    robot = json.loads(result.files["json"].read_text())
    assert part(robot, "pole")["material"] == "wood"
    # the bundled binding, pointed at the generated twins, runs the bundled suite unchanged in both
    binding = yaml.safe_load((BUNDLED / "cartpole" / "binding.yaml").read_text())
    binding["twins"]["mujoco"]["model"] = result.files["xml"].name
    binding["twins"]["webots"]["model"] = result.files["wbt"].name
    binding.pop("cameras", None)
    binding_path = tmp_path / "gen" / "bundled_binding.yaml"
    binding_path.write_text(yaml.safe_dump(binding))
    robot_binding = load_binding(binding_path)
    finals = {}
    for twin in ("mujoco", "webots"):
        run = tmp_path / f"run_{twin}"
        manifest = SuiteRun(BUNDLED / "cartpole" / "suite.json", twin, robot_binding, run).run()
        assert all(s["status"] == "completed" for s in manifest["scenarios"]), (twin, manifest["scenarios"])
        log = np.genfromtxt(sorted((run / "scenarios").glob("01_*"))[0] / "ground_truth.tsv", names=True)
        finals[twin] = float(log["cart_pos_m"][-1])
    # both twins drive the cart forward at 1 rad/s * 0.04 m for 5 s in scenario 01 and agree on where it ends
    assert finals["webots"] == pytest.approx(0.2, rel=0.02)
    assert finals["mujoco"] == pytest.approx(finals["webots"], rel=0.01)


def test_messy_answer_is_read_with_every_assumption_recorded() -> None:
    data = paper_cartpole()
    data["robot_name"] = "Cart Pole #1"
    data["physics"] = {"mass": 1.4, "center_of_mass": None, "inertia": None, "friction": None,
                       "restitution": 0.3, "damping": 0.01, "air_drag": "unknown"}
    data["notes_from_model"] = "I was unsure about the wheel size"
    cart = part(data, "cart")
    cart["mass"] = None  # unknown: takes what physics.mass leaves
    cart["parent"] = "world"
    cart["manufacturer"] = "ACME"
    wheel = part(data, "wheel1")
    wheel["orientation"] = [90, 0, 0]  # degrees, like every Euler triple of this answer
    part(data, "wheel4")["orientation"] = [90, 0, 0]
    wheel["joint"]["type"] = "revolute"
    wheel["dimensions"] = {"diameter": 0.08, "length": 0.02}
    wheel2 = part(data, "wheel2")
    wheel2["orientation"] = [math.sin(math.pi / 4), 0, 0, math.cos(math.pi / 4)]  # quaternion, scalar last
    wheel3 = part(data, "wheel3")
    wheel3["orientation"] = [1, 0, 0, math.pi / 2]  # a Webots axis-angle copied from the PROTO
    pole = part(data, "pole")
    pole["joint"]["limits"] = [57.29578, -57.29578]  # degrees, and reversed
    translation = translate(data)
    notes = "\n".join(translation.notes)
    desc = translation.description
    assert desc["robot_name"] == "Cart_Pole_1"
    assert part(desc, "cart")["mass"] == pytest.approx(1.4 - 0.2 - 4 * 0.05)
    assert part(desc, "cart")["parent"] is None
    assert part(desc, "wheel1")["dimensions"] == pytest.approx([0.04, 0.02])
    assert part(desc, "wheel1")["joint"]["type"] == "hinge"
    assert part(desc, "pole")["joint"]["limits"] == pytest.approx([-1.0, 1.0], abs=1e-6)
    assert part(desc, "pole")["joint"]["damping"] == 0.0  # its own damping wins over physics.damping
    for p in ("wheel1", "wheel2", "wheel3"):  # three spellings of the same 90 degree roll
        axis_angle = part(desc, p)["orientation"]
        assert axis_angle == pytest.approx([1, 0, 0, math.pi / 2], abs=1e-6), p
    for expected in ("in degrees", "'air_drag'", "'manufacturer'", "'notes_from_model'", "restitution 0.3",
                     "share the", "axis-angle", "swapped", "'revolute' read as 'hinge'", "half the given diameter",
                     "became 'Cart_Pole_1'"):
        assert expected in notes, expected
    read = read_description(data, "answer.json")
    assert read.dialect == "paper" and read.description.physics.friction == 1.0


def test_world_frame_positions_declared_or_recognised_from_the_approximate_scale() -> None:
    relative = translate(paper_cartpole()).description
    # the same CartPole with every position (and the pole's anchor) written in the world frame, declared so
    world = paper_cartpole()
    world["position_frame"] = "world"
    for p in world["parts"]:
        if p["parent"] == "cart":
            p["position"][2] += 0.07
    part(world, "pole")["joint"]["anchor"] = [0, 0, 0.12]
    declared = translate(world).description
    for name in ("wheel1", "wheel4", "pole"):
        assert part(declared, name)["position"] == pytest.approx(part(relative, name)["position"], abs=1e-9), name
    assert part(declared, "pole")["joint"]["anchor"] == pytest.approx([0, 0, 0.05])

    # a stacked arm: positions z = 0.05, 0.3, 0.7 fit a 0.9 m tall robot only if they are world coordinates
    def link(name: str, z: float, parent: str | None) -> dict[str, Any]:
        return {"name": name, "type": "box", "dimensions": {"size": [0.08, 0.08, 0.4 if parent else 0.1]},
                "mass": 1.0, "position": [0, 0, z], "parent": parent,
                "joint": {"type": "hinge", "axis": [0, 1, 0]} if parent else {"type": "fixed"}}

    arm = {"robot_name": "arm", "approximate_scale": [0.1, 0.1, 0.9],
           "parts": [link("base", 0.05, None), link("upper", 0.3, "base"), link("fore", 0.7, "upper")]}
    inferred = translate(arm)
    assert part(inferred.description, "upper")["position"] == pytest.approx([0, 0, 0.25])
    assert part(inferred.description, "fore")["position"] == pytest.approx([0, 0, 0.4])
    assert any("world's frame" in n and "closer to approximate_scale" in n for n in inferred.notes)
    arm["approximate_scale"] = [0.1, 0.1, 1.25]  # now the parent reading fits
    assert part(translate(arm).description, "fore")["position"] == pytest.approx([0, 0, 0.7])


def test_inconsistent_answers_name_the_part_and_the_fix() -> None:
    data = paper_cartpole()
    data["physics"]["mass"] = 3.0
    with pytest.raises(DialectProblem, match=r"masses do not add up: the parts weigh 1.4 kg .* physics.mass is 3 kg"):
        translate(data)
    data = paper_cartpole()
    part(data, "wheel2")["orientation"] = [0, 0, 0]  # the cylinder stands upright: its axis is z, the hinge's y
    with pytest.raises(DialectProblem) as info:
        translate(data)
    message = str(info.value)
    assert "part 'wheel2'" in message and "would not roll" in message and "set its orientation to" in message
    assert "\n" not in message  # one line at the CLI
    data = paper_cartpole()
    part(data, "pole")["dimensions"] = {"radius": 0.01}
    with pytest.raises(DialectProblem, match=r"part 'pole': dimensions .* give \{\"size\": \[x, y, z\]\}"):
        translate(data)


def test_overlapping_parts_are_refused_with_the_fix(tmp_path: Path) -> None:
    data = paper_cartpole()
    part(data, "wheel2")["position"] = [0.15, 0.11, -0.03]  # 1 cm from wheel1: the two discs interpenetrate
    path = tmp_path / "overlap.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DualtwinError, match=r"parts 'wheel1' and 'wheel2' overlap by \d+\.\d mm: move 'wheel2'"):
        generate(Source.from_json(path), tmp_path / "out")


def test_unreadable_files_are_one_line(tmp_path: Path) -> None:
    binary = tmp_path / "robot.json"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    with pytest.raises(DualtwinError, match="not UTF-8"):
        load_any_description(binary)
    with pytest.raises(DualtwinError, match="not a file"):
        load_any_description(tmp_path)
    bad = tmp_path / "bad.json"
    bad.write_text('{"robot_name": "x",\n "parts": [}')
    with pytest.raises(DualtwinError, match="line 2 column 12"):
        load_any_description(bad)


def test_llm_loop_repairs_a_paper_schema_answer(tmp_path: Path) -> None:
    broken = paper_cartpole()
    part(broken, "wheel3")["orientation"] = [0, 0, 0]
    spec = tmp_path / "SPEC.md"
    spec.write_text("A cart on four wheels carrying a 1 m pole on a hinge.\n")
    script = [Reply(json.dumps(broken)), Reply("```json\n" + json.dumps(paper_cartpole()) + "\n```")]
    with replay_server(script) as (base, log):
        llm = OpenAIChatClient(LLMConfig(model="replay", base_url=base, api_key="k", timeout_s=10, max_retries=0))
        result = generate(Source.from_text(spec), tmp_path / "out", llm=llm, max_iterations=3)
    assert result.converged and result.iterations == 2 and result.dialect == "paper"
    repair = log.requests[1]["messages"][-1]["content"]
    assert "part 'wheel3'" in repair and "set its orientation to" in repair
    transcript = json.loads(result.files["transcript"].read_text())
    answers = [e for e in transcript if e["role"] == "assistant"]
    assert [a["dialect"] for a in answers] == ["paper", "paper"]
    assert any("roll, pitch, yaw" in n for n in answers[1]["assumptions"])


def test_explicit_dialect_overrides_detection(tmp_path: Path) -> None:
    with pytest.raises(DualtwinError, match="invalid robot description"):
        read_description(paper_cartpole(), "x.json", dialect="dualtwin")


def test_a_part_may_overlap_its_parent_even_on_a_fixed_base(tmp_path: Path) -> None:
    # a post fixed to the world with an arm whose hinge sits inside the post: parent and child share the axle
    post = {"name": "post", "type": "box", "dimensions": {"size": [0.1, 0.1, 1.0]}, "mass": 2.0,
            "position": [0, 0, 0.5], "orientation": [0, 0, 0], "parent": None, "joint": {"type": "fixed"}}
    arm = {"name": "arm", "type": "box", "dimensions": {"size": [0.4, 0.04, 0.04]}, "mass": 0.3,
           "position": [0.15, 0, 0.45], "orientation": [0, 0, 0], "parent": "post",
           "joint": {"type": "hinge", "axis": [0, 1, 0], "anchor": [0, 0, 0.45]}}
    data = {"robot_name": "post_arm", "parts": [post, arm]}
    path = tmp_path / "post_arm.json"
    path.write_text(json.dumps(data))
    assert generate(Source.from_json(path), tmp_path / "ok").converged
    # control: a second, unrelated arm in the same place is an overlap
    data["parts"].append({**arm, "name": "arm2", "parent": "arm", "position": [0, 0, 0], "joint": {
        "type": "hinge", "axis": [0, 1, 0]}})
    data["parts"].append({**arm, "name": "arm3"})
    path.write_text(json.dumps(data))
    with pytest.raises(DualtwinError, match="parts 'arm2' and 'arm3' overlap|parts 'arm' and 'arm3' overlap"):
        generate(Source.from_json(path), tmp_path / "bad")


# --- a mobile robot is never welded to the world (issue 28, item 1) ----------------------------------


def welded_cart() -> dict[str, Any]:
    """The paper CartPole with the root marked 'fixed', as the paper's Pioneer answer marks its chassis."""
    data = paper_cartpole()
    part(data, "cart")["joint"] = {"type": "fixed"}
    return data


def test_a_paper_root_marked_fixed_on_a_wheeled_robot_is_read_as_a_mobile_base(tmp_path: Path) -> None:
    translation = translate(welded_cart())
    root = next(p for p in translation.description["parts"] if p["parent"] is None)
    assert "joint" not in root
    note = next(n for n in translation.notes if "free mobile base" in n)
    assert "wheel1" in note and "wheel4" in note
    path = tmp_path / "welded.json"
    path.write_text(json.dumps(welded_cart()))
    result = generate(Source.from_json(path), tmp_path / "gen")
    model = mujoco.MjModel.from_xml_path(str(result.files["xml"]))
    assert model.jnt_type[model.body("cart").jntadr[0]] == mujoco.mjtJoint.mjJNT_FREE  # not welded
    assert any("free mobile base" in a for a in result.assumptions)


def test_a_paper_root_marked_fixed_without_wheels_stays_a_fixed_base() -> None:
    """The control: a mounted robot (a post with an arm) keeps its fixed base."""
    post = {"name": "post", "type": "box", "dimensions": {"size": [0.1, 0.1, 1.0]}, "mass": 2.0,
            "position": [0, 0, 0.5], "orientation": [0, 0, 0], "parent": None, "joint": {"type": "fixed"}}
    arm = {"name": "arm", "type": "box", "dimensions": {"size": [0.4, 0.04, 0.04]}, "mass": 0.3,
           "position": [0.25, 0, 0.45], "orientation": [0, 0, 0], "parent": "post",
           "joint": {"type": "hinge", "axis": [0, 1, 0]}}
    translation = translate({"robot_name": "post_arm", "parts": [post, arm]})
    root = next(p for p in translation.description["parts"] if p["parent"] is None)
    assert root["joint"]["type"] == "fixed"
    assert not any("mobile base" in n for n in translation.notes)


def test_our_schema_refuses_a_welded_robot_that_drives_wheels_and_accepts_a_turntable(tmp_path: Path) -> None:
    data = translate(paper_cartpole()).description
    root = next(p for p in data["parts"] if p["parent"] is None)
    root["joint"] = {"type": "fixed"}
    path = tmp_path / "ours.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DualtwinError, match=r"welds the robot to the world.*wheel1.*remove the root's \"joint\""):
        generate(Source.from_json(path), tmp_path / "bad", dialect="dualtwin")
    # control: a driven turntable (vertical axis) on a fixed base is a mounted robot, not a mobile one
    table = {"robot_name": "turntable", "parts": [
        {"name": "base", "type": "box", "dimensions": [0.4, 0.4, 0.1], "mass": 5.0, "position": [0, 0, 0.05],
         "joint": {"type": "fixed"}},
        {"name": "plate", "type": "cylinder", "dimensions": [0.15, 0.02], "mass": 0.5, "position": [0, 0, 0.07],
         "parent": "base", "joint": {"type": "hinge", "axis": [0, 0, 1]},
         "motor": {"name": "plate motor", "maxVelocity": 3.0, "maxTorque": 2.0}}]}
    path.write_text(json.dumps(table))
    assert generate(Source.from_json(path), tmp_path / "ok", dialect="dualtwin").converged


def test_a_paper_answer_without_a_root_is_one_error_naming_the_rule(tmp_path: Path) -> None:
    """A tree with no root (the cart's parent a wheel, a number) reached the mobile-base reading before the tree
    was checked: ``desc.root`` raised StopIteration, a traceback. Now the tree's own check says what is wrong."""
    for parent in ("wheel1", 5):
        data = paper_cartpole()
        part(data, "cart")["parent"] = parent
        translation = translate(data)  # (before: StopIteration)
        assert not any("mobile base" in n for n in translation.notes)
        path = tmp_path / f"rootless_{parent}.json"
        path.write_text(json.dumps(data))
        with pytest.raises(DualtwinError, match=r"exactly one part must have parent null \(the root\)"):
            generate(Source.from_json(path), tmp_path / f"out_{parent}")


def test_a_refused_description_leaves_no_folder(tmp_path: Path) -> None:
    """Bad input is refused before anything is kept: the output folder generate made is gone again."""
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"robot_name": "r", "parts": []}))
    with pytest.raises(DualtwinError):
        generate(Source.from_json(path), tmp_path / "out", dialect="dualtwin")
    assert not (tmp_path / "out").exists()
    # control: a folder the user made beforehand stays, empty, as it was
    (tmp_path / "mine").mkdir()
    with pytest.raises(DualtwinError):
        generate(Source.from_json(path), tmp_path / "mine", dialect="dualtwin")
    assert (tmp_path / "mine").is_dir()


def test_the_terminal_says_every_assumption_of_a_paper_answer(tmp_path: Path) -> None:
    """The mobile-base reading (and every other) is printed, not only kept in generation.json."""
    import subprocess
    import sys

    path = tmp_path / "welded.json"
    path.write_text(json.dumps(welded_cart()))
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "generate", "--from-json", str(path),
                           "--out", str(tmp_path / "gen")], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "assumed: part 'cart': the root's joint 'fixed' read as a free mobile base" in done.stdout
    assert done.stdout.count("assumed: ") == len(json.loads((tmp_path / "gen/generation.json").read_text())[
        "assumptions"])


def test_the_smoke_test_fails_when_the_twins_do_not_move_alike(tmp_path: Path) -> None:
    """A welded wheeled robot (built past the mobile-base check, as a world file could be) turns its wheels in the
    air in both twins (its wheels are jointed to the static environment, so neither touches the floor: Webots'
    rule, webots-on-ode.md §2.3 rule 6, and the converter's contact excludes): the twin check finds its wheels
    alike (the control). Its converted model edited so that MuJoCo's wheels cannot turn (a damping no motor
    overcomes: what a converter bug would do) still passes MuJoCo's own checks, and the twin check names the
    wheels."""
    import re

    from dualtwin.convert.webots_to_mjcf import convert_world_text
    from dualtwin.genai.agreement import motion_disagreements
    from dualtwin.genai.generate import check_description, default_suite
    from dualtwin.genai.primitive import CompiledRobot, RobotDescription, to_world_text

    data = translate(paper_cartpole()).description
    fine = check_description(RobotDescription.model_validate(data), str(tmp_path / "a.wbt"))
    assert fine.stage == 5, fine.error
    next(p for p in data["parts"] if p["parent"] is None)["joint"] = {"type": "fixed"}
    welded = RobotDescription.model_validate(data)
    text = to_world_text(welded)
    compiled = CompiledRobot(welded, text, convert_world_text(text, "w.wbt", "cartpole"))
    files = compiled.write(tmp_path / "welded")
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps(default_suite(compiled.conversion.binding_dict(files["xml"].name,
                                                                               files["wbt"].name))))
    wheels = {f"wheel{i}_joint_position_rad" for i in range(1, 5)}
    assert not {d.channel for d in motion_disagreements(files["binding"], suite)} & wheels
    model = Path(files["xml"])
    stuck, n = re.subn(r'(<joint name="wheel\d_joint")', r'\1 damping="1e12"', model.read_text())
    assert n == 4
    model.write_text(stuck)
    found = motion_disagreements(files["binding"], suite)
    assert {d.channel for d in found} >= wheels
    assert all(d.webots_range > 0.5 and d.mujoco_range < 0.01 for d in found if "joint_position" in d.channel)
