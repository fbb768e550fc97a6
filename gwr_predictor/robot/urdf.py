"""The Nao URDF used by the PyBullet simulator, built from the figures in `nao.py`.

Why generated: no usable Nao model installs from PyPI (see the notes), and a model written from
the same offsets as `nao.forward_kinematics` cannot drift from it. Shapes are primitives (boxes,
cylinders, spheres) with V4-like masses; inertias follow from the shapes. The torso is the base;
head and legs are fixed links; each arm has its 5 revolute joints (names `nao.ROBOT_ARM_JOINTS`)
and a fixed `<side>_hand` frame at the hand end point, so the tip can be read from the simulator.

`python -m gwr_predictor.robot.urdf` rewrites the shipped copy, `gwr_predictor/robot/nao.urdf`.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gwr_predictor.robot.nao import JOINT_LIMITS, SIDES, VELOCITY_LIMITS, side_offsets

ROBOT_NAME = "nao_arms"
BASE_LINK = "torso"

#: Fixed frame links at the arm end points, per side.
HAND_LINKS = {side: f"{side}_hand" for side in SIDES}
#: Links whose origin sits on the elbow / wrist joint (child links of ElbowYaw / WristYaw).
ELBOW_LINKS = {side: f"{side}Elbow" for side in SIDES}
WRIST_LINKS = {side: f"{side}Wrist" for side in SIDES}
SHOULDER_LINKS = {side: f"{side}Shoulder" for side in SIDES}

#: Motor torque limits (N m) per joint suffix: plausible for Nao's arm actuators.
EFFORT = {"ShoulderPitch": 1.33, "ShoulderRoll": 1.33, "ElbowYaw": 0.80, "ElbowRoll": 0.80, "WristYaw": 0.16}
JOINT_DAMPING = 0.05

NECK_OFFSET = np.array([0.0, 0.0, 0.1265])
HIP_OFFSET = np.array([0.0, 0.05, -0.085])
LEG_LENGTH = 0.2029  # thigh + tibia
FOOT_HEIGHT = 0.04519

_COLOURS = {"white": "0.92 0.92 0.92 1", "grey": "0.45 0.47 0.5 1", "orange": "0.95 0.55 0.15 1"}


def _fmt(values: np.ndarray | tuple[float, ...] | list[float]) -> str:
    """Floats in a stable, exact-enough text form (the shipped file must equal a fresh build)."""
    return " ".join(f"{float(v) + 0.0:.10g}" for v in values)


@dataclass(frozen=True)
class Shape:
    """A primitive with its pose in the link frame; mass spread uniformly through it."""

    kind: str  # "box" (size = x y z), "cylinder" (radius, length; along z), "sphere" (radius,)
    size: tuple[float, ...]
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    colour: str = "white"

    def inertia(self, mass: float) -> tuple[float, float, float]:
        """Principal moments (ixx, iyy, izz) about the shape's own centre and axes."""
        if self.kind == "box":
            x, y, z = self.size
            return (mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12, mass * (x * x + y * y) / 12)
        if self.kind == "cylinder":
            r, length = self.size
            side = mass * (3 * r * r + length * length) / 12
            return (side, side, mass * r * r / 2)
        r = self.size[0]
        return (2 * mass * r * r / 5,) * 3

    def geometry(self) -> ET.Element:
        geom = ET.Element("geometry")
        if self.kind == "box":
            ET.SubElement(geom, "box", size=_fmt(self.size))
        elif self.kind == "cylinder":
            ET.SubElement(geom, "cylinder", radius=_fmt(self.size[:1]), length=_fmt(self.size[1:]))
        else:
            ET.SubElement(geom, "sphere", radius=_fmt(self.size))
        return geom


def _segment(vector: np.ndarray, radius: float, colour: str = "white") -> Shape:
    """A cylinder from the link origin to `vector` (link frame)."""
    v = np.asarray(vector, dtype=float)
    length = float(np.linalg.norm(v))
    d = v / length
    pitch = float(np.arccos(np.clip(d[2], -1.0, 1.0)))
    yaw = float(np.arctan2(d[1], d[0]))
    return Shape("cylinder", (radius, length), tuple(v / 2), (0.0, pitch, yaw), colour)


def _link(robot: ET.Element, name: str, mass: float, shape: Shape | None) -> None:
    link = ET.SubElement(robot, "link", name=name)
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "origin", xyz=_fmt(shape.xyz if shape else (0, 0, 0)),
                  rpy=_fmt(shape.rpy if shape else (0, 0, 0)))
    ET.SubElement(inertial, "mass", value=_fmt([mass]))
    ixx, iyy, izz = shape.inertia(mass) if shape else (1e-6, 1e-6, 1e-6)
    ET.SubElement(inertial, "inertia", ixx=_fmt([ixx]), ixy="0", ixz="0", iyy=_fmt([iyy]), iyz="0", izz=_fmt([izz]))
    if shape is None:
        return
    for tag in ("visual", "collision"):
        element = ET.SubElement(link, tag)
        ET.SubElement(element, "origin", xyz=_fmt(shape.xyz), rpy=_fmt(shape.rpy))
        element.append(shape.geometry())
        if tag == "visual":
            ET.SubElement(element, "material", name=shape.colour)


