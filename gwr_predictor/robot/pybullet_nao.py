"""The Nao's arms in PyBullet: position-controlled joints, link positions, offscreen pictures.

Why a wrapper: every user (the robot model, the ROS node, tests, figures) needs the same few
things, each simulator on its own physics client (several can coexist in one process, and none
touches PyBullet's global default client) and a connection that is always closed.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gwr_predictor.files.user_files import output_file
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS, ROBOT_ARM_JOINTS, SIDES, VELOCITY_LIMITS, ArmPoints, clip_to_limits
from gwr_predictor.robot.urdf import ELBOW_LINKS, HAND_LINKS, SHOULDER_LINKS, WRIST_LINKS, default_urdf_path


@dataclass(frozen=True)
class Camera:
    """A look-at camera in the torso frame (x forward, z up): default in front of the robot."""

    eye: tuple[float, float, float] = (0.75, 0.25, 0.2)
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fov_deg: float = 50.0


def _pybullet():
    import pybullet  # imported on use: the rest of the library must not pay for it

    return pybullet


class NaoSimulator:
    """One PyBullet physics client with the Nao URDF (fixed torso); use as a context manager."""

    def __init__(self, gui: bool = False, time_step: float = 1.0 / 240.0, urdf_path: str | Path | None = None,
                 *, gravity: bool = True, floor: bool = True) -> None:
        if not (0.0 < time_step <= 0.05):
            raise RobotError(f"time_step must be in (0, 0.05] s, got {time_step!r}")
        self.time_step = float(time_step)
        self.urdf_path = Path(urdf_path) if urdf_path is not None else default_urdf_path()
        if not self.urdf_path.is_file():
            raise RobotError(f"URDF not found: {self.urdf_path}")
        if gui and not os.environ.get("DISPLAY"):
            # PyBullet's GUI would exit the whole process without an X display: refuse instead.
            raise RobotError("gui=True needs a display, but DISPLAY is not set (run headless with gui=False)")
        p = _pybullet()
        self._p = p
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        if self.client < 0:
            raise RobotError(f"PyBullet could not connect ({'GUI' if gui else 'DIRECT'})")
        try:
            self._setup(gravity, floor)
            if gui:  # the live view looks at the robot from the front, as the videos do
                p.resetDebugVisualizerCamera(1.0, 70.0, -10.0, [0.0, 0.0, 0.0], physicsClientId=self.client)
        except Exception:
            self.close()
            raise
        self.t = 0.0

    def _setup(self, gravity: bool, floor: bool) -> None:
        p, c = self._p, self.client
        p.setTimeStep(self.time_step, physicsClientId=c)
        p.setGravity(0.0, 0.0, -9.81 if gravity else 0.0, physicsClientId=c)
        self.robot = p.loadURDF(str(self.urdf_path), useFixedBase=True, physicsClientId=c)
        self._joint_index: dict[str, int] = {}
        self._link_index: dict[str, int] = {}
        for j in range(p.getNumJoints(self.robot, physicsClientId=c)):
            info = p.getJointInfo(self.robot, j, physicsClientId=c)
            self._link_index[info[12].decode()] = j
            if info[2] == p.JOINT_REVOLUTE:
                self._joint_index[info[1].decode()] = j
        missing = [n for n in ROBOT_ARM_JOINTS if n not in self._joint_index]
        if missing:
            raise RobotError(f"{self.urdf_path}: joints {missing} missing")
        self._arm_ids = [self._joint_index[n] for n in ARM_JOINTS]
        self._all_ids = [self._joint_index[n] for n in ROBOT_ARM_JOINTS]
        self._forces = [float(p.getJointInfo(self.robot, j, physicsClientId=c)[10]) for j in self._all_ids]
        self._targets = np.zeros(len(ROBOT_ARM_JOINTS))
        if floor:
            shape = p.createVisualShape(p.GEOM_BOX, halfExtents=[1.0, 1.0, 0.005], rgbaColor=[0.55, 0.6, 0.55, 1],
                                        physicsClientId=c)
            p.createMultiBody(0.0, -1, shape, [0.0, 0.0, -0.34], physicsClientId=c)
        self.reset(clip_to_limits(np.zeros(len(ARM_JOINTS))))

    # --- lifecycle ------------------------------------------------------------------------------
    def __enter__(self) -> NaoSimulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect this client (idempotent)."""
        if getattr(self, "client", -1) >= 0 and self._p.isConnected(physicsClientId=self.client):
            self._p.disconnect(physicsClientId=self.client)
        self.client = -1

    def _require(self) -> int:
        if self.client < 0:
            raise RobotError("simulator is closed")
        return self.client

    # --- joints ---------------------------------------------------------------------------------
    @property
    def joint_names(self) -> tuple[str, ...]:
        """The actuated joints (ROBOT_ARM_JOINTS: the 8 learner joints plus both WristYaw)."""
        return ROBOT_ARM_JOINTS

    def _full_targets(self, positions: Mapping[str, float] | np.ndarray | Sequence[float]) -> np.ndarray:
        full: np.ndarray = self._targets.copy()
        if isinstance(positions, Mapping):
            unknown = set(positions) - set(ROBOT_ARM_JOINTS)
            if unknown:
                raise RobotError(f"unknown joints {sorted(unknown)}; known: {ROBOT_ARM_JOINTS}")
            for name, value in positions.items():
                full[ROBOT_ARM_JOINTS.index(name)] = float(value)
        else:
            arr = np.asarray(positions, dtype=float)
            if arr.shape == (len(ARM_JOINTS),):
                for name, value in zip(ARM_JOINTS, arr, strict=True):
                    full[ROBOT_ARM_JOINTS.index(name)] = value
            elif arr.shape == (len(ROBOT_ARM_JOINTS),):
                full = arr.copy()
            else:
                raise RobotError(f"expected {len(ARM_JOINTS)} (ARM_JOINTS) or {len(ROBOT_ARM_JOINTS)} "
                                 f"(ROBOT_ARM_JOINTS) angles, got shape {arr.shape}")
        if not np.all(np.isfinite(full)):
            raise RobotError(f"joint targets must be finite, got {full}")
        return full

    def command(self, positions: Mapping[str, float] | np.ndarray | Sequence[float]) -> None:
        """Position targets (by name, or an array in ARM_JOINTS / ROBOT_ARM_JOINTS order).

        Each motor tracks its target with the URDF's effort limit and at most its Nao velocity.
        Targets are not clipped here: `SimulatedRobot.command`, the robot's input, clipped them
        already; a target beyond a limit sent directly stops at the URDF's joint limit, which
        PyBullet enforces like the arm's mechanical stop.
        """
        c = self._require()
        self._targets = self._full_targets(positions)
        for name, j, target, force in zip(ROBOT_ARM_JOINTS, self._all_ids, self._targets, self._forces, strict=True):
            self._p.setJointMotorControl2(self.robot, j, self._p.POSITION_CONTROL, targetPosition=float(target),
                                          force=force, maxVelocity=VELOCITY_LIMITS[name], physicsClientId=c)

    def step(self, seconds: float | None = None) -> int:
        """Advance by `seconds` (default: one time step); returns the physics steps taken.

        Whole steps only; the remainder is carried over so that `t` follows the requested time.
        """
        c = self._require()
        goal = self.t + (self.time_step if seconds is None else seconds)
        n = max(0, math.floor((goal - self._sim_t) / self.time_step + 1e-9))
        for _ in range(n):
            self._p.stepSimulation(physicsClientId=c)
        self._sim_t += n * self.time_step
        self.t = goal
        return n

    def joint_positions(self, names: Sequence[str] = ARM_JOINTS) -> np.ndarray:
        """Current angles (rad) of `names` (default: the 8 ARM_JOINTS)."""
        c = self._require()
        ids = [self._joint_index[n] for n in names]
        return np.array([s[0] for s in self._p.getJointStates(self.robot, ids, physicsClientId=c)])

    def joint_velocities(self, names: Sequence[str] = ARM_JOINTS) -> np.ndarray:
        c = self._require()
        ids = [self._joint_index[n] for n in names]
        return np.array([s[1] for s in self._p.getJointStates(self.robot, ids, physicsClientId=c)])

    def reset(self, angles: Mapping[str, float] | np.ndarray | Sequence[float]) -> None:
        """Teleport the joints to `angles` (clipped into the limits: a pose is placed, not driven
        there, so no joint stop would hold it) at rest and hold them there (targets = angles)."""
        c = self._require()
        self._targets = clip_to_limits(self._full_targets(angles), ROBOT_ARM_JOINTS)
        for j, a in zip(self._all_ids, self._targets, strict=True):
            self._p.resetJointState(self.robot, j, float(a), 0.0, physicsClientId=c)
        self.command(self._targets)
        self.t = self._sim_t = 0.0

    # --- geometry -------------------------------------------------------------------------------
    def link_positions(self, names: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """World positions of link frames (URDF link origins, not centres of mass), by link name."""
        c = self._require()
        names = list(self._link_index) if names is None else list(names)
        out = {}
        for name in names:
            if name not in self._link_index:
                raise RobotError(f"unknown link {name!r}; known: {sorted(self._link_index)}")
            state = self._p.getLinkState(self.robot, self._link_index[name], computeForwardKinematics=True,
                                         physicsClientId=c)
            out[name] = np.array(state[4])
        return out

    def arm_points(self) -> dict[str, ArmPoints]:
        """Shoulder, elbow, wrist and hand positions per side, as `nao.forward_kinematics` gives them."""
        links = self.link_positions([*SHOULDER_LINKS.values(), *ELBOW_LINKS.values(), *WRIST_LINKS.values(),
                                     *HAND_LINKS.values()])
        return {s: ArmPoints(links[SHOULDER_LINKS[s]], links[ELBOW_LINKS[s]], links[WRIST_LINKS[s]],
                             links[HAND_LINKS[s]]) for s in SIDES}

    # --- pictures -------------------------------------------------------------------------------
    def render(self, width: int = 320, height: int = 240, camera: Camera | None = None) -> np.ndarray:
        """An offscreen RGB picture (height x width x 3, uint8) from TinyRenderer."""
        c = self._require()
        if not (16 <= width <= 4096 and 16 <= height <= 4096):
            raise RobotError(f"render size must be within 16..4096 pixels, got {width}x{height}")
        cam = camera or Camera()
        view = self._p.computeViewMatrix(cam.eye, cam.target, cam.up, physicsClientId=c)
        proj = self._p.computeProjectionMatrixFOV(cam.fov_deg, width / height, 0.02, 5.0, physicsClientId=c)
        _, _, rgba, _, _ = self._p.getCameraImage(width, height, view, proj, renderer=self._p.ER_TINY_RENDERER,
                                                  physicsClientId=c)
        return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an HxWx3 uint8 image as PNG."""
    from PIL import Image

    with output_file(path, "image", RobotError) as f:
        Image.fromarray(np.asarray(image, dtype=np.uint8)).save(f, format="PNG")
    return Path(path)


def contact_sheet(images: Sequence[np.ndarray], path: str | Path, columns: int = 4,
                  labels: Sequence[str] | None = None) -> Path:
    """Tile equally sized frames into one PNG (row-major), each with an optional label."""
    from PIL import Image, ImageDraw

    if not images:
        raise RobotError("contact_sheet needs at least one image")
    h, w = images[0].shape[:2]
    if any(im.shape[:2] != (h, w) for im in images):
        raise RobotError("contact_sheet images must all have one size")
    if labels is not None and len(labels) != len(images):
        raise RobotError(f"{len(labels)} labels for {len(images)} images")
    cols = max(1, min(columns, len(images)))
    rows = math.ceil(len(images) / cols)
    sheet = Image.new("RGB", (cols * w, rows * h), "white")
    draw = ImageDraw.Draw(sheet)
    for i, im in enumerate(images):
        x, y = (i % cols) * w, (i // cols) * h
        sheet.paste(Image.fromarray(np.asarray(im, dtype=np.uint8)), (x, y))
        if labels is not None:
            draw.text((x + 4, y + 4), labels[i], fill=(0, 0, 0))
    return save_png(np.asarray(sheet), path)
