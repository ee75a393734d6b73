"""``Robot.getUrdf()``: the robot's kinematic tree as URDF text, as Webots exports it.

Solids become links (a Solid without a name inherits its parent link's), ``HingeJoint`` becomes ``revolute`` when
its motor has position limits and ``continuous`` otherwise, ``SliderJoint`` becomes ``prismatic``; each joint has
its ``<origin xyz rpy>`` (ZYX Euler angles) relative to the parent link, its ``<axis>`` and, with a motor, its
``<limit effort velocity [lower upper]>``. Like Webots' export, masses, inertias and shapes' meshes are not
written; joints are named after their motor (or position sensor), else after the child link.
"""

from __future__ import annotations

from typing import Any
from xml.sax.saxutils import quoteattr

from dualtwin.webots import _math3 as m3
from dualtwin.webots.nodes import Node
from dualtwin.webots.writer import format_float

__all__ = ["robot_urdf"]

_JOINTS = {"HingeJoint": "HingeJointParameters", "SliderJoint": "JointParameters"}


def _vec(values: Any) -> str:
    return " ".join(format_float(float(v)) for v in values)


def _local_pose(node: Node) -> m3.Pose:
    return m3.Pose.from_fields(node.fields.get("translation"), node.fields.get("rotation"))


def _devices(joint: Node) -> list[Node]:
    value = joint.fields.get("device") or []
    return [d for d in value if isinstance(d, Node)]


def robot_urdf(robot: Node, robot_name: str, prefix: str = "") -> str:
    links: list[str] = []
    joints: list[str] = []
    used: set[str] = set()

    def unique(name: str) -> str:
        base, n = name, 1
        while name in used:
            n += 1
            name = f"{base}_{n}"
        used.add(name)
        return name

    def visit(node: Node, link: str, pose: m3.Pose) -> None:
        """Walk the children of ``node``; ``pose`` is ``node``'s frame relative to ``link``'s frame."""
        for key in ("children", "endPoint"):
            value = node.fields.get(key)
            items = value if isinstance(value, list) else [value]
            for child in items:
                if not isinstance(child, Node):
                    continue
                if child.type_name in _JOINTS:
                    joint(child, link, pose)
                elif child.type_name in ("Solid", "Robot") or "physics" in child.fields and "name" in child.fields:
                    child_pose = pose * _local_pose(child)
                    name = unique(prefix + (str(child.fields.get("name") or "") or "solid"))
                    links.append(f"  <link name={quoteattr(name)}/>")
                    joints.append(_fixed(unique(f"{name}_joint"), link, name, child_pose))
                    visit(child, name, m3.Pose())
                elif "translation" in child.fields or "children" in child.fields:
                    visit(child, link, pose * _local_pose(child))

    def joint(node: Node, link: str, pose: m3.Pose) -> None:
        end = node.fields.get("endPoint")
        if not isinstance(end, Node):
            return
        params = node.fields.get("jointParameters")
        axis = params.fields.get("axis") if isinstance(params, Node) else None
        axis = axis or ((0.0, 0.0, 1.0) if node.type_name == "SliderJoint" else (1.0, 0.0, 0.0))
        child_pose = pose * _local_pose(end)
        child = unique(prefix + (str(end.fields.get("name") or "") or "solid"))
        links.append(f"  <link name={quoteattr(child)}/>")
        devices = _devices(node)
        motor = next((d for d in devices if d.type_name.endswith("Motor")), None)
        named = motor or next(iter(devices), None)
        name = unique(prefix + str(named.fields.get("name"))) if named is not None else unique(f"{child}_joint")
        kind = "prismatic" if node.type_name == "SliderJoint" else "continuous"
        limit = ""
        if motor is not None:
            lo, hi = float(motor.fields.get("minPosition", 0.0)), float(motor.fields.get("maxPosition", 0.0))
            if kind == "continuous" and (lo != 0.0 or hi != 0.0):
                kind = "revolute"
            effort = motor.fields.get("maxTorque", motor.fields.get("maxForce", 10.0))
            bounds = f" lower={quoteattr(format_float(lo))} upper={quoteattr(format_float(hi))}" if lo or hi else ""
            limit = (f"\n    <limit effort={quoteattr(format_float(float(effort)))} "
                     f"velocity={quoteattr(format_float(float(motor.fields.get('maxVelocity', 10.0))))}{bounds}/>")
        # the joint frame is the endPoint's frame; the axis is given in the parent's frame, as Webots reads it
        local_axis = m3.mat_t_vec(child_pose.R, m3.mat_vec(pose.R, axis))
        joints.append(
            f"  <joint name={quoteattr(name)} type=\"{kind}\">\n    <parent link={quoteattr(link)}/>\n"
            f"    <child link={quoteattr(child)}/>\n    <axis xyz=\"{_vec(local_axis)}\"/>\n"
            f"    {_origin(child_pose)}{limit}\n  </joint>"
        )
        visit(end, child, m3.Pose())

    base = unique(prefix + "base_link")
    links.append(f"  <link name={quoteattr(base)}/>")
    visit(robot, base, m3.Pose())
    body = "\n".join([*links, *joints])
    return f"<?xml version=\"1.0\"?>\n<robot name={quoteattr(robot_name)}>\n{body}\n</robot>\n"


def _origin(pose: m3.Pose) -> str:
    roll, pitch, yaw = m3.roll_pitch_yaw(pose.R)
    return f"<origin xyz=\"{_vec(pose.t)}\" rpy=\"{_vec((roll, pitch, yaw))}\"/>"


def _fixed(name: str, parent: str, child: str, pose: m3.Pose) -> str:
    return (f"  <joint name={quoteattr(name)} type=\"fixed\">\n    <parent link={quoteattr(parent)}/>\n"
            f"    <child link={quoteattr(child)}/>\n    {_origin(pose)}\n  </joint>")
