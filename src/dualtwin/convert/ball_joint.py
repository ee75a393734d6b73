"""What a converted BallJoint leaves out: the remarks the converter reports for it.

A BallJoint becomes one MuJoCo ``ball`` joint at its anchor, started at the file's pose, with ``jointParameters``'
springConstant, dampingConstant and staticFriction as the joint's stiffness, damping and frictionloss. Webots
drives a BallJoint through Euler AMotors with three axes (on-ODE §4.4: by default x, z × x and z; springs on a
second AMotor), each axis with its own parameters node (``jointParameters`` a BallJointParameters,
``jointParameters2`` and ``jointParameters3`` JointParameters), devices (``device``, ``device2``, ``device3``) and
position. MuJoCo's ball joint has one stiffness, damping and friction for every rotation, and its only limit is a
cone on the rotation angle, so per-axis stops, devices, positions and dynamics have no counterpart there: each is
reported. Before, stops were dropped without a word, and a BallJoint that Webots holds within its stops swung
freely in MuJoCo.

Why the stops stay unconverted: Webots' stops bound each Euler angle of the AMotor (a box in the three angles,
each axis's stops from its own parameters node), MuJoCo's ball ``range`` only the total rotation angle from the
reference pose (a ball around it, from zero). No cone reproduces a box: the inscribed one (the smallest stop)
blocks the diagonal turns Webots allows about sqrt(3) times further (small angles), a circumscribed one lets the joint pass each
stop, and an asymmetric stop (0 to 1 rad) or one stopped axis among free ones has no cone at all. The faithful
form, three hinges in the child body along the Euler axes (MuJoCo composes a body's joints in order, as the
AMotor's angles compose) with a range each, is another joint for the rest of the project: the twins' state holds
a ball joint as one rotation vector (``/rx /ry /rz`` entries), which three hinges would not match, and a hinge
chain locks at the middle angle's +-pi/2 where a ball joint does not. So the conversion keeps the ball joint and
says its stops are missing.
"""

from __future__ import annotations

from dualtwin.webots.nodes import Node

__all__ = ["ball_joint_notes"]

#: The JointParameters fields that act on the joint's motion.
_DYNAMICS = ("springConstant", "dampingConstant", "staticFriction")


def ball_joint_notes(joint: Node) -> list[str]:
    """The remarks for BallJoint ``joint`` (none for an anchor alone)."""
    notes = []
    if any(joint.get(field) for field in ("device", "device2", "device3")):
        notes.append("BallJoint devices (motors/sensors) are not converted")
    params = [joint.get(field) for field in ("jointParameters", "jointParameters2", "jointParameters3")]
    positions = [p.get("position", 0.0) if p is not None else joint.get(f"position{s}", 0.0)
                 for p, s in zip(params, ("", "2", "3"), strict=True)]
    if any(float(v or 0.0) for v in positions):
        notes.append("BallJoint position is ignored (MuJoCo ball joints start at the XML pose)")
    if any(p is not None and float(p.get("minStop", 0.0)) != float(p.get("maxStop", 0.0)) for p in params):
        notes.append("BallJoint stops are not converted (Webots stops each of its three axes; MuJoCo limits a ball "
                     "joint's rotation angle only): the converted joint turns past them")
    if any(p is not None and any(float(p.get(f, 0.0)) for f in _DYNAMICS) for p in params):
        notes.append("BallJoint springConstant/dampingConstant/staticFriction: Webots applies each parameters node's "
                     "about its own Euler axis, MuJoCo's ball joint one value about every axis (jointParameters' "
                     "converted for all rotations, jointParameters2/jointParameters3's not converted)")
    return notes