def _joint(robot: ET.Element, name: str, parent: str, child: str, xyz: np.ndarray, axis: str | None = None) -> None:
    """A revolute joint about `axis`, or a fixed one without."""
    joint = ET.SubElement(robot, "joint", name=name, type="fixed" if axis is None else "revolute")
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    ET.SubElement(joint, "origin", xyz=_fmt(xyz), rpy="0 0 0")
    if axis is not None:
        ET.SubElement(joint, "axis", xyz=axis)
        lo, hi = JOINT_LIMITS[name]
        suffix = name[1:]
        ET.SubElement(joint, "limit", lower=_fmt([lo]), upper=_fmt([hi]), effort=_fmt([EFFORT[suffix]]),
                      velocity=_fmt([VELOCITY_LIMITS[name]]))
        ET.SubElement(joint, "dynamics", damping=_fmt([JOINT_DAMPING]), friction="0")


def _arm(robot: ET.Element, side: str) -> None:
    shoulder, elbow, wrist, hand = side_offsets(side)
    s = side
    chain = [  # (joint, axis, origin in parent frame, child link, mass, shape)
        (f"{s}ShoulderPitch", "0 1 0", shoulder, SHOULDER_LINKS[s], 0.07,
         Shape("sphere", (0.025,), colour="grey")),
        (f"{s}ShoulderRoll", "0 0 1", np.zeros(3), f"{s}Bicep", 0.16, _segment(elbow, 0.022)),
        (f"{s}ElbowYaw", "1 0 0", elbow, ELBOW_LINKS[s], 0.065, Shape("sphere", (0.02,), colour="grey")),
        (f"{s}ElbowRoll", "0 0 1", np.zeros(3), f"{s}ForeArm", 0.08, _segment(wrist, 0.02)),
        (f"{s}WristYaw", "1 0 0", wrist, WRIST_LINKS[s], 0.185, _segment(hand, 0.018, "orange")),
    ]
    parent = BASE_LINK
    for joint, axis, origin, child, mass, shape in chain:
        _link(robot, child, mass, shape)
        _joint(robot, joint, parent, child, origin, axis)
        parent = child
    _link(robot, HAND_LINKS[s], 0.005, None)
    _joint(robot, f"{s}HandFrame", parent, HAND_LINKS[s], hand)


def _leg(robot: ET.Element, side: str) -> None:
    mirror = np.array([1.0, 1.0 if side == "L" else -1.0, 1.0])
    name = f"{side}Leg"
    _link(robot, name, 1.6, Shape("cylinder", (0.035, LEG_LENGTH), (0.0, 0.0, -LEG_LENGTH / 2)))
    _joint(robot, f"{side}HipFixed", BASE_LINK, name, HIP_OFFSET * mirror)
    foot = f"{side}Foot"
    _link(robot, foot, 0.16, Shape("box", (0.16, 0.088, FOOT_HEIGHT), (0.02, 0.0, -FOOT_HEIGHT / 2), colour="grey"))
    _joint(robot, f"{side}AnkleFixed", name, foot, np.array([0.0, 0.0, -LEG_LENGTH]))


def build_nao_urdf() -> str:
    """The URDF text (deterministic: equal inputs give byte-equal output)."""
    robot = ET.Element("robot", name=ROBOT_NAME)
    for colour, rgba in _COLOURS.items():
        ET.SubElement(ET.SubElement(robot, "material", name=colour), "color", rgba=rgba)
    _link(robot, BASE_LINK, 1.05, Shape("box", (0.09, 0.14, 0.2), (-0.005, 0.0, 0.03)))
    _link(robot, "Head", 0.6, Shape("sphere", (0.065,), (0.0, 0.0, 0.06)))
    _joint(robot, "HeadFixed", BASE_LINK, "Head", NECK_OFFSET)
    for side in SIDES:
        _arm(robot, side)
    for side in SIDES:
        _leg(robot, side)
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def default_urdf_path() -> Path:
    """The URDF shipped with the package (package data)."""
    return Path(__file__).resolve().parent / "nao.urdf"


def write_urdf(path: Path | None = None) -> Path:
    """Write a fresh build to `path` (default: the shipped copy) and return the path."""
    target = Path(path) if path is not None else default_urdf_path()
    target.parent.mkdir(parents=True, exist_ok=True)
    with target.open("w", encoding="utf-8") as f:
        f.write(build_nao_urdf())
    return target


if __name__ == "__main__":
    print(write_urdf())
